"""Faults a user runs into, with real processes: bad parameters and corrupt run files give one line
naming the problem and exit code 2; killed nodes are respawned by the launcher; Ctrl-C and SIGTERM
checkpoint the agent and stop every process cleanly; a restarted simulator is reset and training goes on."""

from __future__ import annotations

import dataclasses
import subprocess
from pathlib import Path

import pytest
import yaml
from inest_agent_node.train import Trainer
from inest_bringup.launcher import graph_environment
from rosgraph import BIN, fresh_domain
from test_agent import tiny_config

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
        (["inest-agent-node", "-p", "subtasks:=three"], ["parameter subtasks must be an integer, got 'three'"]),
        (["inest-agent-node", "-p", "subtasks:=4"], ["subtasks must be one of (1, 3, 6), got 4"]),
        (["inest-agent-node", "-p", "sac.batch_size:=0"], ["sac.batch_size must be positive, got 0"]),
        (["inest-agent-node", "-p", "step_timeout:=0"], ["step_timeout must be positive (seconds), got 0.0"]),
        (
            ["inest-agent-node", "--params-file", str(tmp_path / "params.yaml")],
            ["inest_agent_node has no parameter total_step (did you mean total_steps?)"],
        ),
    ]
    started = [(start(tmp_path, command[0], "--ros-args", *command[1:]), expected) for command, expected in cases]
    for process, expected in started:
        assert_refused(process, *expected)


@pytest.fixture(scope="module")
def saved_run(tmp_path_factory):
    """A finished 200-step run with its checkpoint, and the YAML of its settings for inest-train."""
    root = tmp_path_factory.mktemp("saved_run")
    config = dataclasses.replace(tiny_config(200), learner="sac")
    Trainer(config, root / "run", progress_bar=False).train()
    (root / "train.yaml").write_text(yaml.safe_dump(config.to_dict()))
    return root


def damaged_copy(saved_run: Path, tmp_path: Path, name: str, damage) -> Path:
    """A copy of the saved run with checkpoint/`name` damaged by `damage(bytes) -> bytes`."""
    run = tmp_path / name.replace(".", "_")
    subprocess.run(["cp", "-r", saved_run / "run", run], check=True)
    path = run / "checkpoint" / name
    path.write_bytes(damage(path.read_bytes()))
    return run


def test_corrupt_run_files_and_an_empty_resume_are_one_line_and_exit_2(saved_run, tmp_path):
    def truncate(data: bytes) -> bytes:
        return data[: len(data) // 2]

    runs = {
        "replay_buffer.pkl": damaged_copy(saved_run, tmp_path, "replay_buffer.pkl", truncate),
        "history.json": damaged_copy(saved_run, tmp_path, "history.json", lambda data: b"[[200, 0.1"),
        "model.zip": damaged_copy(saved_run, tmp_path, "model.zip", truncate),
    }
    before = {name: (run / "checkpoint" / name).read_bytes() for name, run in runs.items()}
    config = str(saved_run / "train.yaml")
    trains = {
        name: start(tmp_path, "inest-train", "--out", str(run), "--config", config, "--resume")
        for name, run in runs.items()
    }
    empty = start(tmp_path, "inest-train", "--out", str(tmp_path / "never-ran"), "--config", config, "--resume")
    agent = start(
        tmp_path, "inest-agent-node", "--ros-args", "-p", "resume:=true", "-p", f"out:={tmp_path / 'no-agent-run'}"
    )
    for name, process in trains.items():
        assert_refused(process, "inest-train: cannot read", str(runs[name] / "checkpoint" / name))
        assert (runs[name] / "checkpoint" / name).read_bytes() == before[name]  # nothing saved is lost
    assert_refused(empty, f"nothing to resume in {tmp_path / 'never-ran'}")
    assert_refused(agent, "inest-agent-node: nothing to resume in", "no-agent-run")
