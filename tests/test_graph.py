"""The ROS 2 node graph with real processes on a private domain: training over topics, a foreign
camera, malformed images, a reward node restarted mid-training, the reset service, the launcher."""

from __future__ import annotations

import itertools
import json
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from inest_interfaces.msg import Action, EpisodeStatus, Reward, State
from inest_interfaces.srv import ResetEpisode
from inest_reward_node.learning.data import load_demos
from inest_reward_node.runtime.intrinsic import IntrinsicConfig
from inest_reward_node.runtime.model import load_model
from inest_reward_node.runtime.rewards import RewardScorer, replay
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rosgraph import BIN, fresh_domain
from rosgraph_msgs.msg import Clock

pytestmark = pytest.mark.timeout(300)
FOREIGN_CAMERA = Path(__file__).parent / "foreign_camera.py"
TINY_AGENT = [  # a few hundred steps, updates from step 100, no periodic evaluation
    "-p", "sac.learning_starts:=100", "-p", "eval_every:=1000000", "-p", "final_eval_episodes:=2",
    "-p", "checkpoint_every:=100", "-p", "sac.buffer_size:=10000",
]  # fmt: skip


def reward_node_args(model, *extra: str) -> list[str]:
    return ["inest-reward-node", "--ros-args", "-p", f"model:={model}", "-p", "diagnostics_period:=0.2", *extra]


def sim_node_args(namespace: str, *extra: str) -> list[str]:
    return ["inest-sim-node", "--ros-args", "-r", f"__ns:=/{namespace}", "-p", "image_size:=48", *extra]


def demo_that_completes_subtasks(tiny_demos, model):
    """A training demonstration on which the in-process tracker completes at least one subtask."""
    for demo in load_demos(tiny_demos, "train", "ego", model.image_size, progress_bar=False):
        if replay(model, model.embed(demo.frames), 3, frames=demo.frames).completion_frames:
            return demo
    raise AssertionError("the tiny model completes no subtask on any training demonstration")


