"""Train SAC on the learned (or the environment's) reward, in one process (`inest-train`).

Run folder: config.json (the full configuration), checkpoint/ (the learner's state as arrays and
JSON (learner_state.py), replay_buffer.npz (replay_store.py), history.json, diagnostics.json,
exploration.npz with the novelty memories, and checkpoint.json, its manifest, with its step and
the training seconds so far: the `--resume` point, written as one unit (checkpoint.py) every
`checkpoint_every` steps or `checkpoint_minutes`, whichever comes first; nothing in it is
pickled),
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
from inest_common.files import (
    NO_SPACE_EXIT,
    RunFileError,
    no_space_message,
    out_of_space,
    read_json,
    read_run_file,
    write_atomic,
)
from inest_common.settings import OneLineParser, add_setting_flags
from inest_reward_node.learning.coverage import measure_coverage, plot_coverage
from inest_reward_node.learning.labelled_rollouts import RolloutLabelling
from inest_reward_node.learning.runs import CONFIG_FILE, check_run_dir, merge_settings, prepare_run_dir
from inest_reward_node.learning.self_negatives import SelfNegatives
from inest_reward_node.learning.stage_refit import REFIT_MODEL_DIR, StageRefit
from inest_reward_node.runtime.model import ModelError, load_model
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper, unwrap_vec_wrapper

from .callbacks import training_callbacks
from .checkpoint import CHECKPOINT_DIR, CHECKPOINT_INFO, checkpoint_folder, read_manifest, write_checkpoint
from .config import TrainConfig, setting_defaults
from .envs import ConcurrentUpdatesVecEnv, RewardVecEnv, build_env
from .evaluate import TEST, VALIDATION, EvalResult, Layouts, evaluate_vec_env, format_table, plot_learning_curve
from .learner_state import load_learner_state, refuse_model_zip, save_learner_state
from .learners import (
    OverlappedUpdatesMixin,
    RewardBatchingMixin,
    build_learner_class,
    configure_jax_threads,
    learner_kwargs,
)
from .policy_export import EXPORTABLE, POLICY_DIR, export_policy, exported
from .replay_store import load_replay_buffer, save_replay_buffer

RESULTS_FILE = "results.json"
EVALUATION_FILE = "evaluation.json"  # a saved policy evaluated over the graph (the agent node's evaluate mode)
EXPLORATION_FILE = "exploration.npz"  # novelty memories and visited embeddings
SELF_NEGATIVES_FILE = "self-negatives.npz"  # the stage refit's self negatives so far
HISTORY_FILE = "history.json"  # the learning curve: [steps, mean score, std] per evaluation
DIAGNOSTICS_FILE = "diagnostics.json"
REPLAY_FILE = "replay_buffer.npz"
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
        self.prepare_run_dir(resume or start_over, start_over, write=False)  # refusals before the learner is built
        if config.learner.startswith("sbx"):
            configure_jax_threads(config.threads)
        batching = not overlap_updates and self.reward_env is not None and self.reward_env.batch_steps > 1
        algorithm = build_learner_class(
            config.learner,
            overlap_updates,
            batching,
            drops_broken_steps=env is not None,  # the graph's simulators
        )
        self.model = new_learner(algorithm, config, self.env, tensorboard_log=str(self.run_dir / "tensorboard"))
        if resume:
            checkpoint = restore_learner(self.model, config.learner, self.run_dir)
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
        self.prepare_run_dir(resume or start_over, start_over)  # config.json once the checkpoint has loaded
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

    def prepare_run_dir(self, overwrite: bool, start_over: bool, write: bool = True) -> None:
        """Refuse a run folder this run may not use; `write`: then write its config.json."""
        must_match = self.config.settings_that_matter(start_over)
        prepare = prepare_run_dir if write else check_run_dir
        prepare(self.run_dir, self.config.to_dict(), overwrite, must_match, setting_defaults())

    def save_checkpoint(self) -> int:
        """Learner state, replay buffer, history, diagnostics and novelty memories as one
        checkpoint (checkpoint.py), then the exported policy. Returns the checkpoint's size in
        bytes; NoSpaceError when the disk is full (the last checkpoint is kept)."""
        if isinstance(self.model, RewardBatchingMixin):
            self.model.settle_rewards()
        now = time.monotonic()
        info = {
            "steps": int(self.model.num_timesteps),
            "training_s": self.trained_seconds + now - self.session_start,
            "stage_refits": self.refits,
        }
        size = write_checkpoint(self.run_dir, self.write_checkpoint_files, info)
        self.trained_seconds, self.session_start = info["training_s"], now
        if self.config.learner in EXPORTABLE:
            export_policy(self.model, self.config, self.run_dir / POLICY_DIR)  # inest-evaluate's, at every checkpoint
        return size

    def write_checkpoint_files(self, folder: Path) -> None:
        save_learner_state(self.model, self.config.learner, folder)
        save_replay_buffer(self.model.replay_buffer, folder / REPLAY_FILE)
        (folder / HISTORY_FILE).write_text(json.dumps(self.history))
        (folder / DIAGNOSTICS_FILE).write_text(json.dumps(self.diagnostics))
        if self.reward_env is not None:
            write_npz(folder / EXPLORATION_FILE, self.reward_env.exploration_state())
        if self.stage_refit is not None and self.stage_refit.self_negatives is not None:
            write_npz(folder / SELF_NEGATIVES_FILE, self.stage_refit.self_negatives.state())

    def train(self) -> EvalResult:
        remaining = self.config.total_steps - self.model.num_timesteps
        self.session_start = time.monotonic()  # not the set-up (models, compilation) before it
        if remaining > 0:
            callbacks = training_callbacks(self)
            try:
                self.model.learn(remaining, callback=callbacks, reset_num_timesteps=False, tb_log_name="sac")
            except BaseException:
                callbacks.on_training_end()  # the progress bar closes before the line saying why
                raise
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


def new_learner(algorithm: type, config: TrainConfig, env: VecEnv, tensorboard_log: str | None = None) -> Any:
    """A fresh learner of class `algorithm` with the run's settings: the one training starts
    from, and the one a checkpoint's state is loaded into (learner_state.py)."""
    return algorithm(
        "MlpPolicy",
        env,
        **learner_kwargs(config.learner, config.sac),
        tensorboard_log=tensorboard_log,
        seed=config.seed,
        verbose=0,
    )


