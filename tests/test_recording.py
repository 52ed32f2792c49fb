"""`inest-record`: the reward topics of real publisher processes into an MCAP file that the
third-party reader (mcap_ros2) decodes to the values published; bad paths; `inest-launch --record`."""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest
from inest_bringup.launcher import node_commands, parse_args
from inest_bringup.recorder import type_name
from inest_bringup.recording import DELIMITER, message_definition, msg_text
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rclpy.serialization import deserialize_message
from reward_publisher import expected_messages
from rosgraph import Processes, fresh_domain

pytestmark = pytest.mark.timeout(300)
PUBLISHER = Path(__file__).parent / "reward_publisher.py"
RECORDER = [sys.executable, "-m", "inest_bringup.recorder"]


@pytest.fixture
def graph(tmp_path):
    processes = Processes(fresh_domain(), tmp_path)
    yield processes
    processes.stop_all()


def test_the_schema_is_the_msg_text_then_each_dependency_once_like_ros2_bag():
    definition = message_definition("diagnostic_msgs/msg/DiagnosticArray")
    sections = definition.split(f"\n{DELIMITER}\nMSG: ")
    assert sections[0] == msg_text("diagnostic_msgs/msg/DiagnosticArray")
    names = [section.split("\n", 1)[0] for section in sections[1:]]
    # depth first, dependencies sorted: DiagnosticStatus, its KeyValue, then Header and its Time
    assert names == ["diagnostic_msgs/DiagnosticStatus", "diagnostic_msgs/KeyValue", "std_msgs/Header",
                     "builtin_interfaces/Time"]  # fmt: skip
    for name, section in zip(names, sections[1:], strict=True):
        assert section == f"{name}\n{msg_text(name)}"
    assert message_definition("std_msgs/msg/Float32") == msg_text("std_msgs/msg/Float32")


@pytest.mark.parametrize("stop_signal", [signal.SIGINT, signal.SIGTERM])
def test_the_recording_holds_every_published_message_as_published(graph, tmp_path, stop_signal):
    out = tmp_path / "run.mcap"
    out.write_bytes(b"an older recording")
    recorder = graph.start("record", *RECORDER, out, "--namespaces", "sim0", "sim1", "--images", "--overwrite")
    published = subprocess.run(
        [sys.executable, PUBLISHER, "--namespaces", "sim0", "sim1", "--images"],
        env=graph.env, capture_output=True, text=True, timeout=200,
    )  # fmt: skip
    assert published.returncode == 0, published.stdout + published.stderr + graph.log("record")
    recorder.send_signal(stop_signal)
    assert recorder.wait(60) == 0, graph.log("record")
    assert not (tmp_path / "run.mcap.part").exists()
    expected = expected_messages(["sim0", "sim1"], images=True)
    recorded: dict[str, list] = {topic: [] for topic in expected}
    with open(out, "rb") as file:
        for schema, channel, message, decoded in make_reader(
            file, decoder_factories=[DecoderFactory()]
        ).iter_decoded_messages(log_time_order=False):
            assert schema.encoding == "ros2msg" and channel.message_encoding == "cdr"
            assert message.log_time >= message.publish_time > 0  # received, sent (system clock)
            recorded[channel.topic].append((schema, message, decoded))
    assert {topic: len(items) for topic, items in recorded.items()} == {t: len(m) for t, m in expected.items()}
    for topic, items in recorded.items():
        for (schema, message, _), msg in zip(items, expected[topic], strict=True):
            assert deserialize_message(message.data, type(msg)) == msg  # the CDR bytes as published
            assert schema.name == type_name(type(msg)) and schema.data.decode() == message_definition(schema.name)
    values = {topic: [decoded for *_, decoded in items] for topic, items in recorded.items()}
    rewards = values["/sim1/reward"]
    assert [r.total for r in rewards] == [-1.0, -0.75, -0.5, -0.25, 0.0, 0.25]
    assert [r.subtask for r in rewards] == [0, 1, 2, 3, 0, 1] and {r.num_subtasks for r in rewards} == {3}
    assert [r.subtask_completed for r in rewards] == [False, True, False, False, False, True]
    assert [(r.header.stamp.sec, r.header.stamp.nanosec) for r in rewards[-2:]] == [(0, 625_000_000), (0, 750_000_000)]
    assert {r.header.frame_id for r in rewards} == {"camera_sim1"}
    assert [m.data for m in values["/sim0/reward/total"]] == [0.0, 0.25, 0.5, 0.75, 1.0, 1.25]
    assert [m.data for m in values["/sim0/reward/subtask"]] == [0, 1, 2, 3, 0, 1]
    statuses = values["/sim1/episode_status"]
    assert [s.truncated for s in statuses] == [False] * 5 + [True] and {s.seed for s in statuses} == {8}
    diagnostics = [m.status[0] for m in values["/diagnostics"]]
    assert [(d.level, d.values[0].key, d.values[0].value) for d in diagnostics] == [
        (0, "rate_hz", "8.000"), (1, "rate_hz", "16.000")]  # fmt: skip
    image = values["/sim0/camera/ego/image_raw"][2]
    assert (image.height, image.width, image.encoding, bytes(image.data)) == (2, 2, "rgb8", bytes(range(2, 14)))


def test_without_images_flag_no_image_topic_is_recorded(graph, tmp_path):
    recorder = graph.start("record", *RECORDER, tmp_path / "run.mcap", "--namespaces", "sim0")
    published = subprocess.run([sys.executable, PUBLISHER, "--namespaces", "sim0"], env=graph.env, timeout=200)
    assert published.returncode == 0, graph.log("record")
    recorder.send_signal(signal.SIGINT)
    assert recorder.wait(60) == 0, graph.log("record")
    with open(tmp_path / "run.mcap", "rb") as file:
        summary = make_reader(file).get_summary()
    counts = {
        summary.channels[channel].topic: count for channel, count in summary.statistics.channel_message_counts.items()
    }
    assert counts == {"/sim0/reward": 6, "/sim0/reward/total": 6, "/sim0/reward/subtask": 6,
                      "/sim0/episode_status": 6, "/diagnostics": 2}  # fmt: skip


@pytest.mark.parametrize(
    ("target", "message"),
    [("missing/run.mcap", "no folder"), ("existing.mcap", "exists (--overwrite replaces it)")],
)
def test_a_bad_output_path_is_one_line_and_status_2(tmp_path, target, message):
    (tmp_path / "existing.mcap").write_bytes(b"keep me")
    result = subprocess.run([*RECORDER, tmp_path / target], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and message in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert (tmp_path / "existing.mcap").read_bytes() == b"keep me"
    assert sorted(path.name for path in tmp_path.iterdir()) == ["existing.mcap"]


def test_the_launcher_starts_the_recorder_first_on_every_simulator(tmp_path):
    args = parse_args(["--sims", "2", "--record", str(tmp_path / "run.mcap")])
    name, command = node_commands(args, tmp_path)[0]
    assert name == "record"
    assert command == [*RECORDER, str(tmp_path / "run.mcap"), "--namespaces", "sim0", "sim1"]
    (tmp_path / "run.mcap").touch()
    with pytest.raises(SystemExit) as refused:
        parse_args(["--record", str(tmp_path / "run.mcap")])
    assert refused.value.code == 2
