"""Coverage numbers on synthetic embedding clouds."""

from __future__ import annotations

import numpy as np
from inest_reward_node.learning.coverage import measure_coverage, plot_coverage, unique_states


def lattice_cloud(side: int, repeats: int, dim: int = 8) -> np.ndarray:
    """side x side lattice points (wider than tall, so the principal axes are the lattice's) in a
    random 2-D plane of a dim-D space, each visited `repeats` times."""
    rng = np.random.default_rng(0)
    plane = np.linalg.qr(rng.normal(size=(dim, 2)))[0].T  # orthonormal 2 x dim
    xs, ys = np.meshgrid(np.arange(side) * 1.0, np.arange(side) * 0.5)
    points = np.stack([xs.ravel(), ys.ravel()], axis=1) @ plane
    return np.repeat(points, repeats, axis=0)


def test_a_lattice_fills_exactly_its_cells():
    coverage = measure_coverage(lattice_cloud(side=10, repeats=3), grid_size=10)
    assert coverage.occupied_cells == 100 and coverage.occupied_fraction == 1.0
    assert coverage.unique_states == 100 and coverage.samples == 300
    assert coverage.grid.sum() == 300 and np.all(coverage.grid == 3)


def test_a_concentrated_cloud_covers_little():
    cloud = np.concatenate([lattice_cloud(10, 1), np.zeros((900, 8))])
    coverage = measure_coverage(cloud, grid_size=100)
    assert coverage.unique_states == 100  # the origin is a lattice point
    assert coverage.occupied_cells <= 100
    assert coverage.grid.max() >= 900


def test_rounding_merges_near_duplicates(tmp_path):
    base = np.random.default_rng(1).normal(size=(50, 4))
    jittered = np.concatenate([base, base + 1e-5])
    assert unique_states(jittered, decimals=3) <= 52  # rounding boundaries may split a few
    assert unique_states(jittered, decimals=6) == 100
    path = tmp_path / "coverage.png"
    plot_coverage(measure_coverage(jittered), path)
    assert path.stat().st_size > 5000