def test_a_foreign_camera_gets_rewards_that_match_the_library_frame_by_frame(graph, tiny_model, tiny_demos, tmp_path):
    model = load_model(tiny_model)
    demo = demo_that_completes_subtasks(tiny_demos, model)
    np.save(tmp_path / "frames.npy", demo.frames)
    graph.start("reward", *reward_node_args(tiny_model, "-p", "image_topic:=camera/image_raw"))
    camera = subprocess.run(
        [sys.executable, FOREIGN_CAMERA, tmp_path / "frames.npy", tmp_path / "out.json", "--malformed", "--reset"],
        env=graph.env, capture_output=True, text=True, timeout=240,
    )  # fmt: skip
    assert camera.returncode == 0, camera.stdout + camera.stderr + graph.log("reward")
    received = json.loads((tmp_path / "out.json").read_text())
    rewards = received["rewards"]
    assert len(rewards) == len(demo.frames)
    assert all(r["frame_id"] == "foreign_camera" and r["num_subtasks"] == 3 for r in rewards)
    # the same frames through the library, one at a time: same rewards and parts
    library = RewardScorer(model, 3, intrinsic=IntrinsicConfig(mode="embedding"))
    expected = [library.score(frame[None]) for frame in demo.frames]
    np.testing.assert_allclose([r["total"] for r in rewards], [e.total[0] for e in expected], rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(
        [r["intrinsic"] for r in rewards], [e.intrinsic[0] for e in expected], rtol=1e-4, atol=1e-5
    )
    subtasks = [r["subtask"] for r in rewards]
    assert subtasks == [int(e.completed[0]) for e in expected]  # the stage: subtasks done so far
    # and how sure it is, from the stage evidence the tracker read
    confidence = [r["confidence"] for r in rewards]
    np.testing.assert_allclose(confidence, [e.confidence[0] for e in expected], atol=1e-4)
    assert all(0.0 <= value <= 1.0 for value in confidence)
    # the default tracker reopens a subtask whose frames stop looking done, one step at a time
    assert max(subtasks) >= 1 and all(b - a in (-1, 0, 1) for a, b in itertools.pairwise(subtasks))
    # the reset service restarted the tracker
    assert received["after_reset"]["subtask"] == 0 and received["after_reset"]["bonus"] == 0.0
    # three malformed images: rejected, counted, the reason logged, and the node kept serving
    assert received["rejected"] == 3 and received["rejected_total"] == 3  # per report, and the running total
    log = graph.log("reward")
    for reason in ("unsupported encoding 'mono16'", "step 143 is shorter", "no pixel data"):
        assert reason in log


def test_a_compressed_camera_is_scored_as_its_frames_and_malformed_files_are_refused(
    graph, tiny_model, tiny_demos, tmp_path
):
    model = load_model(tiny_model)
    frames = next(iter(load_demos(tiny_demos, "train", "ego", model.image_size, progress_bar=False))).frames[:12]
    np.save(tmp_path / "frames.npy", frames)
    transport = ("-p", "image_topic:=camera/image_raw", "-p", "image_transport:=compressed")
    graph.start("reward", *reward_node_args(tiny_model, *transport))
    camera = subprocess.run(
        [sys.executable, FOREIGN_CAMERA, tmp_path / "frames.npy", tmp_path / "out.json", "--malformed",
         "--compressed", "png"],
        env=graph.env, capture_output=True, text=True, timeout=240,
    )  # fmt: skip
    assert camera.returncode == 0, camera.stdout + camera.stderr + graph.log("reward")
    received = json.loads((tmp_path / "out.json").read_text())
    library = RewardScorer(model, 3, intrinsic=IntrinsicConfig(mode="embedding"))
    expected = [library.score(frame[None]).total[0] for frame in frames]  # PNG is lossless: the same frames
    np.testing.assert_allclose([r["total"] for r in received["rewards"]], expected, rtol=1e-4, atol=1e-5)
    assert received["rejected"] == 3
    log = graph.log("reward")
    for reason in ("unsupported compressed format 'tiff'", "a JPEG file without a frame header", "no data in a png"):
        assert reason in log


def test_lockstep_training_over_the_graph_with_two_simulators(graph, tiny_model, tmp_path):
    for index in range(2):
        graph.start(f"sim{index}", *sim_node_args(f"sim{index}", "-p", f"publish_clock:={index == 0}".lower()))
    graph.start("reward", *reward_node_args(tiny_model, "-p", "streams:=[sim0, sim1]"))
    agent = graph.start(
        "agent", "inest-agent-node", "--ros-args", "-p", "namespaces:=[sim0, sim1]", "-p", f"out:={tmp_path / 'run'}",
        "-p", f"model:={tiny_model}",
        "-p", "total_steps:=300", *TINY_AGENT,
    )  # fmt: skip
    assert agent.wait(240) == 0, graph.log("agent")
    results = json.loads((tmp_path / "run" / "results.json").read_text())
    assert results["steps"] == 300 and results["config"]["num_envs"] == 2
    assert results["config"]["reward"] == "topic" and results["config"]["observation"] == "robot"
    assert (tmp_path / "run" / "checkpoint" / "learner.json").exists()
    # evaluate mode: the exported policy over the same graph, on the test layouts
    evaluation = graph.start(
        "evaluate", "inest-agent-node", "--ros-args", "-p", "namespaces:=[sim0, sim1]", "-p", "mode:=evaluate",
        "-p", f"model:={tiny_model}",
        "-p", f"out:={tmp_path / 'run'}", "-p", "episodes:=3",
    )  # fmt: skip
    assert evaluation.wait(120) == 0, graph.log("evaluate")
    table = graph.log("evaluate")
    assert "run (300 steps) over the graph" in table
    evaluation = json.loads((tmp_path / "run" / "evaluation.json").read_text())
    assert evaluation["final_evaluation"]["episodes"] == 3 and evaluation["policy"] == str(tmp_path / "run")
    assert evaluation["layouts"] == {"name": "test", "first_seed": 30_000_000}


MID_EPISODE = range(30, 61)  # steps into a 100-step episode where a fault lands mid-episode with room to spare


def count_steps(domain_env, until_steps: int, timeout: float, into_episode: range | None = None) -> int:
    """Watch sim0's episode status from this process until `until_steps` steps were taken and, if
    `into_episode` is given, the latest one is that many steps into its episode: a fault injected
    then lands mid-episode however far a loaded machine lets the graph run past the count."""
    rclpy.init(domain_id=int(domain_env["ROS_DOMAIN_ID"]))
    try:
        node = rclpy.create_node("step_counter")
        seen: list[EpisodeStatus] = []
        node.create_subscription(EpisodeStatus, "sim0/episode_status", seen.append, 50)
        deadline = time.monotonic() + timeout

        def done() -> bool:
            return len(seen) >= until_steps and (into_episode is None or seen[-1].step in into_episode)

        while not done() and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.05)
        return len(seen)
    finally:
        rclpy.shutdown()


