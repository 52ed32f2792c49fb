"""Train SAC on the learned (or the environment's) reward, in one process (`inest-train`).

Run folder: config.json (the full configuration), checkpoint/ (model.zip, replay_buffer.pkl,
history.json, exploration.npz with the novelty memories: the `--resume` point, written every
`checkpoint_every` steps), tensorboard/,
and at the end results.json (final 150-episode evaluation, learning curve points, coverage of
the visited embeddings, config), learning_curve.png and coverage.png.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np
import torch
from inest_reward_node.coverage import measure_coverage, plot_coverage
from inest_reward_node.intrinsic import INTRINSIC_MODES
from inest_reward_node.model import ModelError, load_model
from inest_reward_node.rewards import RewardScorer
from inest_reward_node.runs import merge_settings, prepare_run_dir
from inest_sim_node.dataset import write_atomic
from stable_baselines3 import SAC
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv
from tqdm import tqdm

from inest_sim_node import EnvConfig

from .config import REWARDS, TrainConfig
from .envs import LearnedRewardVecEnv, make_vec_env
from .evaluate import EvalResult, evaluate, format_table, plot_learning_curve

CHECKPOINT_DIR = "checkpoint"
RESULTS_FILE = "results.json"
EXPLORATION_FILE = "exploration.npz"  # novelty memories and visited embeddings


def build_env(config: TrainConfig) -> VecEnv:
    env_config = EnvConfig(view=config.view)
    if config.reward == "topic":
        raise ValueError("the topic reward comes from inest_reward_node: train over the graph (inest-agent-node)")
    if config.reward == "env":
        return make_vec_env(config.num_envs, env_config, config.seed)
    scheme = config.subtasks if config.reward == "inest" else 1
    model = load_model(config.model, view=config.view, scheme=scheme)
    frames = (config.view, model.image_size)
    scorer = RewardScorer(model, scheme, config.reward, config.intrinsic, config.num_envs)
    venv = make_vec_env(config.num_envs, env_config, config.seed, frames)
    return LearnedRewardVecEnv(venv, scorer, batch_steps=config.reward_batch_steps)


class OverlappedSAC(SAC):
    """SAC whose gradient steps run while the environments take their next step.

    stable-baselines3 stores transition t, updates, then picks the action for t + 1. Here the
    action for t + 1 is picked first (by a policy one update older), sent, and the update runs
    while the simulators and the reward node work in their own processes; it still samples
    from exactly the transitions up to t. The vector env calls `run_pending_updates` once
    its actions are out (GraphVecEnv.while_waiting).
    """

    def train(self, gradient_steps: int, batch_size: int = 64) -> None:
        self.__dict__.setdefault("pending_updates", []).append((gradient_steps, batch_size))

    def run_pending_updates(self) -> None:
        pending = self.__dict__.setdefault("pending_updates", [])
        while pending:
            SAC.train(self, *pending.pop(0))


class RewardBatchingSAC(SAC):
    """SAC on a LearnedRewardVecEnv that scores several vector steps' frames at once.

    A transition waits until its learned reward is known (at most batch_steps - 1 vector steps),
    then goes into the replay buffer exactly as SAC would have stored it; the updates meanwhile
    sample from the transitions already stored. stable-baselines3 hands `_store_transition` fresh
    arrays every step, so holding them is safe.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.held_transitions: deque[tuple[Any, ...]] = deque()

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), "held_transitions"]

    def _store_transition(self, replay_buffer, buffer_action, new_obs, reward, dones, infos) -> None:
        super()._store_transition(TransitionHolder(self.held_transitions), buffer_action, new_obs, reward, dones, infos)
        self.store_scored_transitions()

    def store_scored_transitions(self) -> None:
        # at a checkpoint the current step is scored before SAC hands over its transition
        for reward in self.env.take_rewards(len(self.held_transitions)):
            observation, next_observation, action, _, dones, infos = self.held_transitions.popleft()
            self.replay_buffer.add(observation, next_observation, action, reward, dones, infos)

    def settle_rewards(self) -> None:
        """Score the frames still waiting for a full batch and store their transitions (checkpoints)."""
        self.env.score_waiting()
        self.store_scored_transitions()


class TransitionHolder:
    """Stands in for the replay buffer in SAC's `_store_transition`: keeps the transition it is given."""

    def __init__(self, held: deque[tuple[Any, ...]]) -> None:
        self.held = held

    def add(self, *transition: Any) -> None:
        self.held.append(transition)


