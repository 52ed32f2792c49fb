"""Train SAC on the learned (or the environment's) reward, in one process (`inest-train`).

Run folder: config.json (the full configuration), checkpoint/ (model.zip, replay_buffer.npz
(replay_store.py), history.json, diagnostics.json, exploration.npz with the novelty memories,
checkpoint.json with its step, size and the training seconds so far: the `--resume` point,
written every `checkpoint_every` steps or `checkpoint_minutes`, whichever comes first),
tensorboard/ (evaluation scores and the reward diagnostics), and at the end results.json (final
150-episode evaluation, learning curve points, reward diagnostics per evaluation interval,
coverage of the visited embeddings, wall-clock seconds of training and final evaluation, config),
learning_curve.png and coverage.png. Progress, evaluation, diagnostics and checkpoints during
`learn()` are stable-baselines3 callbacks (callbacks.py); the learner classes are in learners.py.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
import yaml
from inest_common.files import RunFileError, read_json, read_run_file, write_atomic
from inest_reward_node.learning.coverage import measure_coverage, plot_coverage
from inest_reward_node.learning.runs import CONFIG_FILE, merge_settings, prepare_run_dir
from inest_reward_node.runtime.config import SHAPINGS, STAGE_EVIDENCE, STAGE_FILTERS, STAGE_SOURCES
from inest_reward_node.runtime.intrinsic import INTRINSIC_MODES
from inest_reward_node.runtime.model import TCC_SCHEMES, ModelError, load_model
from inest_reward_node.runtime.trackers import TRACKERS
from inest_sim_node.config import ORACLE_REWARDS
from inest_sim_node.observation import STATE_OBSERVATIONS
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper, unwrap_vec_wrapper

from .callbacks import training_callbacks
from .config import REWARDS, SPEED_ONLY_SETTINGS, TrainConfig, setting_defaults
from .envs import ConcurrentUpdatesVecEnv, RewardVecEnv, build_env
from .evaluate import TEST, VALIDATION, EvalResult, Layouts, evaluate_vec_env, format_table, plot_learning_curve
from .labelled_rollouts import RolloutLabelling
from .learners import (
    LEARNERS,
    OverlappedUpdatesMixin,
    RewardBatchingMixin,
    build_learner_class,
    configure_jax_threads,
    learner_kwargs,
)
from .policy_export import EXPORTABLE, POLICY_DIR, export_policy, exported
from .replay_store import load_replay_buffer, save_replay_buffer
from .self_negatives import SelfNegatives
from .stage_refit import REFIT_MODEL_DIR, StageRefit

CHECKPOINT_DIR = "checkpoint"
RESULTS_FILE = "results.json"
EVALUATION_FILE = "evaluation.json"  # a saved policy evaluated over the graph (the agent node's evaluate mode)
EXPLORATION_FILE = "exploration.npz"  # novelty memories and visited embeddings
SELF_NEGATIVES_FILE = "self-negatives.npz"  # the stage refit's self negatives so far
HISTORY_FILE = "history.json"  # the learning curve: [steps, mean score, std] per evaluation
DIAGNOSTICS_FILE = "diagnostics.json"
REPLAY_FILE = "replay_buffer.npz"
# the checkpoint's step, its size in bytes, and the training seconds up to it, periodic evaluations
# included, summed over resumes (the time between a run's last checkpoint and its kill is lost with
# the steps it trained)
CHECKPOINT_INFO = "checkpoint.json"
EVAL_ENVS = 10  # evaluation episodes run side by side (one encoder pass for all their frames)


def deterministic(model: OffPolicyAlgorithm):
    def act(observations: np.ndarray) -> np.ndarray:
        return model.predict(observations, deterministic=True)[0]

    return act


def waiting_hook_owner(env: VecEnv) -> VecEnv:
    """The vector env (`env` or one it wraps) with a `while_waiting` hook: work it runs while it
    waits for a step (GraphVecEnv), which an overlapped learner's updates need."""
    owner = env
    while "while_waiting" not in vars(owner) and isinstance(owner, VecEnvWrapper):
        owner = owner.venv
    if "while_waiting" not in vars(owner):
        raise ValueError("overlapped updates need an env that runs them while it steps (GraphVecEnv.while_waiting)")
    return owner


