"""MCAP recordings of serialized ROS 2 messages, readable by Foxglove, PlotJuggler, `ros2 bag`
and `mcap_ros2`, without `ros2 bag` (a pip install has none). No rclpy: the recorder node feeds it.

Schemas are the complete `ros2msg` definitions `ros2 bag record` stores: the type's .msg text,
then each dependency's once, depth first, after a line of 80 `=` and `MSG: <type>`
(rosbag2_cpp's LocalMessageDefinitionSource), read from the installed share/ folders.
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

from mcap.well_known import MessageEncoding, Profile, SchemaEncoding
from mcap.writer import LIBRARY_IDENTIFIER, Writer

DELIMITER = "=" * 80
# the type of a field, the first word of a line ("std_msgs/Header" in "std_msgs/Header header"), as rosbag2 matches it
FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
PRIMITIVES = {"bool", "byte", "char", "string", "float32", "float64"} | {
    f"{sign}int{bits}" for sign in ("", "u") for bits in (8, 16, 32, 64)
}
PARTIAL_SUFFIX = ".part"


class RecordingError(ValueError):
    """A recording that cannot be made: a bad output path or an unknown message type."""


def share_directory(package: str) -> Path:
    """The package's share/ folder: from the ament index on ROS installs, else this environment's
    share/ (the pip wheels install there and set no AMENT_PREFIX_PATH)."""
    try:
        from ament_index_python.packages import get_package_share_directory

        return Path(get_package_share_directory(package))
    except (LookupError, OSError):
        return Path(sys.prefix) / "share" / package


def msg_text(type_name: str) -> str:
    """The .msg file of `pkg/Type` or `pkg/msg/Type`, as installed."""
    package, *_, name = type_name.split("/")
    path = share_directory(package) / "msg" / f"{name}.msg"
    try:
        return path.read_text()
    except OSError as error:
        raise RecordingError(f"no message definition for {type_name} ({path}: {error.strerror})") from None


def dependencies(text: str, package: str) -> set[str]:
    """The message types a .msg text's fields use (`Type` alone is one of `package`)."""
    types = {match.group(1) for match in FIELD_TYPE.finditer(text)} - PRIMITIVES
    return {name if "/" in name else f"{package}/{name}" for name in types}


def message_definition(type_name: str) -> str:
    """The complete ros2msg definition of `type_name` (e.g. `inest_interfaces/msg/Reward`)."""
    seen: set[str] = set()

    def expand(name: str) -> str:
        text = msg_text(name)
        for dependency in sorted(dependencies(text, name.split("/")[0])):
            if dependency not in seen:
                seen.add(dependency)
                text += f"\n{DELIMITER}\nMSG: {dependency}\n" + expand(dependency)
        return text

    return expand(type_name)


def check_target(path: Path, overwrite: bool) -> None:
    """Refuse a recording path whose folder is missing, or that exists unless `overwrite`."""
    if not path.parent.is_dir():
        raise RecordingError(f"cannot record to {path}: no folder {path.parent}")
    if path.is_dir():
        raise RecordingError(f"cannot record to {path}: it is a folder")
    if path.exists() and not overwrite:
        raise RecordingError(f"{path} exists (--overwrite replaces it)")


class McapRecording:
    """An MCAP file of CDR messages on known topics, written under `<path>.part` and renamed to
    `path` by close(), so a file at `path` is always complete."""

    def __init__(self, path: Path | str, topics: dict[str, str], overwrite: bool = False) -> None:
        """`topics`: topic name -> message type (`pkg/msg/Type`)."""
        self.path = Path(path)
        check_target(self.path, overwrite)
        definitions = {type_name: message_definition(type_name) for type_name in sorted(set(topics.values()))}
        self.partial = self.path.with_name(self.path.name + PARTIAL_SUFFIX)
        try:
            self._file = self.partial.open("wb")
        except OSError as error:
            raise RecordingError(f"cannot record to {self.path}: {error.strerror}") from None
        self._writer = Writer(self._file)
        self._writer.start(profile=Profile.ROS2, library=f"{LIBRARY_IDENTIFIER} inest-record")
        schemas = {
            type_name: self._writer.register_schema(type_name, SchemaEncoding.ROS2, text.encode())
            for type_name, text in definitions.items()
        }
        self._channels = {
            topic: self._writer.register_channel(topic, MessageEncoding.CDR, schemas[type_name])
            for topic, type_name in topics.items()
        }
        self.messages = 0
        self.closed = False

    def write(self, topic: str, data: bytes, log_time: int, publish_time: int) -> None:
        """One serialized message; times in nanoseconds since the epoch (received, sent)."""
        self._writer.add_message(self._channels[topic], log_time, data, publish_time)
        self.messages += 1

    def close(self) -> None:
        """Write the summary and footer, then move the file into place (once)."""
        if not self.closed:
            self.closed = True
            self._writer.finish()
            self._file.close()
            os.replace(self.partial, self.path)