def policy_of(model: SAC):
    def act(observation: np.ndarray, _env) -> np.ndarray:
        return model.predict(observation, deterministic=True)[0]

    return act


class TrainingCallback(BaseCallback):
    """Progress bar, periodic evaluation (TensorBoard `eval/score`) and checkpoints."""

    def __init__(self, trainer: Trainer) -> None:
        super().__init__()
        self.trainer = trainer
        self.bar: tqdm | None = None
        self.started = time.perf_counter()
        self.start_steps = 0

    def _on_training_start(self) -> None:
        config = self.trainer.config
        self.start_steps = self.num_timesteps
        self.started = time.perf_counter()
        self.bar = tqdm(
            total=config.total_steps,
            initial=self.num_timesteps,
            unit="step",
            desc=f"SAC {config.reward}",
            disable=not self.trainer.progress_bar,
        )

    def _on_step(self) -> bool:
        config = self.trainer.config
        steps = self.num_timesteps
        self.bar.update(steps - self.bar.n)
        if steps % config.eval_every < config.num_envs:
            result = evaluate(policy_of(self.model), config.eval_episodes, EnvConfig(view=config.view), config.seed)
            self.trainer.history.append([steps, result.mean_score, result.score_std])
            self.logger.record("eval/score", result.mean_score)
            self.logger.record("eval/success_rate", result.success_rate)
            speed = (steps - self.start_steps) / max(time.perf_counter() - self.started, 1e-9)
            self.bar.set_postfix({"score": f"{result.mean_score:.2f}", "steps/s": f"{speed:.0f}"})
        if steps % config.checkpoint_every < config.num_envs:
            self.trainer.save_checkpoint()
        return True

    def _on_training_end(self) -> None:
        self.bar.close()


class Trainer:
    """SAC on in-process environments built from the config, or on `env` (the ROS graph's).
    `overlap_updates`: run each update while `env` steps (OverlappedSAC; env.while_waiting)."""

    def __init__(
        self,
        config: TrainConfig,
        run_dir: str | Path,
        resume: bool = False,
        progress_bar: bool = True,
        env: VecEnv | None = None,
        overlap_updates: bool = False,
    ):
        self.config = config
        self.run_dir = Path(run_dir)
        self.progress_bar = progress_bar
        self.history: list[list[float]] = []
        self.check_run_dir(resume)
        torch.set_num_threads(config.threads)
        self.env = env if env is not None else build_env(config)
        checkpoint = self.run_dir / CHECKPOINT_DIR
        algorithm = SAC
        if overlap_updates:
            algorithm = OverlappedSAC
        elif isinstance(self.env, LearnedRewardVecEnv) and self.env.batch_steps > 1:
            algorithm = RewardBatchingSAC
        if resume and (checkpoint / "model.zip").exists():
            self.model = algorithm.load(
                checkpoint / "model.zip", env=self.env, tensorboard_log=str(self.run_dir / "tensorboard")
            )
            self.model.load_replay_buffer(checkpoint / "replay_buffer.pkl")
            self.history = json.loads((checkpoint / "history.json").read_text())
            if isinstance(self.env, LearnedRewardVecEnv) and (checkpoint / EXPLORATION_FILE).exists():
                with np.load(checkpoint / EXPLORATION_FILE) as state:
                    self.env.restore_exploration({key: state[key] for key in state.files})
        else:
            settings = dataclasses.asdict(config.sac)
            net_arch = list(settings.pop("net_arch"))
            self.model = algorithm(
                "MlpPolicy",
                self.env,
                **settings,
                policy_kwargs={"net_arch": net_arch},
                tensorboard_log=str(self.run_dir / "tensorboard"),
                seed=config.seed,
                verbose=0,
            )
        if overlap_updates:
            self.env.while_waiting = self.model.run_pending_updates

    def check_run_dir(self, resume: bool) -> None:
        settings = self.config.to_dict()
        prepare_run_dir(self.run_dir, settings, resume, set(settings) - {"total_steps", "reward_batch_steps"})

    def save_checkpoint(self) -> None:
        """Model, replay buffer and history, each written whole before it replaces the last one."""
        checkpoint = self.run_dir / CHECKPOINT_DIR
        checkpoint.mkdir(exist_ok=True)
        if isinstance(self.model, RewardBatchingSAC):
            self.model.settle_rewards()
        write_atomic(checkpoint / "replay_buffer.pkl", lambda path: self.model.save_replay_buffer(path))
        write_atomic(checkpoint / "model.zip", lambda path: self.model.save(path))
        write_atomic(checkpoint / "history.json", lambda path: path.write_text(json.dumps(self.history)))
        if isinstance(self.env, LearnedRewardVecEnv):
            state = self.env.exploration_state()

            def save_exploration(path: Path) -> None:
                with open(path, "wb") as handle:
                    np.savez(handle, **state)

            write_atomic(checkpoint / EXPLORATION_FILE, save_exploration)

    def train(self) -> EvalResult:
        remaining = self.config.total_steps - self.model.num_timesteps
        if remaining > 0:
            self.model.learn(remaining, callback=TrainingCallback(self), reset_num_timesteps=False, tb_log_name="sac")
            if isinstance(self.model, OverlappedSAC):
                self.model.run_pending_updates()  # the last update had no next step to overlap with
            self.save_checkpoint()
        return self.finish()

    def finish(self) -> EvalResult:
        config = self.config
        result = evaluate(policy_of(self.model), config.final_eval_episodes, EnvConfig(view=config.view), config.seed)
        results: dict[str, Any] = {
            "final_evaluation": result.to_dict(),
            "steps": int(self.model.num_timesteps),
            "learning_curve": self.history,
            "config": config.to_dict(),
        }
        if isinstance(self.env, LearnedRewardVecEnv) and self.env.visited:
            coverage = measure_coverage(np.concatenate(self.env.visited))
            plot_coverage(coverage, self.run_dir / "coverage.png", f"{config.reward} reward: visited embeddings")
            results["coverage"] = {
                "samples": coverage.samples,
                "grid_cells_occupied": coverage.occupied_cells,
                "grid_fraction_occupied": coverage.occupied_fraction,
                "unique_states": coverage.unique_states,
                "recorded_every_vector_steps": self.env.record_every,
            }
        (self.run_dir / RESULTS_FILE).write_text(json.dumps(results, indent=2) + "\n")
        reference = None
        if config.reward != "env":
            reference = reference_curve(self.run_dir.parent)
        plot_learning_curve({f"{config.reward} reward": self.history}, self.run_dir / "learning_curve.png", reference)
        return result