class Trainer:
    """SAC on in-process environments built from the config, or on `env` (the ROS graph's, with
    the observation path of the config). `config.overlap_updates`: defer each update (learners.OverlappedUpdatesMixin)
    and hand `model.run_pending_updates` to the env, which runs it while it steps: in process on a
    second thread (envs.ConcurrentUpdatesVecEnv); `env`, or a vector env it wraps, must have a
    `while_waiting` hook (GraphVecEnv's)."""

    def __init__(
        self,
        config: TrainConfig,
        run_dir: str | Path,
        resume: bool = False,
        progress_bar: bool = True,
        env: VecEnv | None = None,
        start_over: bool = False,
    ):
        self.config = config
        self.run_dir = Path(run_dir)
        self.progress_bar = progress_bar
        self.history: list[list[float]] = []
        self.diagnostics: list[dict[str, float]] = []  # reward diagnostics per evaluation interval
        self.trained_seconds = 0.0  # up to the last checkpoint, over earlier sessions too
        self.session_start = time.monotonic()
        checkpoint = self.run_dir / CHECKPOINT_DIR
        check_resume(self.run_dir, resume, start_over)
        torch.set_num_threads(config.threads)
        self.env = env if env is not None else build_env(config)
        overlap_updates = config.overlap_updates
        if overlap_updates and env is None:
            self.env = ConcurrentUpdatesVecEnv(self.env)  # the updates run while the in-process envs step
        self.reward_env: RewardVecEnv | None = unwrap_vec_wrapper(self.env, RewardVecEnv)
        self.eval_env = build_env(config, min(EVAL_ENVS, config.final_eval_episodes), evaluation=True)
        # [steps, self negative frames, labelled episodes] of each stage classifier refit
        self.refits: list[list[int]] = []
        self.stage_refit = self.build_stage_refit()
        self.check_run_dir(resume or start_over, start_over)  # written only once the models and envs load
        if config.learner.startswith("sbx"):
            configure_jax_threads(config.threads)
        batching = not overlap_updates and self.reward_env is not None and self.reward_env.batch_steps > 1
        algorithm = build_learner_class(
            config.learner,
            overlap_updates,
            batching,
            drops_broken_steps=env is not None,  # the graph's simulators
        )
        if resume:
            self.model = read_run_file(
                checkpoint / "model.zip",
                lambda path: algorithm.load(path, env=self.env, tensorboard_log=str(self.run_dir / "tensorboard")),
            )
            read_run_file(checkpoint / REPLAY_FILE, lambda path: load_replay_buffer(self.model.replay_buffer, path))
            self.history = read_run_file(checkpoint / HISTORY_FILE, read_json)
            self.diagnostics = read_run_file(checkpoint / DIAGNOSTICS_FILE, read_json)
            info = read_run_file(checkpoint / CHECKPOINT_INFO, read_json)
            self.trained_seconds = float(info["training_s"])
            self.refits = info.get("stage_refits", [])  # absent from checkpoints written before it was kept
            if self.reward_env is not None and (checkpoint / EXPLORATION_FILE).exists():
                self.reward_env.restore_exploration(read_run_file(checkpoint / EXPLORATION_FILE, read_npz))
            if self.stage_refit is not None and (self.run_dir / REFIT_MODEL_DIR).exists():
                refitted = load_model(self.run_dir / REFIT_MODEL_DIR).goals(self.reward_env.reward.num_subtasks)
                for reader in self.stage_readers():
                    reader.use_goals(refitted)
                if self.stage_refit.labelling is not None:
                    self.stage_refit.labelling.restore(self.run_dir)  # a person's labels are kept
            if self.stage_refit is not None and (checkpoint / SELF_NEGATIVES_FILE).exists():
                # without them the next refit would forget what the earlier ones pushed down
                self.stage_refit.self_negatives.restore(read_run_file(checkpoint / SELF_NEGATIVES_FILE, read_npz))
        else:
            self.model = algorithm(
                "MlpPolicy",
                self.env,
                **learner_kwargs(config.learner, config.sac),
                tensorboard_log=str(self.run_dir / "tensorboard"),
                seed=config.seed,
                verbose=0,
            )
        if overlap_updates:
            waiting_hook_owner(self.env).while_waiting = self.model.run_pending_updates

    def build_stage_refit(self) -> StageRefit | None:
        """The stage classifier's refit during training, fed every scored step: with self negatives
        (`refit_every`), labelled rollouts (`label_at`), both, or None."""
        config = self.config
        if not config.refit_every and not config.label_at:
            return None
        scorer = self.reward_env.reward
        labelling = None
        if config.label_at:
            labelling = RolloutLabelling(scorer.num_subtasks, config.num_envs, config.label_at, config.label_episodes)
        self_negatives = SelfNegatives(scorer, config.num_envs) if config.refit_every else None
        refit = StageRefit(scorer, config.refit_demos, self_negatives, labelling, config.label_raise_thresholds)
        self.reward_env.scored_hook = refit.observe
        return refit

    def stage_readers(self) -> list:
        """The training and evaluation rewards, which read one refitted stage classifier."""
        return [self.reward_env.reward, unwrap_vec_wrapper(self.eval_env, RewardVecEnv).reward]

    def refit_stage_classifier(self) -> None:
        """The stage classifier refitted on the agent's own frames so far (stage_refit.py)."""
        frames = self.stage_refit.refit(self.run_dir, self.stage_readers())
        self.refits.append([int(self.model.num_timesteps), frames.self_negatives, frames.labelled_episodes])

    def evaluate(self, episodes: int, on: Layouts = VALIDATION) -> EvalResult:
        """The deterministic policy on the layouts `on` (the periodic evaluations': validation),
        through the training observation path; as exported, when it can be (policy_export.exported)."""
        if self.config.learner in EXPORTABLE:
            return evaluate_vec_env(self.eval_env, exported(self.model, self.config).predict, episodes, on)
        return evaluate_vec_env(self.eval_env, deterministic(self.model), episodes, on)

    def check_run_dir(self, overwrite: bool, start_over: bool) -> None:
        settings = self.config.to_dict()
        must_match = set() if start_over else set(settings) - SPEED_ONLY_SETTINGS - {"total_steps"}
        prepare_run_dir(self.run_dir, settings, overwrite, must_match, setting_defaults())

    def save_checkpoint(self) -> int:
        """Model, replay buffer, history and novelty memories, each written whole before it replaces
        the last one, and checkpoint.json (written last: a checkpoint without it is incomplete).
        Returns the checkpoint's size in bytes."""
        checkpoint = self.run_dir / CHECKPOINT_DIR
        checkpoint.mkdir(exist_ok=True)
        if isinstance(self.model, RewardBatchingMixin):
            self.model.settle_rewards()
        write_atomic(checkpoint / REPLAY_FILE, lambda path: save_replay_buffer(self.model.replay_buffer, path))
        write_atomic(checkpoint / "model.zip", lambda path: self.model.save(path))
        write_atomic(checkpoint / HISTORY_FILE, lambda path: path.write_text(json.dumps(self.history)))
        write_atomic(checkpoint / DIAGNOSTICS_FILE, lambda path: path.write_text(json.dumps(self.diagnostics)))
        if self.config.learner in EXPORTABLE:
            export_policy(self.model, self.config, self.run_dir / POLICY_DIR)  # inest-evaluate's, at every checkpoint
        if self.reward_env is not None:
            write_npz(checkpoint / EXPLORATION_FILE, self.reward_env.exploration_state())
        if self.stage_refit is not None and self.stage_refit.self_negatives is not None:
            write_npz(checkpoint / SELF_NEGATIVES_FILE, self.stage_refit.self_negatives.state())
        now = time.monotonic()
        self.trained_seconds += now - self.session_start
        self.session_start = now
        size = sum(path.stat().st_size for path in checkpoint.iterdir() if path.name != CHECKPOINT_INFO)
        info = {
            "steps": int(self.model.num_timesteps),
            "bytes": size,
            "training_s": self.trained_seconds,
            "stage_refits": self.refits,
        }
        write_atomic(checkpoint / CHECKPOINT_INFO, lambda path: path.write_text(json.dumps(info) + "\n"))
        return size

    def train(self) -> EvalResult:
        remaining = self.config.total_steps - self.model.num_timesteps
        self.session_start = time.monotonic()  # not the set-up (models, compilation) before it
        if remaining > 0:
            self.model.learn(remaining, callback=training_callbacks(self), reset_num_timesteps=False, tb_log_name="sac")
            if isinstance(self.model, OverlappedUpdatesMixin):
                self.model.run_pending_updates()  # the last update had no next step to overlap with
            self.save_checkpoint()
        return self.finish()

    def finish(self) -> EvalResult:
        config = self.config
        evaluation_start = time.monotonic()
        result = self.evaluate(config.final_eval_episodes, on=TEST)
        validation = self.evaluate(config.final_eval_episodes, on=VALIDATION)
        results: dict[str, Any] = {
            "final_evaluation": result.to_dict(),  # on the test layouts, which no choice of setting saw
            "final_validation": validation.to_dict(),  # where settings are chosen
            "layouts": {
                "final_evaluation": TEST.to_dict(),
                "final_validation": VALIDATION.to_dict(),
                "learning_curve": VALIDATION.to_dict(),
            },
            "steps": int(self.model.num_timesteps),
            "wall_clock_s": {
                "training": round(self.trained_seconds, 2),
                "final_evaluation": round(time.monotonic() - evaluation_start, 2),
            },
            "learning_curve": self.history,
            "reward_diagnostics": self.diagnostics,
            "reward_shares": reward_shares(self.diagnostics),
            "stage_refits": self.refits,
            "config": config.to_dict(),
        }
        if self.reward_env is not None and self.reward_env.visited:
            coverage = measure_coverage(np.concatenate(self.reward_env.visited))
            plot_coverage(coverage, self.run_dir / "coverage.png", f"{config.reward} reward: visited embeddings")
            results["coverage"] = {
                "samples": coverage.samples,
                "grid_cells_occupied": coverage.occupied_cells,
                "grid_fraction_occupied": coverage.occupied_fraction,
                "unique_states": coverage.unique_states,
                "recorded_every_vector_steps": self.reward_env.record_every,
            }
        # whole or not at all: a grid (experiments.py) counts a run with results.json as finished
        write_atomic(self.run_dir / RESULTS_FILE, lambda path: path.write_text(json.dumps(results, indent=2) + "\n"))
        reference = None
        if config.reward != "env":
            reference = reference_curve(self.run_dir.parent)
        plot_learning_curve({f"{config.reward} reward": self.history}, self.run_dir / "learning_curve.png", reference)
        return result