def restore_learner(model: Any, learner: str, run_dir: Path) -> Path:
    """Load the state of the run's checkpoint into `model` (new_learner's, of the run's settings);
    returns the checkpoint folder. RunFileError when there is none or it is not whole."""
    checkpoint = check_checkpoint(run_dir)
    load_learner_state(model, learner, checkpoint)
    return checkpoint


def check_checkpoint(run_dir: Path) -> Path:
    """The run's checkpoint folder, once it is whole (its manifest's sizes and hashes) and holds no
    stable-baselines3 model.zip; RunFileError otherwise. Cheap enough for a launcher's check."""
    checkpoint = checkpoint_folder(run_dir)
    if checkpoint is None:
        raise RunFileError(f"{run_dir} holds no checkpoint ({CHECKPOINT_DIR}/{CHECKPOINT_INFO})")
    refuse_model_zip(checkpoint / "model.zip")
    read_manifest(checkpoint)
    return checkpoint


def has_checkpoint(run_dir: Path) -> bool:
    """Whether the run in `run_dir` has a checkpoint to resume (checkpoint.py)."""
    return checkpoint_folder(run_dir) is not None


def checkpoint_steps(run_dir: Path) -> int:
    """The step of the run's checkpoint (has_checkpoint must hold)."""
    return int(read_run_file(checkpoint_folder(run_dir) / CHECKPOINT_INFO, read_json)["steps"])


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
    """Refuse, before anything loads or is written, a resume with nothing (whole) to continue (never
    silently from step 0), and a start-over that would throw a checkpoint, or its files, away."""
    if resume and start_over:
        raise ValueError("resume and start over exclude each other")
    if resume and not (run_dir / CONFIG_FILE).is_file():
        raise RunFileError(f"nothing to resume in {run_dir}: it holds no earlier run ({CONFIG_FILE})")
    unfinished = run_dir / CHECKPOINT_DIR
    if not has_checkpoint(run_dir) and unfinished.is_dir() and any(unfinished.iterdir()):
        raise RunFileError(
            f"{unfinished} holds checkpoint files but no manifest ({CHECKPOINT_INFO}, written last): they are "
            f"not a whole checkpoint, and nothing is started over on them; move {unfinished} away to start over"
        )
    if resume and has_checkpoint(run_dir):
        check_checkpoint(run_dir)  # a damaged one is refused before anything starts
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
    with open(path, "wb") as handle:
        np.savez(handle, **arrays)