def test_the_agent_waits_for_a_restarted_reward_node_resets_the_episode_it_lost_and_finishes(
    graph, tiny_model, tmp_path
):
    graph.start("sim0", *sim_node_args("sim0"))
    reward = graph.start("reward", *reward_node_args(tiny_model, "-p", "streams:=[sim0]"))
    agent = graph.start(
        "agent", "inest-agent-node", "--ros-args", "-p", "namespaces:=[sim0]", "-p", f"out:={tmp_path / 'run'}",
        "-p", f"model:={tiny_model}",
        "-p", "total_steps:=300", "-p", "step_timeout:=1.0", *TINY_AGENT,
    )  # fmt: skip
    assert count_steps(graph.env, 150, timeout=120, into_episode=MID_EPISODE) >= 150  # from the second episode on
    reward.kill()
    reward.wait()
    time.sleep(2.0)  # the agent is stuck on a step now
    assert agent.poll() is None
    graph.start("reward-restarted", *reward_node_args(tiny_model, "-p", "streams:=[sim0]"))
    assert agent.wait(240) == 0, graph.log("agent")
    assert json.loads((tmp_path / "run" / "results.json").read_text())["steps"] == 300
    log = graph.log("agent")
    assert "still waiting after 1 s: sim0: reward" in log  # it said what it waited for
    # the new reward node's tracker knows nothing of the subtasks done in this episode: the episode
    # is cut short and reset, and said so, rather than learned from with a forgotten stage
    lost = "sim0: the reward node lost this episode's subtask progress (restarted? its tracker counts 1 frames"
    assert lost in log, log


def refitted_copy(model: Path, out: Path) -> Path:
    """The model with every completion threshold lowered: another model, the same encoder."""
    shutil.copytree(model, out)
    metadata = json.loads((out / "model.json").read_text())
    for goals in metadata["subtasks"].values():
        goals["thresholds"] = [value - 0.5 for value in goals["thresholds"]]
    (out / "model.json").write_text(json.dumps(metadata))
    return out


def set_parameter(node, name: str, value: object) -> tuple[bool, str]:
    """Set a parameter of the reward node from `node`: (accepted, the node's reason)."""
    client = AsyncParameterClient(node, "inest_reward_node")
    assert client.wait_for_services(timeout_sec=30)
    future = client.set_parameters([Parameter(name, value=value)])
    rclpy.spin_until_future_complete(node, future, timeout_sec=60)
    result = future.result().results[0]
    return result.successful, result.reason


def test_a_refitted_model_is_loaded_live_and_the_agent_trains_on(graph, tiny_model, tmp_path):
    refitted = refitted_copy(tiny_model, tmp_path / "refitted")
    graph.start("sim0", *sim_node_args("sim0"))
    graph.start("reward", *reward_node_args(tiny_model, "-p", "streams:=[sim0]"))
    agent = graph.start(
        "agent", "inest-agent-node", "--ros-args", "-p", "namespaces:=[sim0]", "-p", f"out:={tmp_path / 'run'}",
        "-p", f"model:={tiny_model}", "-p", "total_steps:=300", *TINY_AGENT,
    )  # fmt: skip
    rclpy.init(domain_id=int(graph.env["ROS_DOMAIN_ID"]))
    try:
        node = rclpy.create_node("refitter")
        rewards, diagnostics = [], {}
        node.create_subscription(Reward, "sim0/reward", rewards.append, 500)

        def on_diagnostics(msg: DiagnosticArray) -> None:
            for status in msg.status:
                diagnostics.update({value.key: value.value for value in status.values})

        node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 10)
        deadline = time.monotonic() + 120
        while len(rewards) < 120 and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
        assert len(rewards) >= 120, graph.log("reward")
        accepted, reason = set_parameter(node, "model", str(tmp_path / "missing"))  # refused: the old one goes on
        assert not accepted and "missing" in reason
        accepted, reason = set_parameter(node, "threads", 2)
        assert not accepted and "threads: read at start-up" in reason
        assert set_parameter(node, "model", str(refitted)) == (True, "")
        switched = len(rewards)
        while (
            len(rewards) < switched + 50 or diagnostics.get("model_generation") != "1"
        ) and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
    finally:
        rclpy.shutdown()
    generations = [reward.model_generation for reward in rewards]
    assert generations[:120] == [0] * 120 and generations[-1] == 1  # every reward names its model
    assert generations == sorted(generations)  # once the new one scores, the old one never does again
    assert diagnostics["model"] == str(refitted)
    assert agent.wait(240) == 0, graph.log("agent")  # the agent trained on across the switch
    assert json.loads((tmp_path / "run" / "results.json").read_text())["steps"] == 300
    log = graph.log("reward")
    assert f"model generation 1: {refitted} scores from the next frame on" in log and "novelty memories kept" in log
    assert f"kept model {tiny_model}: {tmp_path / 'missing'} refused" in log