def reward_shares(diagnostics: list[dict[str, float]]) -> dict[str, dict[str, float]]:
    """Each reward part's share of the reward (diagnostics.py), over the whole run (the mean of
    its evaluation intervals) and over its last interval."""
    names = sorted({key for entry in diagnostics for key in entry if key.endswith("_share")})
    if not names:
        return {}
    return {
        "run": {name: float(np.mean([entry.get(name, 0.0) for entry in diagnostics])) for name in names},
        "last_interval": {name: float(diagnostics[-1].get(name, 0.0)) for name in names},
    }


def has_checkpoint(run_dir: Path) -> bool:
    """Whether the run in `run_dir` has a whole checkpoint to resume (its info file is written last)."""
    return (run_dir / CHECKPOINT_DIR / CHECKPOINT_INFO).is_file()


def checkpoint_steps(run_dir: Path) -> int:
    """The step of the run's checkpoint (has_checkpoint must hold)."""
    return int(read_run_file(run_dir / CHECKPOINT_DIR / CHECKPOINT_INFO, read_json)["steps"])


def continuation(run_dir: Path) -> str | None:
    """How to carry on the run in `run_dir`, whatever its state: "resume" from its checkpoint,
    "start_over" for one stopped before its first, None for a new one."""
    if has_checkpoint(run_dir):
        return "resume"
    return "start_over" if (run_dir / CONFIG_FILE).exists() else None