def reference_curve(runs_root: Path) -> list[list[float]] | None:
    """The learning curve of an env-reward run next to this one, if there is one."""
    for results in sorted(runs_root.glob(f"*/{RESULTS_FILE}")):
        data = json.loads(results.read_text())
        if data["config"]["reward"] == "env":
            return data["learning_curve"]
    return None


INTEGER_FLAGS = (
    "total_steps",
    "num_envs",
    "reward_batch_steps",
    "eval_every",
    "eval_episodes",
    "final_eval_episodes",
    "checkpoint_every",
    "seed",
    "threads",
)


def parse_args(argv: list[str] | None) -> tuple[TrainConfig, argparse.Namespace]:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True, help="run folder")
    parser.add_argument("--config", help="YAML file of training settings (see configs/train.yaml)")
    parser.add_argument("--resume", action="store_true", help="continue the run in --out from its last checkpoint")
    parser.add_argument("--reward", choices=REWARDS)
    parser.add_argument("--model", help="reward model folder (a pretraining run's model/)")
    parser.add_argument("--subtasks", type=int, choices=(1, 3, 6))
    parser.add_argument("--intrinsic", choices=INTRINSIC_MODES)
    parser.add_argument("--view", choices=("ego", "allo"))
    for name in INTEGER_FLAGS:
        parser.add_argument(f"--{name.replace('_', '-')}", type=int)
    args = parser.parse_args(argv)
    overrides: dict[str, Any] = {
        name: getattr(args, name)
        for name in ("reward", "model", "subtasks", "view", *INTEGER_FLAGS)
        if getattr(args, name) is not None
    }
    if args.intrinsic is not None:
        overrides["intrinsic"] = {"mode": args.intrinsic}
    elif overrides.get("reward", "inest") != "inest":
        overrides["intrinsic"] = {"mode": "none"}  # --reward env|xirl|holdr on an inest config file
    if args.config:
        return TrainConfig.from_yaml(args.config, overrides), args
    return TrainConfig.from_dict(merge_settings({}, overrides)), args


def main(argv: list[str] | None = None) -> int:
    try:
        config, args = parse_args(argv)
        trainer = Trainer(config, args.out, resume=args.resume)
        result = trainer.train()
    except (ModelError, FileExistsError, ValueError) as error:
        print(f"inest-train: {error}", file=sys.stderr)
        return 2
    print(format_table({f"{config.reward} ({trainer.model.num_timesteps} steps)": result}))
    print(f"wrote {Path(args.out) / RESULTS_FILE} and learning_curve.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