def test_the_launcher_runs_the_whole_graph_and_writes_the_reward_trace(tiny_model, tmp_path):
    launched = subprocess.run(
        [BIN / "inest-launch", "--out", tmp_path / "graph", "--model", tiny_model, "--steps", "200",
         "--record", tmp_path / "graph.mcap",
         "--domain-id", str(fresh_domain()), "--interval", "1", "--param", "sim:image_size:=48", "--episode-lines",
         *[arg for value in TINY_AGENT[1::2] for arg in ("--param", f"agent:{value}")]],
        capture_output=True, text=True, timeout=240,
    )  # fmt: skip
    assert launched.returncode == 0, launched.stdout + launched.stderr
    assert "remap rule" not in launched.stdout + launched.stderr  # --param NODE:NAME:=VALUE is the launcher's own
    assert "steps/s" in launched.stdout and "subtask" in launched.stdout
    episode = r"sim0: episode 1: \d of 3 blocks placed in order \(score \d\.\d\d\); the learned reward's subtask "
    assert re.search(episode, launched.stdout)
    assert "mean score" in launched.stdout  # the final evaluation table
    assert (tmp_path / "graph" / "reward_trace.png").stat().st_size > 1000
    for name in ("sim0", "reward", "agent", "record"):
        assert (tmp_path / "graph" / "logs" / f"{name}.log").exists()
    # the recording, stopped with the graph, is complete: every step's reward, on both reward topics
    recorded = {"/sim0/reward": [], "/sim0/reward/total": []}
    with open(tmp_path / "graph.mcap", "rb") as file:
        reader = make_reader(file, decoder_factories=[DecoderFactory()])
        for _, channel, _, decoded in reader.iter_decoded_messages(list(recorded), log_time_order=False):
            recorded[channel.topic].append(decoded)
    rewards = recorded["/sim0/reward"]
    assert len(rewards) >= 200 and {r.num_subtasks for r in rewards} == {3} and max(r.subtask for r in rewards) <= 3
    assert [r.total for r in rewards] == [total.data for total in recorded["/sim0/reward/total"]]


def test_a_reset_asked_again_before_a_step_answers_with_the_same_episode_and_a_step_carries_its_state(graph):
    graph.start("sim0", *sim_node_args("sim0"))
    rclpy.init(domain_id=int(graph.env["ROS_DOMAIN_ID"]))
    try:
        node = rclpy.create_node("resetter")
        client = node.create_client(ResetEpisode, "sim0/reset")
        statuses, states = [], []
        node.create_subscription(EpisodeStatus, "sim0/episode_status", statuses.append, 50)
        node.create_subscription(State, "sim0/state", states.append, 50)
        action_pub = node.create_publisher(Action, "sim0/action", 10)
        assert client.wait_for_service(timeout_sec=60)
        while node.count_publishers("sim0/state") < 1:
            rclpy.spin_once(node, timeout_sec=0.2)
        time.sleep(1.0)  # the simulator sees this subscriber too: it publishes `state` only while one listens

        def reset(seed: int = -1) -> ResetEpisode.Response:
            future = client.call_async(ResetEpisode.Request(seed=seed))
            rclpy.spin_until_future_complete(node, future, timeout_sec=30)
            return future.result()

        first, again = reset(), reset()
        assert (again.header.stamp, again.message, again.state) == (first.header.stamp, first.message, first.state)
        action = Action(values=[0.5, 0.0, 0.0])
        action.header.stamp = first.header.stamp
        deadline = time.monotonic() + 30
        while not any(s.action_stamp == first.header.stamp for s in statuses) and time.monotonic() < deadline:
            action_pub.publish(action)
            rclpy.spin_once(node, timeout_sec=0.2)
        stepped = next(status for status in statuses if status.action_stamp == first.header.stamp)
        while not any(state.header.stamp == stepped.header.stamp for state in states) and time.monotonic() < deadline:
            action_pub.publish(action)  # a repeat re-publishes the step, `state` now that this listener is seen
            rclpy.spin_once(node, timeout_sec=0.2)
        after_a_step, seeded = reset(), reset(seed=123)
    finally:
        rclpy.shutdown()
    # the step's new state rides on its status, and on `state` for whoever listens, stamped alike
    assert len(stepped.state) == len(first.state) and list(stepped.state) != list(first.state)
    published = [list(state.values) for state in states if state.header.stamp == stepped.header.stamp]
    assert published and all(values == list(stepped.state) for values in published)  # repeats re-publish it
    assert after_a_step.message != first.message  # a step taken: a new episode
    assert seeded.message.endswith("seed 123")  # another seed: a new episode even before a step