def continuation_flags(run_dir: Path) -> list[str]:
    """inest-train's flags for `continuation(run_dir)`: --resume, --start-over or none."""
    how = continuation(run_dir)
    return [] if how is None else [f"--{how.replace('_', '-')}"]


def check_resume(run_dir: Path, resume: bool, start_over: bool) -> None:
    """Refuse, before anything loads or is written, a resume with nothing to continue (never
    silently from step 0), and a start-over that would throw a checkpoint away."""
    if resume and start_over:
        raise ValueError("resume and start over exclude each other")
    if resume and not (run_dir / CONFIG_FILE).is_file():
        raise RunFileError(f"nothing to resume in {run_dir}: it holds no earlier run ({CONFIG_FILE})")
    if resume and not has_checkpoint(run_dir) and (run_dir / CHECKPOINT_DIR / "replay_buffer.pkl").exists():
        raise RunFileError(
            f"cannot resume {run_dir}: its checkpoint is in an older format (a pickled replay buffer), "
            "which is no longer loaded: it could run code"
        )
    if resume and not has_checkpoint(run_dir):
        raise RunFileError(
            f"nothing to resume in {run_dir}: the run stopped before its first checkpoint; "
            "start it over from step 0 (inest-train --start-over; the agent node's start_over:=true, "
            "inest-launch --param agent:start_over:=true) or pick a new folder"
        )
    if start_over and has_checkpoint(run_dir):
        raise FileExistsError(
            f"{run_dir} has a checkpoint at step {checkpoint_steps(run_dir)}: resume it, or pick a new folder "
            "to start over"
        )


