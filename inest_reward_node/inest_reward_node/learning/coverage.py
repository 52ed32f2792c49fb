"""Coverage of visited embeddings over a run (thesis 4.2.3): a PCA-to-2D occupancy grid and an
exact count of distinct embeddings after rounding, with a PNG heatmap."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass
class Coverage:
    grid: np.ndarray  # (G, G) visit counts
    occupied_cells: int
    occupied_fraction: float
    unique_states: int  # distinct embeddings after rounding to `decimals`
    samples: int


def pca_grid(embeddings: np.ndarray, grid_size: int = 100) -> np.ndarray:
    """Project onto the first two principal components, normalise to the projected bounds,
    and discretise into a grid_size x grid_size count map."""
    centred = embeddings - embeddings.mean(axis=0)
    if len(embeddings) < 2 or not np.any(centred):
        projected = np.zeros((len(embeddings), 2))
    else:
        _, _, components = np.linalg.svd(centred, full_matrices=False)
        axes = components[:2].T
        projected = centred @ (axes if axes.shape[1] == 2 else np.pad(axes, ((0, 0), (0, 1))))
    low, high = projected.min(axis=0), projected.max(axis=0)
    span = np.where(high > low, high - low, 1.0)
    # rounding first keeps float noise from dropping a point on a cell edge into the cell below
    cells = np.floor(np.round((projected - low) / span * (grid_size - 1), 9)).astype(int)
    grid = np.zeros((grid_size, grid_size), dtype=np.int64)
    np.add.at(grid, (cells[:, 1], cells[:, 0]), 1)
    return grid


def unique_states(embeddings: np.ndarray, decimals: int = 3) -> int:
    rounded = np.round(embeddings, decimals) + 0.0  # + 0.0 folds -0.0 into 0.0
    return len({row.tobytes() for row in rounded})


def measure_coverage(embeddings: np.ndarray, grid_size: int = 100, decimals: int = 3) -> Coverage:
    embeddings = np.asarray(embeddings, dtype=np.float64)
    grid = pca_grid(embeddings, grid_size)
    occupied = int(np.count_nonzero(grid))
    return Coverage(grid, occupied, occupied / grid.size, unique_states(embeddings, decimals), len(embeddings))


def plot_coverage(coverage: Coverage, path: str | Path, title: str = "embedding coverage") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    figure, axis = plt.subplots(figsize=(5, 4.5))
    counts = np.ma.masked_equal(coverage.grid, 0)
    image = axis.imshow(counts, origin="lower", cmap="viridis", norm=LogNorm(vmin=1, vmax=max(2, counts.max())))
    figure.colorbar(image, ax=axis, label="visits")
    axis.set(
        title=f"{title}\n{coverage.occupied_cells} cells ({coverage.occupied_fraction:.1%}), "
        f"{coverage.unique_states} unique of {coverage.samples}",
        xlabel="PC 1 (binned)",
        ylabel="PC 2 (binned)",
    )
    figure.tight_layout()
    figure.savefig(path, dpi=90)
    plt.close(figure)
