"""Faults a user runs into, with real processes: bad parameters and corrupt run files give one line
naming the problem and exit code 2; killed nodes are respawned by the launcher; Ctrl-C and SIGTERM
checkpoint the agent and stop every process cleanly; a restarted simulator is reset and training goes on."""

from __future__ import annotations

import base64
import dataclasses
import importlib.util
import json
import os
import pickle
import re
import shutil
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path
from types import SimpleNamespace

import ament_index_python.packages
import numpy as np
import pytest
import rclpy
import yaml
from inest_agent_node.checkpoint import read_manifest
from inest_agent_node.envs import build_env
from inest_agent_node.learners import learner_class
from inest_agent_node.train import Trainer, new_learner, restore_learner
from inest_bringup.launcher import graph_environment, resuming_agent
from inest_bringup.monitor import GraphMonitor
from inest_bringup.supervisor import TRAINING_NICENESS, Outcome, RespawnPolicy, Supervisor, training_cpus
from inest_common.files import NO_SPACE_EXIT, RunFileError, sha256_of
from inest_interfaces.msg import EpisodeStatus, Reward
from inest_reward_node.runtime.serving import StreamScorer
from rclpy.duration import Duration
from rosgraph import BIN, fresh_domain
from test_agent import tiny_config
from test_graph import MID_EPISODE, TINY_AGENT, count_steps, reward_node_args, sim_node_args
from test_serving import FRAMES, scorer

from inest_agent_node.config import TrainConfig

pytestmark = pytest.mark.timeout(300)


def start(tmp_path: Path, *argv: str) -> subprocess.Popen:
    env = graph_environment(fresh_domain(), tmp_path / "ros")
    return subprocess.Popen(
        [str(BIN / argv[0]), *argv[1:]], env=env, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True,
    )  # fmt: skip


def assert_refused(process: subprocess.Popen, *expected: str) -> str:
    """Exit code 2 and one stderr line (after any log lines) saying `expected`, no traceback."""
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 2, stderr
    assert "Traceback" not in stderr, stderr
    last = stderr.strip().splitlines()[-1]
    for part in expected:
        assert part in last, stderr
    return last


def test_bad_parameters_are_one_line_and_exit_2_on_every_node(tmp_path):
    (tmp_path / "params.yaml").write_text("/**/inest_agent_node:\n  ros__parameters:\n    total_step: 5\n")
    cases = [  # (command, what its error line must say), all started at once
        (["inest-sim-node", "-p", "image_size:=big"], ["parameter image_size must be an integer, got 'big'"]),
        (["inest-sim-node", "-p", "max_step:=5"], ["no parameter max_step (did you mean max_steps?)"]),
        (["inest-sim-node", "-p", "seed:=-1"], ["seed must be >= 0, got -1"]),
        (["inest-reward-node", "-p", "subtasks:=three"], ["parameter subtasks must be an integer, got 'three'"]),
        (["inest-reward-node", "-p", "max_pending:=0"], ["max_pending must be >= 1, got 0"]),
        (["inest-reward-node", "-p", "intrinsic.k:=1.5"], ["parameter intrinsic.k must be an integer, got 1.5"]),
        (["inest-reward-node", "-p", "max_pending:=[1"], ["-p 'max_pending:=[1': the value is not valid YAML"]),
        (["inest-reward-node", "-p", "max pending:=1"], ["-p 'max pending:=1' is not NAME:=VALUE"]),
        (["inest-reward-node", "-p", "streams:=[]"], ["-p 'streams:=[]': ROS cannot pass an empty list"]),
        (["inest-agent-node", "-p", "subtasks:=three"], ["parameter subtasks must be an integer, got 'three'"]),
        (["inest-agent-node", "-p", "subtasks:=4"], ["unknown subtasks 4; expected one of (1, 3, 6)"]),
        (["inest-agent-node", "-p", "sac.batch_size:=0"], ["sac.batch_size must be positive, got 0"]),
        (["inest-agent-node", "-p", "step_timeout:=0"], ["step_timeout must be positive (seconds), got 0.0"]),
        (["inest-agent-node", "-p", "reward:=inest", "-p", "model:=m"], ["reward 'inest' is scored in process"]),
        (
            ["inest-agent-node", "--params-file", str(tmp_path / "params.yaml")],
            ["inest_agent_node has no parameter total_step (did you mean total_steps?)"],
        ),
    ]
    started = [(start(tmp_path, command[0], "--ros-args", *command[1:]), expected) for command, expected in cases]
    for process, expected in started:
        assert_refused(process, *expected)