def write_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    def write(partial: Path) -> None:
        with open(partial, "wb") as handle:
            np.savez(handle, **arrays)

    write_atomic(path, write)


def read_npz(path: Path) -> dict[str, np.ndarray]:
    with np.load(path) as arrays:
        return {key: arrays[key] for key in arrays.files}


def reference_curve(runs_root: Path) -> list[list[float]] | None:
    """The learning curve of an env-reward run next to this one, if there is one."""
    for results in sorted(runs_root.glob(f"*/{RESULTS_FILE}")):
        data = read_run_file(results, read_json)
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
    "refit_every",
    "label_episodes",
)


def parse_args(argv: list[str] | None) -> tuple[TrainConfig, argparse.Namespace]:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", help="run folder (required unless --print-config)")
    parser.add_argument("--config", help="YAML file of training settings (see inest_agent_node/config/train.yaml)")
    parser.add_argument(
        "--print-config",
        action="store_true",
        help="print every setting these arguments give, defaults included, as YAML and exit",
    )
    resuming = parser.add_mutually_exclusive_group()
    resuming.add_argument("--resume", action="store_true", help="continue the run in --out from its last checkpoint")
    resuming.add_argument(
        "--start-over",
        action="store_true",
        help="train the run in --out again from step 0: one that stopped before its first checkpoint",
    )
    parser.add_argument("--reward", choices=REWARDS)
    parser.add_argument("--model", help="reward model folder (a pretraining run's model/)")
    parser.add_argument(
        "--refit-demos",
        help="with --refit-every or --label-at: the dataset whose demonstrations anchor the refitted classifier",
    )
    parser.add_argument("--subtasks", type=int, choices=TCC_SCHEMES)
    parser.add_argument("--intrinsic", choices=INTRINSIC_MODES)
    parser.add_argument(
        "--intrinsic-weight",
        type=float,
        help="the novelty bonus's weight; twice it for the steps after a subtask switch (thesis: 0.2, 0.4)",
    )
    parser.add_argument("--view", choices=("ego", "allo"))
    parser.add_argument(
        "--observation",
        choices=STATE_OBSERVATIONS,
        help="robot (default): what a robot senses and the reward's stage; stage: the same on the whole "
        "simulator state, score included; state: the bare state vector",
    )
    parser.add_argument("--learner", choices=tuple(LEARNERS), help="off-policy learner (learners.py)")
    parser.add_argument("--shaping", choices=SHAPINGS, help="learned reward shaping (runtime.config.RewardConfig)")
    parser.add_argument("--tracker", choices=TRACKERS, help="learned reward subtask tracker")
    parser.add_argument(
        "--stage-source", choices=STAGE_SOURCES, help="privileged: stage and bonus from the true progress (diagnostic)"
    )
    parser.add_argument(
        "--stage-evidence",
        choices=STAGE_EVIDENCE,
        help="what the confirmed tracker reads: auto (the pixel stage head if the model has one), pixels, "
        "embedding, window (a classifier over the frame and frames before it)",
    )
    parser.add_argument(
        "--confirm-steps", type=int, help="frames the confirmed tracker's stage evidence must agree (0: hold_steps)"
    )
    parser.add_argument("--stage-confidence", type=float, help="P(stage >= j) at which the stage evidence agrees")
    parser.add_argument(
        "--stage-filter", choices=STAGE_FILTERS, help="forward: the tracker reads a causal filter over the stages"
    )
    parser.add_argument("--filter-advance", type=float, help="the stage filter's chance per frame of one stage up")
    parser.add_argument("--filter-temperature", type=float, help="the power the filter raises each frame's evidence to")
    parser.add_argument(
        "--instant-confidence", type=float, help="P(stage >= j) at which one frame confirms a completion (1: off)"
    )
    parser.add_argument("--oracle", choices=ORACLE_REWARDS, help="the simulator's reward, used by --reward env")
    parser.add_argument(
        "--overlap-updates",
        action=argparse.BooleanOptionalAction,
        help="run each update on a second thread while the environments step (faster on 2 cores)",
    )
    for name in INTEGER_FLAGS:
        parser.add_argument(f"--{name.replace('_', '-')}", type=int)
    parser.add_argument(
        "--label-raise-thresholds",
        action=argparse.BooleanOptionalAction,
        help="the episodes labelled in the loop also raise the completion thresholds (default: yes)",
    )
    parser.add_argument(
        "--label-at",
        type=int,
        nargs="+",
        metavar="STEP",
        help="steps at which --label-episodes of the agent's episodes are labelled and refitted on "
        "(needs --refit-demos)",
    )
    parser.add_argument(
        "--gradient-steps", type=int, help="gradient steps per vector step (sac.gradient_steps; the replay ratio)"
    )
    args = parser.parse_args(argv)
    if args.out is None and not args.print_config:
        parser.error("the following arguments are required: --out")
    overrides: dict[str, Any] = {
        name: getattr(args, name)
        for name in (
            *("reward", "model", "subtasks", "view", "observation", "oracle", "learner", "overlap_updates"),
            *("refit_demos", "label_raise_thresholds"),
            *INTEGER_FLAGS,
        )
        if getattr(args, name) is not None
    }
    learned = {
        name: getattr(args, name)
        for name in (
            *("shaping", "tracker", "stage_source", "stage_evidence", "stage_filter"),
            *("confirm_steps", "stage_confidence", "instant_confidence", "filter_advance", "filter_temperature"),
        )
        if getattr(args, name) is not None
    }
    if args.label_at is not None:
        overrides["label_at"] = tuple(args.label_at)
    if learned:
        overrides["learned_reward"] = learned
    if args.gradient_steps is not None:
        overrides["sac"] = {"gradient_steps": args.gradient_steps}
    if args.intrinsic is not None:
        overrides["intrinsic"] = {"mode": args.intrinsic}
    elif overrides.get("reward", "inest") != "inest":
        overrides["intrinsic"] = {"mode": "none"}  # --reward env|xirl|holdr on an inest config file
    if args.intrinsic_weight is not None:
        overrides["intrinsic"] = {
            **overrides.get("intrinsic", {}),
            "weight": args.intrinsic_weight,
            "boosted_weight": 2 * args.intrinsic_weight,
        }
    if args.config:
        return TrainConfig.from_yaml(args.config, overrides), args
    return TrainConfig.from_dict(merge_settings({}, overrides)), args


def main(argv: list[str] | None = None) -> int:
    try:
        config, args = parse_args(argv)
        if args.print_config:
            print(yaml.safe_dump(config.to_dict(), sort_keys=False), end="")
            return 0
        trainer = Trainer(config, args.out, resume=args.resume, start_over=args.start_over)
        result = trainer.train()
    except (ModelError, FileExistsError, ValueError) as error:
        print(f"inest-train: {error}", file=sys.stderr)
        return 2
    print(format_table({f"{config.reward} ({trainer.model.num_timesteps} steps)": result}))
    print(f"wrote {Path(args.out) / RESULTS_FILE} and learning_curve.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
