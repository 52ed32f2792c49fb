"""The replay buffer of a checkpoint as plain arrays (an .npz read without pickle): only the rows
filled so far, so a checkpoint grows with the steps trained, not with the buffer's capacity, and
resuming a run folder someone else wrote runs none of its code."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from stable_baselines3.common.buffers import ReplayBuffer

# the transition arrays of stable-baselines3's ReplayBuffer (SBX uses the same class), each
# (buffer_size, n_envs, ...); next_observations is None when it is optimised away
FIELDS = ("observations", "next_observations", "actions", "rewards", "dones", "timeouts")


def save_replay_buffer(buffer: ReplayBuffer, path: Path) -> None:
    rows = buffer.buffer_size if buffer.full else buffer.pos
    arrays = {name: getattr(buffer, name)[:rows] for name in FIELDS if getattr(buffer, name) is not None}
    with open(path, "wb") as handle:
        np.savez(handle, pos=np.int64(buffer.pos), full=np.bool_(buffer.full), **arrays)


def load_replay_buffer(buffer: ReplayBuffer, path: Path) -> None:
    """Fill `buffer` (a fresh one of the run's settings) from `path`; ValueError if they differ."""
    with np.load(path, allow_pickle=False) as saved:
        for name in FIELDS:
            target = getattr(buffer, name)
            if target is None:
                continue
            rows = saved[name]
            if len(rows) > len(target) or rows.shape[1:] != target.shape[1:]:
                raise ValueError(
                    f"its {name} are {rows.shape}, not rows of {target.shape[1:]} within {len(target)}: "
                    "saved with other settings"
                )
            target[: len(rows)] = rows
        buffer.pos, buffer.full = int(saved["pos"]), bool(saved["full"])