def read_npz(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as arrays:
        return {key: arrays[key] for key in arrays.files}


def reference_curve(runs_root: Path) -> list[list[float]] | None:
    """The learning curve of an env-reward run next to this one, if there is one."""
    for results in sorted(runs_root.glob(f"*/{RESULTS_FILE}")):
        data = read_run_file(results, read_json)
        if data["config"]["reward"] == "env":
            return data["learning_curve"]
    return None


# the command line's names of settings whose flag is not their dotted path's (add_setting_flags)
TRAIN_FLAG_PREFIXES = {"learned_reward": "", "sac": ""}
TRAIN_FLAG_NAMES = {"intrinsic.mode": "intrinsic"}


def parse_args(argv: list[str] | None) -> tuple[TrainConfig, argparse.Namespace]:
    parser = OneLineParser(
        prog="inest-train", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", help="run folder (required unless --print-config)")
    parser.add_argument("--config", help="YAML file of training settings (see inest_agent_node/config/train.yaml)")
    parser.add_argument(
        "--print-config", action="store_true", help="print every setting these arguments give, as YAML, and exit"
    )
    resuming = parser.add_mutually_exclusive_group()
    resuming.add_argument("--resume", action="store_true", help="continue the run in --out from its last checkpoint")
    resuming.add_argument(
        "--start-over",
        action="store_true",
        help="train the run in --out again from step 0 (stopped before its first checkpoint)",
    )
    settings = add_setting_flags(
        parser.add_argument_group("training settings (TrainConfig; a flag overrides --config)"),
        TrainConfig,
        prefixes=TRAIN_FLAG_PREFIXES,
        flags=TRAIN_FLAG_NAMES,
    )
    args = parser.parse_args(argv)
    if args.out is None and not args.print_config:
        parser.error("the following arguments are required: --out")
    if args.resume:  # a run with nothing to resume says so, whatever settings the flags lack
        check_resume(Path(args.out), resume=True, start_over=False)
    overrides = settings.overrides(args)
    intrinsic = overrides.setdefault("intrinsic", {})
    if "mode" not in intrinsic and overrides.get("reward", "inest") != "inest":
        intrinsic["mode"] = "none"  # --reward env|xirl|holdr on an inest config file
    if "weight" in intrinsic:
        intrinsic.setdefault("boosted_weight", 2 * intrinsic["weight"])  # the thesis's doubling after a switch
    if not intrinsic:
        del overrides["intrinsic"]
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
    except Exception as error:
        if not out_of_space(error):
            raise
        print(f"inest-train: {no_space_message(error)}", file=sys.stderr)
        return NO_SPACE_EXIT
    print(format_table({f"{config.reward} ({trainer.model.num_timesteps} steps)": result}))
    print(f"wrote {Path(args.out) / RESULTS_FILE} and learning_curve.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