def test_a_realtime_simulator_steps_at_8_hz_holding_the_last_action(graph):
    graph.start("sim0", *sim_node_args("sim0", "-p", "mode:=realtime", "-p", "max_steps:=5"))
    rclpy.init(domain_id=int(graph.env["ROS_DOMAIN_ID"]))
    try:
        node = rclpy.create_node("watcher")
        statuses, clocks = [], []
        node.create_subscription(EpisodeStatus, "sim0/episode_status", statuses.append, 50)
        node.create_subscription(Clock, "/clock", clocks.append, 50)
        deadline = time.monotonic() + 60
        while len(statuses) < 2 and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.05)
        started, before = time.monotonic(), len(statuses)
        while time.monotonic() - started < 2.0:
            rclpy.spin_once(node, timeout_sec=0.05)
        per_second = (len(statuses) - before) / (time.monotonic() - started)
    finally:
        rclpy.shutdown()
    assert 5 <= per_second <= 11  # 8 Hz of wall time, give or take scheduling
    assert any(status.truncated for status in statuses) and len({status.episode for status in statuses}) >= 2
    steps = [status.step for status in statuses]
    assert max(steps) == 5 and 0 in steps[1:]  # episodes of 5 steps, a new one after each truncation
    status_times = {(status.header.stamp.sec, status.header.stamp.nanosec) for status in statuses}
    clock_times = [(clock.clock.sec, clock.clock.nanosec) for clock in clocks]
    assert len(clock_times) >= len(statuses) - 2 and set(clock_times[2:]) <= status_times  # /clock = simulated time


def test_a_watching_graph_resets_the_reward_at_every_episode_the_simulator_starts(graph, tiny_model):
    """No agent calls the resets of a realtime graph: the simulator asks the reward node itself."""
    steps = 5
    graph.start("reward", *reward_node_args(tiny_model, "-p", "streams:=[sim0]"))
    graph.start("sim0", *sim_node_args("sim0", "-p", "mode:=realtime", "-p", f"max_steps:={steps}"))
    rewards = graph.watch(Reward, "sim0/reward", lambda rewards: sum(r.episode_frame == 1 for r in rewards) >= 4)
    frames = [reward.episode_frame for reward in rewards]
    assert frames.count(1) >= 4, (frames, graph.log("reward"), graph.log("sim0"))
    assert max(frames) <= steps + 1, frames  # never counted across an episode: each starts at 1 again


def test_a_malformed_burst_leaves_no_valid_frame_unanswered_or_uncounted(tiny_model):
    """benchmarks/reward_node_flood.py, short: a 30 Hz camera beside a 1 kHz burst of malformed frames."""
    flood = subprocess.run(
        [sys.executable, Path(__file__).parent.parent / "benchmarks" / "reward_node_flood.py", tiny_model,
         "--seconds", "2"],
        capture_output=True, text=True, timeout=240,
    )  # fmt: skip
    assert flood.returncode == 0, flood.stdout + flood.stderr
    report = json.loads(flood.stdout)
    for name in ("flood_96", "camera_640x480", "flood_640x480"):
        phase = report[name]
        assert phase["valid_sent"] >= 30 and phase["answered"] == phase["valid_sent"], (name, phase)
        assert phase["uncounted"] == 0 and phase["malformed_rejected"] == phase["malformed_sent"], (name, phase)
    assert report["flood_96"]["malformed_sent"] >= 1000  # six kinds of malformed frames, each rejected
    assert report["node_log_lines_about_rejections"] <= 30  # each reason once, then counted per 5 s


def test_one_reward_node_answers_every_frame_of_several_free_running_cameras(tiny_model):
    """benchmarks/reward_node_cameras.py, short: two 30 Hz streams out of step, one node."""
    cameras = subprocess.run(
        [sys.executable, Path(__file__).parent.parent / "benchmarks" / "reward_node_cameras.py", tiny_model,
         "--streams", "2", "--seconds", "2"],
        capture_output=True, text=True, timeout=240,
    )  # fmt: skip
    assert cameras.returncode == 0, cameras.stdout + cameras.stderr
    report = json.loads(cameras.stdout)["streams"]["2"]
    assert [stream["stream"] for stream in report["per_stream"]] == ["cam0", "cam1"]
    for stream in report["per_stream"]:
        assert stream["valid_sent"] == 60 and stream["answered"] + stream["counted_drops"] == 60, stream
    assert report["uncounted"] == 0 and report["mean_batch"] >= 1 and report["node_cpu_percent"] > 0, report
