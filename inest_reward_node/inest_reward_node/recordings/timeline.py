"""One clock for every camera: frames picked at a fixed rate from streams that tick at their own.

A recording's cameras run at their own rates and phases; a demonstration dataset has one frame
per control step. Each output time takes, per camera, the latest frame at or before it (what a
controller acting then would have seen), over the span every camera covers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

NANOSECONDS = 1_000_000_000


@dataclass(frozen=True)
class Picks:
    """Per output frame: its time (seconds from the first) and, per camera, which input frame."""

    seconds: np.ndarray  # (N,) float64
    frames: dict[str, np.ndarray]  # camera -> (N,) index into that camera's frames, in the order given


def pick_frames(stamps: dict[str, np.ndarray], rate: float) -> Picks:
    """`stamps`: per camera, its frames' times in nanoseconds, in the order the frames come.
    Output times run from the latest first frame to the earliest last frame, `rate` per second."""
    if not stamps or any(len(times) == 0 for times in stamps.values()):
        empty = [name for name, times in stamps.items() if len(times) == 0]
        raise ValueError(f"no frames from camera {', '.join(empty)}" if empty else "no camera")
    ordered = {name: np.argsort(np.asarray(times, dtype=np.int64), kind="stable") for name, times in stamps.items()}
    sorted_stamps = {name: np.asarray(stamps[name], dtype=np.int64)[order] for name, order in ordered.items()}
    start = max(int(times[0]) for times in sorted_stamps.values())
    end = min(int(times[-1]) for times in sorted_stamps.values())
    if end < start:
        raise ValueError("the cameras' recordings do not overlap in time")
    # up to a quarter period past the earliest last frame: cameras a few milliseconds out of phase
    # keep their last frames (a demonstration's last frame is where its last block counts)
    count = int(np.floor((end - start) / NANOSECONDS * rate + 0.25)) + 1
    times = start + np.round(np.arange(count) * NANOSECONDS / rate).astype(np.int64)
    frames = {name: ordered[name][np.searchsorted(sorted_stamps[name], times, side="right") - 1] for name in stamps}
    return Picks((times - start) / NANOSECONDS, frames)


def frame_at(seconds: np.ndarray, moment: float) -> int:
    """The first output frame at or after `moment` (seconds from the first frame): where an event
    seen at that moment first shows, clipped to the last frame."""
    return int(min(np.searchsorted(seconds, moment - 1e-6, side="left"), len(seconds) - 1))
