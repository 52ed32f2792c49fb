"""Small helpers every INEST node shares: stamps, typed parameters, and the process main loop.

Only the node modules import this (it imports rclpy); the libraries stay free of ROS.
"""

from __future__ import annotations

import dataclasses
import difflib
import os
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import rclpy
import yaml
from builtin_interfaces.msg import Time
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.exceptions import NameValidationException
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node

from .files import NO_SPACE_EXIT, no_space_message, out_of_space

NANOSECONDS = 1_000_000_000


def stamp_ns(stamp: Time) -> int:
    return stamp.sec * NANOSECONDS + stamp.nanosec


def ns_stamp(nanoseconds: int) -> Time:
    return Time(sec=nanoseconds // NANOSECONDS, nanosec=nanoseconds % NANOSECONDS)


def namespaced(namespace: str, name: str) -> str:
    """`name` under `namespace`, still relative (so the node's own namespace applies on top); an
    absolute `name` stays as it is only outside any namespace (ValueError otherwise: every stream
    would read the same topic)."""
    if not namespace.strip("/"):
        return name
    if name.startswith("/"):
        raise ValueError(f"topic {name} is absolute: under stream {namespace} give it relative (without the leading /)")
    return f"{namespace.strip('/')}/{name}"


class ParameterError(ValueError):
    """A parameter the node was started with has the wrong type or a name the node does not have."""


def _checked(name: str, value: Any, default: Any) -> Any:
    """`value` as the type of `default` (ints are accepted for floats): parameters are declared
    with dynamic typing so that a wrong type reaches this one-line message, not rclpy's traceback."""
    if isinstance(default, tuple):
        items = [] if value is None else value
        if not isinstance(items, list):
            raise ParameterError(f"parameter {name} must be a list, got {value!r}")
        return tuple(_checked(name, item, default[0]) for item in items) if default else tuple(items)
    kind = str if default is None else type(default)
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if type(value) is not kind:
        expected = {bool: "true or false", int: "an integer", float: "a number", str: "a string"}[kind]
        raise ParameterError(f"parameter {name} must be {expected}, got {value!r}")
    return None if default is None and value == "" else value


def declare_dataclass(node: Node, instance: Any, prefix: str = "") -> dict[str, Any]:
    """Declare one ROS parameter per field (nested dataclasses as `field.sub`), the dataclass's
    defaults as the parameters' defaults; return the values the node was started with, nested
    like the dataclass, each checked against its field's type (None defaults are declared as ""
    and come back as None when unset; tuple fields are declared as lists and come back as tuples)."""
    values: dict[str, Any] = {}
    for field in dataclasses.fields(instance):
        default = getattr(instance, field.name)
        name = f"{prefix}{field.name}"
        if dataclasses.is_dataclass(default):
            values[field.name] = declare_dataclass(node, default, f"{name}.")
            continue
        declared = "" if default is None else list(default) if isinstance(default, tuple) else default
        value = node.declare_parameter(name, declared, ParameterDescriptor(dynamic_typing=True)).value
        values[field.name] = _checked(name, value, default)
    return values


def reject_unknown_parameters(node: Node) -> None:
    """A parameter given on the command line or in a params file that the node never declared is a
    typo the node would otherwise silently ignore."""
    overrides = node._parameter_overrides  # rclpy has no public accessor for them
    unknown = sorted(name for name in overrides if not node.has_parameter(name))
    if unknown:
        declared = list(node._parameters)
        hints = [
            f"{name} (did you mean {close[0]}?)" if (close := difflib.get_close_matches(name, declared, 1)) else name
            for name in unknown
        ]
        raise ParameterError(f"{node.get_name()} has no parameter {', '.join(hints)}")


def new_executor() -> Executor:
    """rclpy's EventsExecutor, whose event queue lives in C++: it moves messages between
    processes faster than SingleThreadedExecutor, which rebuilds its wait set on every spin
    (docs/reports/performance.md). Spin it from the main thread: on a background thread it hung."""
    return EventsExecutor()


SHUTDOWN_CHECK_S = 0.5  # how often an idle node looks whether Ctrl-C or SIGTERM shut ROS down


def spin_until_shutdown(node: Node) -> None:
    """`rclpy.spin`, but never blocked for longer than SHUTDOWN_CHECK_S: an idle node spinning
    without a timeout sometimes slept through the SIGTERM that shut its context down and never
    exited (scripts/experiments/sigterm_check.sh)."""
    executor = new_executor()
    executor.add_node(node)
    try:
        while rclpy.ok():
            executor.spin_once(timeout_sec=SHUTDOWN_CHECK_S)
    finally:
        executor.shutdown()


# set in a node's environment: build the node (every parameter checked, the model loaded), then
# exit 0 without spinning, or 2 with the line naming what is wrong (inest-launch's check)
CHECK_ONLY_ENV = "INEST_CHECK_ONLY"
PARAMETER_RULE = re.compile(r"[A-Za-z_~][\w./~:]*:=(.*)", re.DOTALL)


def malformed_parameter(argv: list[str]) -> str | None:
    """What is wrong with the first `-p NAME:=VALUE` of `argv`'s ROS arguments that rcl could not
    parse (it would fail with a traceback) or would silently drop (an empty list, which has no
    type: the parameter keeps an earlier value, as `inest-launch --param reward:streams:=[]` kept
    the launcher's streams), or None."""
    inside = False
    for index, item in enumerate(argv):
        if item in ("--ros-args", "--"):
            inside = item == "--ros-args"
        elif inside and item in ("-p", "--param") and index + 1 < len(argv):
            rule = argv[index + 1]
            match = PARAMETER_RULE.fullmatch(rule)
            if match is None:
                return f"-p {rule!r} is not NAME:=VALUE"
            try:
                value = yaml.safe_load(match[1])
            except yaml.YAMLError as error:
                return f"-p {rule!r}: the value is not valid YAML ({str(error).splitlines()[0]})"
            if value is None:
                return f"-p {rule!r} has no value"
            if value == []:
                return f"-p {rule!r}: ROS cannot pass an empty list (an earlier value of the parameter would stay)"
    return None


def run_node(
    make_node: Callable[[], Node],
    spin: Callable[[Node], None] | None = None,
    config_errors: tuple[type[Exception], ...] = (ValueError,),
    check: Callable[[Node], None] | None = None,
) -> int:
    """Init from sys.argv (so `--ros-args -p ... --params-file ...` work), spin, shut down cleanly
    on Ctrl-C or SIGTERM. `config_errors` (and ParameterError: a wrong type or an unknown name)
    mean a bad configuration, as do arguments rcl cannot parse: one line on stderr, exit 2.
    `check(node)` refuses what the parameters name (a run folder, a file) once they are all known
    and typed, so that a misspelt parameter is named rather than what its default led to; it runs
    in inest-launch's check too (CHECK_ONLY_ENV)."""
    program = Path(sys.argv[0]).name
    if problem := malformed_parameter(sys.argv):
        print(f"{program}: {problem}", file=sys.stderr)
        return 2
    try:
        rclpy.init(args=sys.argv)  # also turns SIGINT and SIGTERM into ExternalShutdownException
    except _rclpy.RCLError as error:  # arguments rcl refuses that the check above let through
        print(f"{program}: cannot parse its ROS arguments: {str(error).split('. Error')[0]}", file=sys.stderr)
        return 2
    node = None
    try:
        node = make_node()
        reject_unknown_parameters(node)
        if check is not None:
            check(node)
        if os.environ.get(CHECK_ONLY_ENV):
            return 0
        (spin or spin_until_shutdown)(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except config_errors as error:
        print(f"{program}: {error}", file=sys.stderr)
        return 2
    except NameValidationException as error:  # a topic, service or namespace name ROS refuses
        reason, _, name = str(error).partition(":\n")
        print(f"{program}: {reason}: {name.strip().splitlines()[0] if name.strip() else ''}", file=sys.stderr)
        return 2
    except Exception as error:
        if out_of_space(error):  # even under a SIGTERM: the checkpoint it was saving did not fit
            print(f"{program}: {no_space_message(error)}", file=sys.stderr)
            return NO_SPACE_EXIT
        if rclpy.ok():
            raise
        # raised because Ctrl-C or SIGTERM shut ROS down under the node (an RCLError from a
        # publisher or timer whose context just went): a clean stop, not a crash
    finally:
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0