def assert_launch_refused(process: subprocess.Popen, out: Path, *expected: str) -> None:
    """inest-launch's refusal: exit code 2 and its one line saying `expected`, nothing else (no node
    started, none was to be stopped), and nothing written to its run folder `out`."""
    stdout, stderr = process.communicate(timeout=120)
    assert process.returncode == 2 and not stdout and stderr.count("\n") == 1, stdout + stderr
    assert stderr.startswith("inest-launch: ") and "started " not in stderr, stderr
    for part in expected:
        assert part in stderr, stderr
    assert not (out / "logs").exists()


def test_bad_launcher_settings_and_usage_mistakes_are_one_line_and_exit_2(tmp_path):
    cases = [
        (["--env-cpus", "999"], ["--env-cpus: CPU list '999' names CPUs this process may not run on"]),
        (["--env-cpus", "0-1000000000"], ["--env-cpus: CPU list '0-1000000000' names CPUs this process may not"]),
        (["--env-cpus", "one"], ["--env-cpus: 'one' is not a CPU list such as 1 or 0,2-3 (nor auto or all)"]),
        (["--env-cpus", "1-"], ["--env-cpus: '1-' is not a CPU list such as 1 or 0,2-3"]),
        (["--nice", "20"], ["--nice must be an integer between 0 and 19, got 20"]),
        (["--nice", "-1"], ["--nice must be an integer between 0 and 19, got -1"]),
        (["--sims", "0"], ["--sims must be at least 1"]),
        (["--respawn", "-1"], ["--respawn and --respawn-delay must be >= 0"]),
        (["--params", str(tmp_path / "nowhere.yaml")], [f"no params file at {tmp_path / 'nowhere.yaml'}"]),
        # argparse's own: an unknown flag, a missing value, a bad type, a bad choice
        (["--simulators", "2"], ["unrecognized arguments: --simulators 2"]),
        (["--steps"], ["argument --steps: expected one argument"]),
        (["--sims", "two"], ["argument --sims: invalid int value: 'two'"]),
        (["--discovery", "lan"], ["argument --discovery: invalid choice: 'lan'"]),
        (["--domain-id", "300"], ["--domain-id must be in 0..232 (ROS 2's DDS port range), got 300"]),
        (["--domain-id", "-1"], ["--domain-id must be in 0..232"]),
    ]
    out = tmp_path / "graph"
    started = [(start(tmp_path, "inest-launch", "--out", str(out), *args), expected) for args, expected in cases]
    (tmp_path / "afile").write_text("")
    a_file = start(tmp_path, "inest-launch", "--out", str(tmp_path / "afile"))
    for process, expected in started:
        assert_launch_refused(process, out, *expected)
    assert_launch_refused(a_file, tmp_path / "afile", f"--out {tmp_path / 'afile'} is a file, not a folder")
    assert not out.exists()


def test_the_launcher_refuses_what_its_agent_or_reward_node_would_before_starting_any_node(saved_run, tmp_path):
    """The refusals a node used to make once the graph was up (a policy that is not there, a run
    folder already in use or resumed with other settings, the agent's evaluation model) or never
    made (an empty list, which rcl drops: the launcher's own streams stayed and the run trained)
    come from the launcher's check."""
    held = tmp_path / "held"  # a run folder whose agent/ holds a run
    shutil.copytree(saved_run / "run", held / "agent")
    damaged = tmp_path / "damaged"  # ... and one whose checkpoint lost a byte of its learner's weights
    shutil.copytree(saved_run / "run", damaged / "agent")
    weights = damaged / "agent" / "checkpoint" / "learner.safetensors"
    weights.write_bytes(weights.read_bytes()[:-1] + b"\x00")
    policy, model, streams = tmp_path / "policy", tmp_path / "model", tmp_path / "streams"
    evaluate = ["--param", "agent:mode:=evaluate", "--param", "agent:policy:=/nonexistent"]
    cases = [  # (run folder, arguments, what the line says)
        (policy, evaluate, "agent refused its configuration: inest-agent-node: no exported policy at /nonexistent"),
        (held, [], f"agent refused its configuration: inest-agent-node: {held / 'agent'} already holds a run; pass"),
        (held, ["--resume"], f"inest-agent-node: cannot resume {held / 'agent'}: settings differ from the saved run"),
        (model, ["--param", "agent:model:=/nowhere"], "inest-agent-node: no reward model at /nowhere"),
        (streams, ["--param", "reward:streams:=[]"], "-p 'streams:=[]': ROS cannot pass an empty list"),
        (damaged, ["--resume"], f"checkpoint {damaged / 'agent' / 'checkpoint'} is damaged: learner.safetensors"),
    ]
    before = sorted(path.relative_to(held) for path in held.rglob("*"))
    started = [(start(tmp_path, "inest-launch", "--out", str(out), *args), out, line) for out, args, line in cases]
    for process, out, line in started:
        assert_launch_refused(process, out, line, "; nothing was started")
    assert not policy.exists() and not model.exists() and not streams.exists()
    assert sorted(path.relative_to(held) for path in held.rglob("*")) == before  # the run is left as it was


