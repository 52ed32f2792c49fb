"""`inest-record`: record the graph's reward topics to an MCAP file (a pip install has no `ros2 bag`).

For every namespace in `--namespaces`: `reward`, `reward/total`, `reward/subtask` and
`episode_status` (with `--images` also `camera/ego/image_raw` and `camera/allo/image_raw`; with
`--images --image-transport compressed` their `/compressed` topics, as a simulator with `image_transport`
"compressed" or a robot camera sends them), plus
`/diagnostics`. Messages are stored as published (CDR) with the complete ros2msg schemas, so
Foxglove, PlotJuggler, `ros2 bag` and `mcap_ros2.reader.read_ros2_messages` decode them. Ctrl-C or
SIGTERM ends the recording: what already reached this process is written and the file is closed;
until then it is `FILE.part`. `--ros-args` works as for the other nodes (`-r __ns:=/run7`).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticArray
from inest_common.rosutil import namespaced, run_node
from inest_common.settings import OneLineParser
from inest_interfaces.msg import EpisodeStatus, Reward
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.utilities import remove_ros_args
from sensor_msgs.msg import CompressedImage, Image
from std_msgs.msg import Float32, Int32

from .recording import McapRecording, RecordingError

STREAM_TOPICS = {"reward": Reward, "reward/total": Float32, "reward/subtask": Int32, "episode_status": EpisodeStatus}
IMAGE_TOPICS = {
    "raw": {"camera/ego/image_raw": Image, "camera/allo/image_raw": Image},
    "compressed": {
        "camera/ego/image_raw/compressed": CompressedImage,
        "camera/allo/image_raw/compressed": CompressedImage,
    },
}
GRAPH_TOPICS = {"/diagnostics": DiagnosticArray}
QOS = QoSProfile(depth=100)  # reliable, like every publisher of the graph


def type_name(message_class: type) -> str:
    """`pkg/msg/Type` of a generated message class (its module is `pkg.msg._type`)."""
    return f"{message_class.__module__.split('.')[0]}/msg/{message_class.__name__}"


class RecorderNode(Node):
    def __init__(self, args: argparse.Namespace) -> None:
        super().__init__("inest_recorder")
        per_stream = STREAM_TOPICS | (IMAGE_TOPICS[args.image_transport] if args.images else {})
        wanted = {namespaced(ns, name): kind for ns in args.namespaces for name, kind in per_stream.items()}
        topics = {self.resolve_topic_name(name): kind for name, kind in (wanted | GRAPH_TOPICS).items()}
        self.recording = McapRecording(
            args.file, {topic: type_name(kind) for topic, kind in topics.items()}, args.overwrite
        )
        for topic, kind in topics.items():
            self.create_subscription(
                kind, topic, lambda data, info, topic=topic: self.on_message(topic, data, info), QOS, raw=True
            )
        self.get_logger().info(f"recording {sorted(topics)} to {self.recording.partial}")

    def on_message(self, topic: str, data: bytes, info: dict) -> None:
        self.recording.write(topic, data, info["received_timestamp"], info["source_timestamp"])

    def record(self) -> None:
        """Spin until SIGINT or SIGTERM (handled here rather than by rclpy, which would shut the
        context down at once), then take what DDS already received, so no delivered message is lost."""
        stop = threading.Event()
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, lambda *_: stop.set())
        executor = SingleThreadedExecutor()
        executor.add_node(self)
        try:
            while not stop.is_set():
                executor.spin_once(timeout_sec=0.1)
            before = -1
            while before != self.recording.messages:
                before = self.recording.messages
                executor.spin_once(timeout_sec=0.0)
        finally:
            executor.shutdown()

    def destroy_node(self) -> None:
        self.recording.close()
        self.get_logger().info(f"wrote {self.recording.messages} messages to {self.recording.path}")
        super().destroy_node()


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = OneLineParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("file", type=Path, help="the MCAP file to write")
    parser.add_argument("--namespaces", nargs="+", default=["sim0"], help="simulator namespaces ('' for none)")
    parser.add_argument("--images", action="store_true", help="also record the camera images (large)")
    parser.add_argument(
        "--image-transport", choices=sorted(IMAGE_TOPICS), default="raw", help="with --images: which camera topics"
    )
    parser.add_argument("--overwrite", action="store_true", help="replace FILE if it exists")
    return parser.parse_args(argv)


def main() -> int:
    args = parse_args(remove_ros_args(sys.argv)[1:])
    return run_node(lambda: RecorderNode(args), RecorderNode.record, (RecordingError,))


if __name__ == "__main__":
    sys.exit(main())
