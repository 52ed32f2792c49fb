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