@pytest.fixture(scope="module")
def saved_run(tmp_path_factory):
    """A finished 200-step run with its checkpoint, and the YAML of its settings for inest-train."""
    root = tmp_path_factory.mktemp("saved_run")
    config = dataclasses.replace(tiny_config(200), learner="sac")
    Trainer(config, root / "run", progress_bar=False).train()
    (root / "train.yaml").write_text(yaml.safe_dump(config.to_dict()))
    return root


def damaged_copy(saved_run: Path, tmp_path: Path, name: str, damage, rehash: bool = True) -> Path:
    """A copy of the saved run with checkpoint/`name` damaged by `damage(bytes) -> bytes`;
    `rehash`: its manifest's sha256 made the damaged file's, so that its reader meets the damage."""
    run = tmp_path / (name.replace(".", "_") + ("" if rehash else "_unhashed"))
    subprocess.run(["cp", "-r", saved_run / "run", run], check=True)
    path = run / "checkpoint" / name
    path.write_bytes(damage(path.read_bytes()))
    if rehash:
        manifest = json.loads((run / "checkpoint" / "checkpoint.json").read_text())
        manifest["sha256"][name] = sha256_of(path)
        (run / "checkpoint" / "checkpoint.json").write_text(json.dumps(manifest))
    return run


def test_corrupt_run_files_and_an_empty_resume_are_one_line_and_exit_2(saved_run, tmp_path):
    def garble(data: bytes) -> bytes:  # the size its manifest says, the content unreadable
        return b"\x07" * len(data)

    runs = {
        "replay_buffer.npz": damaged_copy(saved_run, tmp_path, "replay_buffer.npz", garble),
        "history.json": damaged_copy(saved_run, tmp_path, "history.json", garble),
        "learner.safetensors": damaged_copy(saved_run, tmp_path, "learner.safetensors", garble),
    }
    truncated = damaged_copy(saved_run, tmp_path, "diagnostics.json", lambda data: data[: len(data) // 2])
    flipped = damaged_copy(saved_run, tmp_path, "learner.safetensors", garble, rehash=False)
    before = {name: (run / "checkpoint" / name).read_bytes() for name, run in runs.items()}
    config = str(saved_run / "train.yaml")
    configs = {name: (run / "config.json").read_text() for name, run in runs.items()}
    trains = {  # another total_steps: a refused resume must not rewrite config.json with it
        name: start(tmp_path, "inest-train", "--out", str(run), "--config", config, "--resume", "--total-steps", "500")
        for name, run in runs.items()
    }
    empty = start(tmp_path, "inest-train", "--out", str(tmp_path / "never-ran"), "--config", config, "--resume")
    bare = start(tmp_path, "inest-train", "--out", str(tmp_path / "never-ran"), "--resume")  # no settings given
    agent = start(
        tmp_path, "inest-agent-node", "--ros-args", "-p", "resume:=true", "-p", f"out:={tmp_path / 'no-agent-run'}"
    )
    partial = start(tmp_path, "inest-train", "--out", str(truncated), "--config", config, "--resume")
    unhashed = start(tmp_path, "inest-train", "--out", str(flipped), "--config", config, "--resume")
    for name, process in trains.items():
        assert_refused(process, "inest-train: cannot read", str(runs[name] / "checkpoint" / name))
        assert (runs[name] / "checkpoint" / name).read_bytes() == before[name]  # nothing saved is lost
        assert (runs[name] / "config.json").read_text() == configs[name]
    assert_refused(unhashed, f"checkpoint {flipped / 'checkpoint'} is damaged: learner.safetensors is not the file")
    assert_refused(partial, f"checkpoint {truncated / 'checkpoint'} is not whole: diagnostics.json is")
    assert_refused(empty, f"nothing to resume in {tmp_path / 'never-ran'}")
    assert_refused(bare, f"nothing to resume in {tmp_path / 'never-ran'}")  # not "the reward needs a model"
    pretrain = start(tmp_path, "inest-pretrain", str(tmp_path / "no-dataset"), "--out", str(tmp_path / "no-model"))
    assert_refused(pretrain, f"inest-pretrain: no dataset at {tmp_path / 'no-dataset'}")
    assert not (tmp_path / "no-model").exists()  # nothing written before the refusal: a rerun is not blocked
    assert_refused(agent, "inest-agent-node: nothing to resume in", "no-agent-run")


class CreatesMarker:
    """Unpickled, it creates the file `path`: the payload a foreign model.zip can carry."""

    def __init__(self, path: Path) -> None:
        self.path = str(path)

    def __reduce__(self):
        return open, (self.path, "w")


def test_a_pickled_model_zip_in_a_run_folder_is_refused_and_none_of_its_code_runs(saved_run, tmp_path):
    run, marker = tmp_path / "foreign", tmp_path / "payload-ran"
    subprocess.run(["cp", "-r", saved_run / "run", run], check=True)
    checkpoint = run / "checkpoint"
    for name in ("learner.json", "learner.safetensors"):  # laid out as INEST wrote checkpoints before
        (checkpoint / name).unlink()
    manifest = json.loads((checkpoint / "checkpoint.json").read_text())
    (checkpoint / "checkpoint.json").write_text(json.dumps({key: manifest[key] for key in ("steps", "training_s")}))
    entry = {":type:": "<class 'type'>", ":serialized:": base64.b64encode(pickle.dumps(CreatesMarker(marker))).decode()}
    with zipfile.ZipFile(checkpoint / "model.zip", "w") as archive:
        archive.writestr("data", json.dumps({"policy_class": entry}))
    loads = "import sys\nfrom stable_baselines3 import SAC\ntry: SAC.load(sys.argv[1])\nexcept Exception: pass"
    subprocess.run([sys.executable, "-c", loads, checkpoint / "model.zip"], check=True, timeout=120)
    assert marker.exists()  # the payload is live: stable-baselines3's load runs it
    marker.unlink()
    resume = start(tmp_path, "inest-train", "--out", str(run), "--config", str(saved_run / "train.yaml"), "--resume")
    assert_refused(
        resume, f"{checkpoint / 'model.zip'} is a stable-baselines3 model.zip with pickled entries (policy_class)"
    )
    config = TrainConfig.from_dict(json.loads((run / "config.json").read_text()))
    with pytest.raises(RunFileError, match="pickled entries"):  # what inest-record-clips loads a policy with
        restore_learner(new_learner(learner_class(config.learner), config, build_env(config, 1)), config.learner, run)
    assert not marker.exists()


def unshare_tmpfs() -> list[str] | None:
    """The command prefix that runs a shell in its own mount namespace (util-linux unshare), where
    it may mount a small tmpfs without privileges; None where the kernel or sandbox forbids it."""
    prefix = ["unshare", "--user", "--map-root-user", "--mount"]
    try:
        probe = subprocess.run([*prefix, "mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", "/mnt"], timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return prefix if probe.returncode == 0 else None


def test_a_full_disk_keeps_the_last_checkpoint_whole_says_one_line_and_the_run_resumes(saved_run, tmp_path):
    prefix = unshare_tmpfs()
    if prefix is None:
        pytest.skip("no unprivileged mount namespace here to fill a small disk in")
    config = yaml.safe_load((saved_run / "train.yaml").read_text())
    (tmp_path / "slow.yaml").write_text(yaml.safe_dump({**config, "total_steps": 100_000, "checkpoint_minutes": 0.01}))
    disk, kept = tmp_path / "disk", tmp_path / "kept"
    disk.mkdir()
    train = f"{BIN / 'inest-train'} --out {disk}/run --config {tmp_path / 'slow.yaml'}"
    script = f"""
mount -t tmpfs -o size=16m tmpfs {disk}
{train} 2> {tmp_path}/stderr &
until [ -f {disk}/run/checkpoint/checkpoint.json ]; do sleep 0.1; done
dd if=/dev/zero of={disk}/filler bs=64k 2> /dev/null  # the disk fills between two checkpoints
wait $!
echo $? > {tmp_path}/status
cp -r {disk}/run {kept}
"""
    subprocess.run(
        [*prefix, "bash", "-c", script], env=graph_environment(fresh_domain(), tmp_path / "ros"), timeout=240
    )
    stderr = (tmp_path / "stderr").read_text()
    assert (tmp_path / "status").read_text().strip() == str(NO_SPACE_EXIT), stderr
    assert "Traceback" not in stderr, stderr
    line = stderr.strip().splitlines()[-1]
    steps = read_manifest(kept / "checkpoint")["steps"]  # the last good checkpoint, whole
    assert "inest-train: no space left on the device for the checkpoint at step" in line, stderr
    assert f"the checkpoint at step {steps} is kept" in line and 0 < steps < 100_000
    assert not (kept / ".checkpoint.partial").exists()
    resumed = start(tmp_path, "inest-train", "--out", str(kept), "--config", str(tmp_path / "slow.yaml"), "--resume",
                    "--total-steps", str(steps + 8))  # fmt: skip
    assert resumed.communicate(timeout=120)[0] and resumed.returncode == 0
    results = json.loads((kept / "results.json").read_text())
    assert results["steps"] == steps + 8


def test_a_killed_run_resumes_from_a_timed_checkpoint_and_one_without_a_checkpoint_is_refused(saved_run, tmp_path):
    config = yaml.safe_load((saved_run / "train.yaml").read_text())
    slow = {**config, "total_steps": 100_000, "checkpoint_every": 100_000, "checkpoint_minutes": 0.01}
    (tmp_path / "slow.yaml").write_text(yaml.safe_dump(slow))
    run = tmp_path / "run"
    train = ["inest-train", "--out", str(run), "--config", str(tmp_path / "slow.yaml")]
    process = start(tmp_path, *train)
    info = run / "checkpoint" / "checkpoint.json"
    deadline = time.monotonic() + 120
    while not info.exists() and time.monotonic() < deadline:
        time.sleep(0.2)
    process.kill()  # no chance to save anything more
    process.communicate()
    steps = json.loads(info.read_text())["steps"]
    assert 0 < steps < 100_000  # written by the clock, long before the first checkpoint_every
    with np.load(run / "checkpoint" / "replay_buffer.npz") as replay:  # every step counted is stored
        assert int(replay["pos"]) * config["num_envs"] == steps
    assert_refused(start(tmp_path, *train, "--start-over"), f"{run} has a checkpoint at step {steps}: resume it")
    resumed = start(tmp_path, *train, "--resume", "--total-steps", str(steps + 8))
    assert resumed.communicate(timeout=120)[0] and resumed.returncode == 0
    assert json.loads((run / "results.json").read_text())["steps"] == steps + 8  # it went on, not from 0
    # a run killed before its first checkpoint: --resume says so and trains nothing; --start-over trains it again
    unfinished = tmp_path / "unfinished"
    unfinished.mkdir()
    (unfinished / "config.json").write_text(json.dumps(config))
    short = ["inest-train", "--out", str(unfinished), "--config", str(saved_run / "train.yaml")]
    assert_refused(start(tmp_path, *short, "--resume"), "the run stopped before its first checkpoint", "--start-over")
    assert not (unfinished / "checkpoint").exists()
    started_over = start(tmp_path, *short, "--start-over")
    assert started_over.communicate(timeout=120)[0] and started_over.returncode == 0
    assert json.loads((unfinished / "results.json").read_text())["steps"] == config["total_steps"]


def test_a_respawned_agent_resumes_its_checkpoint_or_starts_over_and_says_so(tmp_path, capsys):
    command = resuming_agent(tmp_path)
    argv = ["inest-agent-node", "--ros-args", "-p", "resume:=true", "-p", "total_steps:=10"]
    assert command("sim0", ["inest-sim-node"]) == ["inest-sim-node"]
    assert command("agent", argv) == argv  # no run yet: started as it was
    (tmp_path / "agent").mkdir()
    (tmp_path / "agent" / "config.json").write_text("{}")
    restarted = command("agent", argv)
    assert restarted == ["inest-agent-node", "--ros-args", "-p", "total_steps:=10", "-p", "start_over:=true"]
    assert "the agent stopped before its first checkpoint; its run in" in capsys.readouterr().out
    (tmp_path / "agent" / "checkpoint").mkdir()
    (tmp_path / "agent" / "checkpoint" / "checkpoint.json").write_text("{}")
    assert command("agent", restarted) == [*argv[:2], "-p", "total_steps:=10", "-p", "resume:=true"]


def test_the_supervisor_restarts_with_back_off_and_stops_a_node_that_keeps_dying(tmp_path):
    def supervise(name: str, code: int, policy: RespawnPolicy) -> Supervisor:
        script = f"import sys; print('run of {name}'); sys.exit({code})"
        supervisor = Supervisor([(name, [sys.executable, "-c", script])], tmp_path, dict(os.environ), policy)
        supervisor.start_all()
        while not supervisor.check():
            time.sleep(0.01)
        return supervisor

    dying = supervise("sim0", 3, RespawnPolicy(max_respawns=2, delay=0.05))
    assert dying.outcome.status == 1
    assert "sim0 keeps dying (exit status 3 after 2 restarts)" in dying.outcome.message
    assert (tmp_path / "sim0.log").read_text().count("run of sim0") == 3  # the first run and two restarts
    supervise("sim0", 3, RespawnPolicy(max_respawns=2, delay=0.05))  # launched again into the same folder
    kept = (tmp_path / "sim0.log").read_text()
    assert kept.count("run of sim0") == 6 and kept.count("--- inest-launch: started again") == 1  # nothing lost
    refusing = supervise("reward", 2, RespawnPolicy(delay=0.05))
    assert refusing.outcome == Outcome(2, "reward refused its configuration: run of reward")  # never restarted
    assert supervise("agent", 0, RespawnPolicy()).outcome == Outcome(0, "")  # the run is over
    full = supervise("agent", NO_SPACE_EXIT, RespawnPolicy(delay=0.05))  # a restart would fill the disk again
    assert full.outcome == Outcome(NO_SPACE_EXIT, "agent ran out of disk space: run of agent")
    assert (tmp_path / "agent.log").read_text().count("run of agent") == 2  # the two launches, no restart


def test_the_ros_launch_file_respawns_simulators_and_reward_node_as_inest_launch_does(monkeypatch):
    """inest.launch.py with stand-ins for `launch` and `launch_ros` (not on PyPI; the Docker
    image runs the real ones): the nodes it starts and their respawn settings."""

    class Node:  # launch_ros.actions.Node: keeps what the launch file asks for
        def __init__(self, **settings):
            self.settings = settings

    class LaunchConfiguration:
        def __init__(self, name: str):
            self.name = name

        def perform(self, context: dict) -> str:
            return context[self.name]

    def action(*args, **kwargs):
        return args, kwargs

    stand_ins = {
        "launch": SimpleNamespace(LaunchDescription=list),
        "launch.actions": SimpleNamespace(
            DeclareLaunchArgument=action, OpaqueFunction=action, SetEnvironmentVariable=action
        ),
        "launch.substitutions": SimpleNamespace(LaunchConfiguration=LaunchConfiguration),
        "launch_ros": SimpleNamespace(),
        "launch_ros.actions": SimpleNamespace(Node=Node),
    }
    for name, module in stand_ins.items():
        monkeypatch.setitem(sys.modules, name, module)
    monkeypatch.setattr(ament_index_python.packages, "get_package_share_directory", lambda package: package)
    path = Path(__file__).resolve().parent.parent / "ros2_ws/src/inest_bringup/launch/inest.launch.py"
    spec = importlib.util.spec_from_file_location("inest_launch_file", path)
    launch_file = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(launch_file)
    arguments = {"sims": "2", "params_file": "inest.params.yaml", "mode": "lockstep", "model": "", "agent": "true",
                 "nice": str(TRAINING_NICENESS), "env_cpus": "all"}  # fmt: skip
    nodes = launch_file.graph(arguments | {"out": "runs/graph/agent"})
    executables = [node.settings["executable"] for node in nodes]
    assert executables == ["inest-sim-node", "inest-sim-node", "inest-reward-node", "inest-agent-node"]
    policy = RespawnPolicy()
    for node in nodes[:3]:
        respawn = {key: node.settings[key] for key in ("respawn", "respawn_delay", "respawn_max_retries")}
        assert respawn == {"respawn": True, "respawn_delay": policy.delay, "respawn_max_retries": policy.max_respawns}
    assert "respawn" not in nodes[3].settings  # a restarted agent must resume: not done behind the user's back
    assert [node.settings["namespace"] for node in nodes[:2]] == ["sim0", "sim1"]
    # while the agent trains, the environment side runs nicer than it, as under inest-launch
    assert [node.settings.get("prefix") for node in nodes] == [f"nice -n {TRAINING_NICENESS}"] * 3 + [None]
    # ... and on the CPUs given, here the one CPU the test runs on
    cpu = min(os.sched_getaffinity(0))
    pinned = launch_file.graph(arguments | {"env_cpus": str(cpu), "out": "runs/graph/agent"})
    assert pinned[0].settings["prefix"] == f"taskset -c {cpu} nice -n {TRAINING_NICENESS}"
    with pytest.raises(ValueError, match="nice:=20: must be an integer between 0 and 19"):
        launch_file.graph(arguments | {"nice": "20", "out": "runs/graph/agent"})
    with pytest.raises(ValueError, match="env_cpus:=one: 'one' is not a CPU list"):
        launch_file.graph(arguments | {"env_cpus": "one", "out": "runs/graph/agent"})
    watching = launch_file.graph(arguments | {"agent": "false", "out": "runs/graph/agent"})
    assert [node.settings.get("prefix") for node in watching] == [None] * 3


def launch(tmp_path: Path, tiny_model: Path, *extra: str) -> subprocess.Popen:
    out = open(tmp_path / "launcher.log", "w")  # noqa: SIM115 (closed with the process)
    return subprocess.Popen(
        [BIN / "inest-launch", "--out", tmp_path / "graph", "--model", tiny_model, "--domain-id", extra[0],
         "--interval", "1", "--param", "sim:image_size:=48", *extra[1:]],
        stdout=out, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip


def wait_for_line(path: Path, text: str) -> None:
    while text not in path.read_text():
        time.sleep(0.2)


def test_a_killed_launcher_takes_its_nodes_along_and_the_agent_checkpoints_for_a_resume(tiny_model, tmp_path):
    domain = fresh_domain()
    agent = [arg for value in TINY_AGENT[1::2] for arg in ("--param", f"agent:{value}")]
    launcher = launch(tmp_path, tiny_model, str(domain), "--steps", "100000", *agent)
    assert count_steps(graph_environment(domain, tmp_path / "ros"), 150, timeout=180) >= 150
    log = (tmp_path / "launcher.log").read_text()
    pids = [int(pid) for pid in re.findall(r"started \w+ \(pid (\d+)\)", log)]
    launcher.kill()  # SIGKILL: the launcher cannot pass anything on itself
    launcher.wait()
    deadline = time.monotonic() + 60
    while any(Path(f"/proc/{pid}").exists() for pid in pids) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not [pid for pid in pids if Path(f"/proc/{pid}").exists()]  # no node outlives it
    agent_log = (tmp_path / "graph" / "logs" / "agent.log").read_text()
    steps = int(re.search(r"stopped at step (\d+); checkpoint saved", agent_log)[1])
    resumed = launch(tmp_path, tiny_model, str(domain), "--steps", str(steps + 50), "--resume", *agent)
    assert resumed.wait(180) == 0
    assert (
        f"the agent resumes {tmp_path / 'graph' / 'agent'} from its checkpoint at step {steps}"
        in (tmp_path / "launcher.log").read_text()
    )


def test_a_bad_configuration_stops_the_launcher_before_any_node_starts(tiny_model, tmp_path):
    cases = {  # --param, the line that names it
        "reward:max_pending:=0": "reward refused its configuration: inest-reward-node: max_pending must be >= 1, got 0",
        "agent:sac.batch_size:=0": "agent refused its configuration: inest-agent-node: sac.batch_size must be positive",
        "sim:image_size:=[1": "sim0 refused its configuration: inest-sim-node: -p 'image_size:=[1': the value is not",
        "reward:model:=nowhere": "reward refused its configuration: inest-reward-node: ",
    }
    for index, (setting, expected) in enumerate(cases.items()):
        folder = tmp_path / str(index)
        folder.mkdir()
        launcher = launch(folder, tiny_model, str(fresh_domain()), "--param", setting)
        assert launcher.wait(120) == 2
        output = (folder / "launcher.log").read_text()
        assert f"inest-launch: {expected}" in output and "nothing was started" in output, output
        assert "Traceback" not in output and "started" not in output.replace("nothing was started", "")
        assert not list((folder / "graph" / "logs").glob("*.log"))  # no node ran, no log to clean up


def assert_runs_as_environment(pid: int) -> None:
    """The simulator runs nicer than the agent, whose update sets the pace of training, and off its CPU."""
    assert os.getpriority(os.PRIO_PROCESS, pid) == min(19, os.getpriority(os.PRIO_PROCESS, 0) + TRAINING_NICENESS)
    assert os.sched_getaffinity(pid) == (training_cpus("auto") or os.sched_getaffinity(0))


def test_the_launcher_respawns_a_killed_simulator_and_ctrl_c_checkpoints_the_agent(tiny_model, tmp_path):
    domain = fresh_domain()
    agent = [arg for value in [*TINY_AGENT[1::2], "step_timeout:=1.0"] for arg in ("--param", f"agent:{value}")]
    launcher = launch(tmp_path, tiny_model, str(domain), "--steps", "100000", "--respawn-delay", "0.5", *agent)
    env = graph_environment(domain, tmp_path / "ros")
    assert count_steps(env, 150, timeout=180) >= 150
    pid = int(re.search(r"started sim0 \(pid (\d+)\)", (tmp_path / "launcher.log").read_text())[1])
    assert_runs_as_environment(pid)
    os.kill(pid, signal.SIGKILL)
    wait_for_line(tmp_path / "launcher.log", "restarted sim0")
    assert count_steps(env, 100, timeout=180) >= 100  # the agent reset the new simulator and trains on
    assert_runs_as_environment(
        int(re.search(r"restarted sim0 \(pid (\d+)\)", (tmp_path / "launcher.log").read_text())[1])
    )
    launcher.send_signal(signal.SIGINT)
    assert launcher.wait(180) == 130
    logs = tmp_path / "graph" / "logs"
    assert "sim0: the simulator restarted; resetting it" in (logs / "agent.log").read_text()
    assert "checkpoint saved" in (logs / "agent.log").read_text()
    assert (tmp_path / "graph" / "agent" / "checkpoint" / "learner.json").exists()
    for log in [tmp_path / "launcher.log", *logs.glob("*.log")]:
        assert "Traceback" not in log.read_text(), log


def test_the_agent_resets_a_restarted_simulator_and_finishes(graph, tiny_model, tmp_path):
    graph.start("sim0", *sim_node_args("sim0"))
    graph.start("reward", *reward_node_args(tiny_model, "-p", "streams:=[sim0]"))
    agent = graph.start(
        "agent", "inest-agent-node", "--ros-args", "-p", "namespaces:=[sim0]", "-p", f"out:={tmp_path / 'run'}",
        "-p", f"model:={tiny_model}",
        "-p", "total_steps:=300", "-p", "step_timeout:=1.0", *TINY_AGENT,
    )  # fmt: skip
    assert count_steps(graph.env, 150, timeout=120, into_episode=MID_EPISODE) >= 150
    graph.running["sim0"].kill()
    graph.running["sim0"].wait()
    graph.start("sim0-restarted", *sim_node_args("sim0"))  # its clock and episodes start over
    assert agent.wait(240) == 0, graph.log("agent")
    assert json.loads((tmp_path / "run" / "results.json").read_text())["steps"] == 300
    assert "sim0: the simulator restarted; resetting it" in graph.log("agent")


def test_the_subtask_reaches_num_subtasks_in_the_reward_and_the_monitor_shows_done(tmp_path):
    streams = StreamScorer(scorer(1))
    streams.scorer.trackers[0].completed = 3  # every subtask done
    streams.submit(0, 50, FRAMES[0])
    assert streams.flush()[0].completed == 3 == streams.scorer.num_subtasks  # what Reward.subtask carries
    rclpy.init(domain_id=fresh_domain())
    try:
        monitor = GraphMonitor(["sim0"])
        for subtask in (1, 2, 3):
            monitor.on_reward(0, Reward(total=float(subtask), subtask=subtask, num_subtasks=3))
        assert "sim0: r +3.000 subtask 3/3 done" in monitor.line()
        axis = monitor.trace_figure().axes[1]
        assert [label.get_text() for label in axis.get_yticklabels()] == ["0", "1", "2", "done"]
        assert list(axis.lines[0].get_ydata()) == [1, 2, 3]
        monitor.destroy_node()
    finally:
        rclpy.shutdown()


def test_the_monitor_says_how_sure_the_reward_has_been_of_done_not_one_frames_doubt(tmp_path):
    """Rewards as the default model's reward node sent them for the trained policy: the stage head
    doubted, for a frame, the block the tracker had seen placed. inest-monitor used to show that
    one frame's confidence beside "done" (`done (sure 0.01)`); it shows the mean since done."""
    domain = fresh_domain()
    monitor = subprocess.Popen(
        [BIN / "inest-monitor", "--namespaces", "sim0", "--interval", "0.2", "--duration", "60"],
        env=graph_environment(domain, tmp_path / "ros"), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    rclpy.init(domain_id=domain)
    try:
        node = rclpy.create_node("reward_node_stand_in")
        rewards = node.create_publisher(Reward, "sim0/reward", 100)
        status = node.create_publisher(EpisodeStatus, "sim0/episode_status", 100)
        deadline = time.monotonic() + 60
        while not (rewards.get_subscription_count() and status.get_subscription_count()):
            assert time.monotonic() < deadline and monitor.poll() is None, "inest-monitor never subscribed"
            rclpy.spin_once(node, timeout_sec=0.05)
        for frame, (subtask, confidence) in enumerate([(2, 0.9), (3, 0.99), (3, 0.98), (3, 0.01)], start=38):
            rewards.publish(
                Reward(total=6.0, subtask=subtask, num_subtasks=3, stage_confidence=confidence, episode_frame=frame)
            )
        assert rewards.wait_for_all_acked(Duration(seconds=30))
        time.sleep(1.0)  # taken in before the step below makes the monitor print its line
        status.publish(EpisodeStatus(step=41))
        assert status.wait_for_all_acked(Duration(seconds=30))
    finally:
        rclpy.shutdown()
    line = ""
    while "done" not in line and (line := monitor.stdout.readline()):
        pass
    monitor.send_signal(signal.SIGINT)
    monitor.communicate(timeout=30)
    assert "sim0: r +6.000 subtask 3/3 done (sure 0.66)" in line, line  # (0.99 + 0.98 + 0.01) / 3


def test_inest_train_refuses_a_missing_model_before_writing_anything(tmp_path):
    config = Path(__file__).resolve().parents[1] / "inest_agent_node" / "config" / "train.yaml"
    out = tmp_path / "run"
    process = subprocess.run(
        [str(BIN / "inest-train"), "--config", str(config), "--model", str(tmp_path / "nowhere"), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert process.returncode == 2 and process.stderr.count("\n") == 1, process.stderr
    assert "nowhere" in process.stderr and not out.exists()  # no config.json left to refuse the next try
