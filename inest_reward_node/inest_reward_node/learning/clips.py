"""Labelled clips: episodes of some behaviour with every frame's true ordered progress, the
negatives that calibration fits thresholds and the stage classifier against and that the
quality report counts false completions on.

Built in: random play (uniform random actions: what a policy does before it has learnt
anything) and wrong-order play (the scripted expert placing the blocks in a wrong order).
Any other behaviour, such as a trained policy's own rollouts (`inest-record-clips`), is saved
with `save_clips` and passed to `inest-pretrain --clips` / `inest-reward-quality --clips`.
In simulation the labels come from the simulator; on a robot they would be labelled by hand.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from inest_common.files import write_atomic
from inest_sim_node.expert import TASK_ORDER, ScriptedExpert
from inest_sim_node.subtasks import completed_subtasks

from inest_sim_node import EnvConfig, SweepToTopEnv

RANDOM_PLAY_SEED = 40_000_000  # layouts no demonstration, training or evaluation episode uses
WRONG_ORDER_SEED = 40_500_000
WRONG_ORDERS = tuple(
    order
    for order in ((1, 0, 2), (2, 0, 1), (0, 2, 1), (1, 2, 0), (2, 1, 0))  # every order but the task's
    if order != TASK_ORDER
)


class ClipError(ValueError):
    """A clip file that cannot be read, or that does not fit the model it is used with."""


@dataclass
class Clip:
    """One episode of some behaviour, camera frame after every step."""

    frames: np.ndarray  # (steps, S, S, 3) uint8
    progress: np.ndarray  # (steps,) ordered blocks in the goal
    held: np.ndarray  # (steps,) the current block sits in the gripper

    def not_yet_completed(self, scheme: int, subtask: int) -> np.ndarray:
        """Frames on which `subtask` has not really been completed: where its completion is false."""
        return completed_subtasks(self.progress, self.held, scheme) <= subtask


def play(env: SweepToTopEnv, act: Callable[[SweepToTopEnv], np.ndarray], seed: int, view: str, image_size: int) -> Clip:
    """One episode on layout `seed` under `act(env) -> action`, until the environment truncates it."""
    env.reset(seed=seed)
    frames, progress, held, done = [], [], [], False
    while not done:
        _, _, terminated, truncated, _ = env.step(act(env))
        frames.append(env.render_camera(view, image_size))
        progress.append(env.progress)
        held.append(env.holds_current_block)
        done = terminated or truncated
    return Clip(np.stack(frames), np.array(progress), np.array(held))


def random_play(view: str, image_size: int, episodes: int, seed: int = RANDOM_PLAY_SEED) -> list[Clip]:
    env = SweepToTopEnv(config=EnvConfig(view=view, image_size=image_size))
    rng = np.random.default_rng(seed)
    try:
        return [
            play(env, lambda _: rng.uniform(-1.0, 1.0, 3), seed + episode, view, image_size)
            for episode in range(episodes)
        ]
    finally:
        env.close()


def wrong_order_play(
    view: str,
    image_size: int,
    episodes: int,
    seed: int = WRONG_ORDER_SEED,
    orders: Sequence[tuple[int, ...]] = WRONG_ORDERS,
) -> list[Clip]:
    """The scripted expert placing the blocks in a wrong order (cycling through `orders`): frames
    that look like progress but are not (the environment counts at most the prefix in order)."""
    env = SweepToTopEnv(config=EnvConfig(view=view, image_size=image_size))
    try:
        return [
            play(
                env,
                ScriptedExpert(seed=seed + episode, order=orders[episode % len(orders)]).act,
                seed + episode,
                view,
                image_size,
            )
            for episode in range(episodes)
        ]
    finally:
        env.close()


LABELLERS = ("simulator", "file")  # who labelled a clip file's frames: the simulator, or a person's label file


def save_clips(path: str | Path, clips: Sequence[Clip], view: str, source: str, labelled_by: str = "simulator") -> None:
    """One compressed .npz: every clip's frames, progress and held flags, the view, a `source`
    line saying what behaviour they show and who labelled them (LABELLERS)."""
    if labelled_by not in LABELLERS:
        raise ValueError(f"labelled_by must be one of {LABELLERS}, got {labelled_by!r}")
    arrays: dict[str, np.ndarray] = {
        "view": np.array(view),
        "source": np.array(source),
        "labelled_by": np.array(labelled_by),
    }
    for index, clip in enumerate(clips):
        arrays[f"frames_{index}"] = clip.frames
        arrays[f"progress_{index}"] = clip.progress
        arrays[f"held_{index}"] = clip.held

    def write(temporary: Path) -> None:
        with open(temporary, "wb") as handle:
            np.savez_compressed(handle, **arrays)

    write_atomic(Path(path), write)  # a killed recording never leaves a truncated clip file


def clip_file_labels(path: str | Path) -> tuple[int, str]:
    """(episodes, who labelled them) of a clip file, without reading its frames; files written
    before the labeller was recorded came from the simulator."""
    try:
        with np.load(path) as data:
            labelled_by = str(data["labelled_by"]) if "labelled_by" in data.files else "simulator"
            return sum(1 for key in data.files if key.startswith("frames_")), labelled_by
    except (OSError, ValueError) as error:
        raise ClipError(f"{path}: not a clip file of inest-record-clips ({error})") from error


def load_clips(path: str | Path, view: str, image_size: int) -> list[Clip]:
    """The clips of `save_clips`, checked against the view and image size they will be embedded at."""
    try:
        with np.load(path) as data:
            saved_view = str(data["view"])
            count = sum(1 for key in data.files if key.startswith("frames_"))
            clips = [
                Clip(data[f"frames_{index}"], data[f"progress_{index}"], data[f"held_{index}"])
                for index in range(count)
            ]
    except (OSError, KeyError, ValueError) as error:
        raise ClipError(f"{path}: not a clip file of inest-record-clips ({error})") from error
    if saved_view != view:
        raise ClipError(f"{path}: clips of the {saved_view!r} view; the model uses {view!r}")
    for clip in clips:
        if clip.frames.ndim != 4 or clip.frames.shape[1:] != (image_size, image_size, 3):
            shape = f"{image_size}x{image_size}x3"
            raise ClipError(f"{path}: frames of shape {clip.frames.shape[1:]}; the model needs {shape}")
        if not len(clip.frames) == len(clip.progress) == len(clip.held):
            raise ClipError(f"{path}: a clip whose frames, progress and held flags differ in length")
    if not clips:
        raise ClipError(f"{path}: holds no clips")
    return clips
