"""`inest-record-clips RUN --episodes N --out FILE`: a trained policy's own rollouts, as labelled
clips (inest_reward_node.learning.clips) for calibrating the learned reward against.

Why: a learned reward is judged on the behaviour it will be shown, and the one behaviour no
demonstration, random or wrong-order episode contains is the agent's own: a policy trained on
the reward finds the frames its stage tracker mistakes for progress. Recording those frames
with the simulator's true progress and fitting the stage classifier on them too
(`inest-pretrain ... --resume --clips FILE`) closes the loophole it found (hard-negative
mining). The policy runs through the run's own observation path (the learned reward's stage
included), without the intrinsic bonus, on layouts no training, evaluation or calibration
episode uses, sampling its actions as in training unless `--deterministic`.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from inest_agent_node.envs import FRAME_KEY, TRUE_PROGRESS, build_env
from inest_agent_node.evaluate import check_not_locked
from inest_agent_node.learners import configure_jax_threads, learner_class
from inest_agent_node.rewards import build_reward
from inest_agent_node.train import has_checkpoint, new_learner, restore_learner
from inest_common.progress import track
from inest_common.settings import OneLineParser
from inest_reward_node.learning.clips import Clip, save_clips
from inest_reward_node.runtime.model import ModelError
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from inest_agent_node.config import TrainConfig

CLIP_SEED = 42_000_000  # layouts no demonstration, training, evaluation or calibration episode uses
ENVS = 10


class RolloutRecorder(VecEnvWrapper):
    """Keeps the info entries `keys` of every environment's steps, one tuple of arrays per
    finished episode (in the order they finish: a batch of fixed-length episodes by environment)."""

    def __init__(self, venv: VecEnv, keys: tuple[str, ...]) -> None:
        super().__init__(venv)
        self.keys = keys
        self.running: list[list[tuple]] = [[] for _ in range(venv.num_envs)]
        self.episodes: list[tuple[np.ndarray, ...]] = []

    def reset(self) -> np.ndarray:
        self.running = [[] for _ in range(self.num_envs)]
        return self.venv.reset()

    def step_wait(self):
        observations, rewards, dones, infos = self.venv.step_wait()
        for index, info in enumerate(infos):
            self.running[index].append(tuple(info[key] for key in self.keys))
            if dones[index]:
                self.episodes.append(tuple(np.array(column) for column in zip(*self.running[index], strict=True)))
                self.running[index] = []
        return observations, rewards, dones, infos


def record(run_dir: Path, episodes: int, seed: int, deterministic: bool, progress_bar: bool = True) -> list[Clip]:
    """`episodes` episodes of the run's final policy (its checkpoint), ENVS at a time."""
    config = TrainConfig.from_dict(json.loads((run_dir / "config.json").read_text()))
    if build_reward(config, ENVS, evaluation=True).camera is None:
        raise ValueError(
            f"{run_dir}: its evaluations score no camera frames (the {config.reward!r} reward, the "
            f"{config.observation!r} observation): record clips of a run whose reward reads a camera"
        )
    recorders: list[RolloutRecorder] = []

    def keep(venv: VecEnv) -> VecEnv:
        recorders.append(RolloutRecorder(venv, (FRAME_KEY, TRUE_PROGRESS, "held")))
        return recorders[-1]

    env = build_env(config, ENVS, seed, evaluation=True, wrap_simulators=keep)
    if config.learner.startswith("sbx"):
        configure_jax_threads(config.threads)
    model = new_learner(learner_class(config.learner), config, env)
    restore_learner(model, config.learner, run_dir)
    recorder = recorders[0]
    observations = env.reset()
    with track(total=episodes, desc="recording clips", unit="episode", disable=not progress_bar) as bar:
        while len(recorder.episodes) < episodes:
            before = len(recorder.episodes)
            observations = env.step(model.predict(observations, deterministic=deterministic)[0])[0]
            bar.update(min(len(recorder.episodes), episodes) - before)
    return [Clip(frames, progress, held) for frames, progress, held in recorder.episodes[:episodes]]


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", type=Path, help="a finished or checkpointed inest-train run folder")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--out", type=Path, required=True, help="clip file to write (.npz)")
    parser.add_argument("--seed", type=int, default=CLIP_SEED, help="layout of the first episode (default %(default)s)")
    parser.add_argument("--deterministic", action="store_true", help="the policy's mean action instead of samples")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1, got {args.episodes}")
    try:
        check_not_locked(args.seed, args.episodes, "--seed and --episodes")
    except ValueError as error:
        parser.error(str(error))
    if not has_checkpoint(args.run):
        print(f"inest-record-clips: {args.run} holds no checkpoint (not an inest-train run folder?)", file=sys.stderr)
        return 2
    try:
        args.out.parent.mkdir(parents=True, exist_ok=True)  # before the rollouts, not after
        clips = record(args.run, args.episodes, args.seed, args.deterministic)
        config = json.loads((args.run / "config.json").read_text())
        mode = "mean actions" if args.deterministic else "sampled actions"
        source = f"policy of {args.run} ({mode}), layouts {args.seed}..{args.seed + args.episodes - 1}"
        save_clips(args.out, clips, config["view"], source)
    except (ModelError, ValueError, OSError) as error:
        print(f"inest-record-clips: {error}", file=sys.stderr)
        return 2
    placed = np.bincount([int(clip.progress[-1]) for clip in clips], minlength=4) / len(clips)
    print(f"wrote {args.out}: {len(clips)} clips; final blocks placed 0/1/2/3: {np.round(placed, 2).tolist()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
