"""The stable-baselines3 callbacks `inest-train` runs during `learn()`, one job each.

`training_callbacks(trainer)` combines them in a `CallbackList`, in this order (all see the same
vector step; the order matters only in that a checkpoint saves the history and diagnostics the
evaluation of the same step has just added):

- ProgressCallback: the tqdm bar (steps, and after each evaluation its score and steps/s);
- RewardDiagnosticsCallback: every step's infos into diagnostics.RewardDiagnostics; every
  `eval_every` steps their summary into `trainer.diagnostics` and TensorBoard `diagnostics/*`;
- RefitCallback (with `refit_every` or `label_at`): the stage classifier refitted on the agent's
  own frames;
- EvaluationCallback: every `eval_every` steps the deterministic policy on `eval_episodes`
  evaluation episodes, into `trainer.history` and TensorBoard `eval/score`, `eval/success_rate`;
- CheckpointCallback: every `checkpoint_every` steps or `checkpoint_minutes`, whichever comes
  first, `trainer.save_checkpoint()`, with a line saying its step and size.

"Every N steps" is on the first vector step at or past each multiple of N (`due`), since
`num_timesteps` grows by `num_envs` per vector step.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Protocol

from inest_common.progress import track
from inest_reward_node.learning.stage_refit import StageRefit
from stable_baselines3.common.callbacks import BaseCallback, CallbackList
from tqdm import tqdm

from .config import TrainConfig
from .diagnostics import RewardDiagnostics
from .evaluate import EvalResult


class Trainer(Protocol):
    """What the callbacks use of a training run (train.Trainer)."""

    config: TrainConfig
    run_dir: Path
    progress_bar: bool
    history: list[list[float]]
    diagnostics: list[dict[str, float]]
    stage_refit: StageRefit | None

    def evaluate(self, episodes: int) -> EvalResult: ...

    def save_checkpoint(self) -> int: ...

    def refit_stage_classifier(self) -> None: ...


def due(steps: int, every: int, num_envs: int) -> bool:
    """Whether the vector step that brought the step count to `steps` crossed a multiple of `every`."""
    return steps % every < num_envs


class ProgressCallback(BaseCallback):
    """The progress bar; `show_score` puts an evaluation's score and the training speed on it."""

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
        self.bar = track(
            total=config.total_steps,
            initial=self.num_timesteps,
            unit="step",
            desc=f"SAC {config.reward}",
            disable=not self.trainer.progress_bar,
        )

    def _on_step(self) -> bool:
        self.bar.update(self.num_timesteps - self.bar.n)
        return True

    def show_score(self, score: float) -> None:
        speed = (self.num_timesteps - self.start_steps) / max(time.perf_counter() - self.started, 1e-9)
        self.bar.set_postfix({"score": f"{score:.2f}", "steps/s": f"{speed:.0f}"})

    def _on_training_end(self) -> None:
        self.bar.close()


class RewardDiagnosticsCallback(BaseCallback):
    """What the reward paid for (diagnostics.py), summarised per evaluation interval."""

    def __init__(self, trainer: Trainer) -> None:
        super().__init__()
        self.trainer = trainer
        self.diagnostics = RewardDiagnostics(trainer.config.num_envs, trainer.config.stage_subtasks)

    def _on_step(self) -> bool:
        config = self.trainer.config
        self.diagnostics.update(self.locals["infos"], self.locals["dones"], self.locals["rewards"])
        if due(self.num_timesteps, config.eval_every, config.num_envs):
            diagnostics = self.diagnostics.summary()
            self.trainer.diagnostics.append({"steps": self.num_timesteps, **diagnostics})
            for name, value in diagnostics.items():
                self.logger.record(f"diagnostics/{name}", value)
        return True


class EvaluationCallback(BaseCallback):
    """Periodic evaluation of the deterministic policy (Trainer.evaluate): the learning curve."""

    def __init__(self, trainer: Trainer, progress: ProgressCallback | None = None) -> None:
        super().__init__()
        self.trainer = trainer
        self.progress = progress

    def _on_step(self) -> bool:
        config = self.trainer.config
        steps = self.num_timesteps
        if due(steps, config.eval_every, config.num_envs):
            result = self.trainer.evaluate(config.eval_episodes)
            self.trainer.history.append([steps, result.mean_score, result.score_std])
            self.logger.record("eval/score", result.mean_score)
            self.logger.record("eval/success_rate", result.success_rate)
            if self.progress is not None:
                self.progress.show_score(result.mean_score)
        return True


class RefitCallback(BaseCallback):
    """The stage classifier refitted on the agent's own frames (stage_refit.py): every
    `refit_every` steps, and as soon as a labelling round's episodes are all labelled; before
    the evaluation of the same step, which then reads it."""

    def __init__(self, trainer: Trainer) -> None:
        super().__init__()
        self.trainer = trainer

    def _on_step(self) -> bool:
        config, labelling = self.trainer.config, self.trainer.stage_refit.labelling
        if labelling is not None:
            labelling.open_rounds(self.num_timesteps)
        periodic = config.refit_every and due(self.num_timesteps, config.refit_every, config.num_envs)
        if periodic or (labelling is not None and labelling.round_complete()):
            self.trainer.refit_stage_classifier()
        return True


class CheckpointCallback(BaseCallback):
    """Periodic `Trainer.save_checkpoint()`, the `--resume` point (unlike stable-baselines3's own
    CheckpointCallback it also writes the replay buffer, history, diagnostics and novelty memories).
    A due checkpoint is written at the rollout's end: stable-baselines3 calls `on_step` before it
    stores the step's transition and `on_rollout_end` after, so a checkpoint written in `on_step`
    counted a step whose transition it lacked, and each resume lost one replay row."""

    def __init__(self, trainer: Trainer) -> None:
        super().__init__()
        self.trainer = trainer
        self.last = time.monotonic()
        self.due = False

    def _on_step(self) -> bool:
        config = self.trainer.config
        late = time.monotonic() - self.last >= config.checkpoint_minutes * 60
        self.due = self.due or late or due(self.num_timesteps, config.checkpoint_every, config.num_envs)
        return True

    def _on_rollout_end(self) -> None:
        if self.due:
            size = self.trainer.save_checkpoint()
            self.last, self.due = time.monotonic(), False
            tqdm.write(f"checkpoint at step {self.num_timesteps}: {size / 2**20:.1f} MB in {self.trainer.run_dir}")


def training_callbacks(trainer: Trainer) -> CallbackList:
    """Progress, reward diagnostics, evaluation and checkpoints, in that order (see the module docstring)."""
    progress = ProgressCallback(trainer)
    evaluation = EvaluationCallback(trainer, progress)
    refit = [RefitCallback(trainer)] if trainer.stage_refit is not None else []
    return CallbackList([progress, RewardDiagnosticsCallback(trainer), *refit, evaluation, CheckpointCallback(trainer)])
