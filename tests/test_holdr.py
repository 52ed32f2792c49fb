"""HOLD-R baseline: trains through the same command, predicts step gaps, one goal only."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from inest_reward_node.learning.data import load_demos
from inest_reward_node.runtime.model import ModelError, load_model
from inest_reward_node.runtime.rewards import replay


@pytest.fixture(scope="module")
def holdr_model_dir(tiny_demos, tmp_path_factory):
    out = tmp_path_factory.mktemp("holdr")
    command = [
        Path(sys.executable).parent / "inest-pretrain",
        tiny_demos,
        "--out",
        out,
        "--method",
        "holdr",
        "--image-size",
        "48",
        "--iterations",
        "20",
        "--pairs-per-batch",
        "32",
        "--validate-every",
        "10",
        "--learning-rate",
        "0.001",
        "--stage-head-iterations",
        "0",
    ]
    run = subprocess.run(
        command, capture_output=True, text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"}, check=False
    )
    assert run.returncode == 0, run.stderr
    assert "holdr" in run.stdout and "goals for 1 subtasks" in run.stdout
    return out / "model"


def test_holdr_model_predicts_gaps_and_rewards_at_most_zero(holdr_model_dir, tiny_demos):
    model = load_model(holdr_model_dir, scheme=1)
    assert model.method == "holdr" and sorted(model.subtasks) == [1]
    demo = load_demos(tiny_demos, "valid", "ego", 48, limit=1, progress_bar=False)[0]
    embeddings = model.embed(demo.frames)
    steps = model.holdr_steps(embeddings, model.goals(1).goals[0])
    assert steps.shape == (len(demo),) and np.isfinite(steps).all()
    played = replay(model, embeddings, 1)
    assert played.rewards.shape == (len(demo),)
    assert np.all(played.rewards <= 0.0)


def test_holdr_model_has_no_subtask_goals(holdr_model_dir):
    with pytest.raises(ModelError, match=r"goals for \[1\] subtasks, but the caller asked for 3"):
        load_model(holdr_model_dir, scheme=3)


def test_pretrain_command_reports_bad_input(tmp_path):
    run = subprocess.run(
        [Path(sys.executable).parent / "inest-pretrain", tmp_path / "nowhere", "--out", tmp_path / "out"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 2
    assert "no dataset at" in run.stderr and "metadata.json is missing" in run.stderr
