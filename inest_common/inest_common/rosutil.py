"""Small helpers every INEST node shares: stamps, typed parameters, and the process main loop.

Only the node modules import this (it imports rclpy); the libraries stay free of ROS.
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Callable
from typing import Any

import rclpy
from builtin_interfaces.msg import Time
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

NANOSECONDS = 1_000_000_000


def stamp_ns(stamp: Time) -> int:
    return stamp.sec * NANOSECONDS + stamp.nanosec


def ns_stamp(nanoseconds: int) -> Time:
    return Time(sec=nanoseconds // NANOSECONDS, nanosec=nanoseconds % NANOSECONDS)


def namespaced(namespace: str, name: str) -> str:
    """`name` under `namespace`, still relative (so the node's own namespace applies on top)."""
    return f"{namespace.strip('/')}/{name}" if namespace.strip("/") else name


def declare_dataclass(node: Node, instance: Any, prefix: str = "") -> dict[str, Any]:
    """Declare one ROS parameter per field (nested dataclasses as `field.sub`), the dataclass's
    defaults as the parameters' defaults; return the values the node was started with, nested
    like the dataclass (None defaults are declared as "" and come back as None when unset; tuple
    fields are declared as lists and come back as tuples)."""
    values: dict[str, Any] = {}
    for field in dataclasses.fields(instance):
        default = getattr(instance, field.name)
        name = f"{prefix}{field.name}"
        if dataclasses.is_dataclass(default):
            values[field.name] = declare_dataclass(node, default, f"{name}.")
            continue
        if default is None:
            value = node.declare_parameter(name, "").value
            values[field.name] = None if value == "" else value
        elif isinstance(default, tuple):
            values[field.name] = tuple(node.declare_parameter(name, list(default)).value)
        else:
            values[field.name] = node.declare_parameter(name, default).value
    return values


def run_node(
    make_node: Callable[[], Node],
    spin: Callable[[Node], None] | None = None,
    config_errors: tuple[type[Exception], ...] = (ValueError,),
) -> int:
    """Init from sys.argv (so `--ros-args -p ... --params-file ...` work), spin, shut down cleanly
    on Ctrl-C or SIGTERM. `config_errors` mean a bad configuration: one line on stderr, exit 2."""
    rclpy.init(args=sys.argv)  # also turns SIGINT and SIGTERM into ExternalShutdownException
    node = None
    try:
        node = make_node()
        if spin is None:
            rclpy.spin(node)
        else:
            spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except config_errors as error:
        print(f"{sys.argv[0]}: {error}", file=sys.stderr)
        return 2
    finally:
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0
