"""Shared fixtures: small, real components (real pymunk, real OpenCV rendering)."""

from __future__ import annotations

import numpy as np
import pytest
from inest_sim_node.world import World, sample_layout

from inest_sim_node import EnvConfig, LayoutConfig, SweepToTopEnv, WorldConfig


@pytest.fixture
def demo_world() -> World:
    """The fixed demo layout: red, blue, yellow at x = -0.5, 0, 0.5 on y = 0; robot at (0, -0.6)."""
    return World(WorldConfig(), sample_layout(LayoutConfig(kind="demo"), np.random.default_rng(0)))


@pytest.fixture
def env() -> SweepToTopEnv:
    environment = SweepToTopEnv(config=EnvConfig())
    yield environment
    environment.close()


@pytest.fixture(scope="session")
def tiny_demos(tmp_path_factory):
    """Ten expert demonstrations (8 train, 2 valid) at 48 px, shared by the representation tests."""
    from inest_sim_node.collect import CollectConfig, collect_dataset

    root = tmp_path_factory.mktemp("tiny_demos")
    collect_dataset(root, CollectConfig(episodes=10, valid_fraction=0.2, image_size=48, workers=1), show_progress=False)
    return root


@pytest.fixture(scope="session")
def tiny_tcc_run(tiny_demos, tmp_path_factory):
    """A TCC run of a few iterations on the tiny dataset: (config, run folder)."""
    from inest_reward_node.learning.config import CalibrationConfig, PretrainConfig
    from inest_reward_node.learning.pretrain import pretrain
    from inest_reward_node.runtime.encoders import EncoderConfig
    from inest_reward_node.runtime.stage_head import StageHeadConfig

    config = PretrainConfig(
        dataset=str(tiny_demos),
        encoder=EncoderConfig(image_size=48),
        iterations=40,
        videos_per_batch=6,
        frames_per_video=16,
        validate_every=10,
        validation_batches=1,
        checkpoint_every=10,
        learning_rate=1e-3,
        # the head reads the encoder's camera: most graph tests publish that one camera only
        calibration=CalibrationConfig(
            stage_head=StageHeadConfig(image_size=48, iterations=30, batch_size=32, view=None)
        ),
    )
    run_dir = tmp_path_factory.mktemp("tcc_run")
    pretrain(config, run_dir, progress_bar=False)
    return config, run_dir


@pytest.fixture
def tiny_model(tiny_tcc_run):
    return tiny_tcc_run[1] / "model"


@pytest.fixture
def graph(tmp_path):
    """Node processes on a private ROS domain, stopped at the end of the test."""
    from rosgraph import Processes, fresh_domain

    processes = Processes(fresh_domain(), tmp_path)
    yield processes
    processes.stop_all()
