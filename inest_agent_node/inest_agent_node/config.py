"""Training configuration, one typed place, loadable from YAML (`config/train.yaml`). The experiment
grids' configuration (`config/grid.yaml` and the other grid files) is inest_experiments.config."""

from __future__ import annotations

from dataclasses import MISSING, asdict, dataclass, field, fields
from pathlib import Path
from typing import Any, Literal

import yaml
from inest_common.settings import CHOICES, build_settings, check_choices
from inest_reward_node.learning.runs import merge_settings
from inest_reward_node.runtime.config import RewardConfig
from inest_reward_node.runtime.intrinsic import IntrinsicConfig
from inest_reward_node.runtime.methods import REWARD_METHODS
from inest_reward_node.runtime.model import TCC_SCHEMES
from inest_sim_node.config import ORACLE_REWARDS, VIEWS
from inest_sim_node.observation import STATE_OBSERVATIONS
from inest_sim_node.scoring import NUM_BLOCKS

from .learners import LEARNERS

LEARNER_NAMES = tuple(LEARNERS)


def reward_names() -> tuple[str, ...]:
    """env: the simulator's own; the learned methods (runtime.methods.REWARD_METHODS, read at each
    call: a method registered later counts); topic: served by inest_reward_node (graph only)."""
    return ("env", *REWARD_METHODS, "topic")


REWARDS = reward_names()


def reward_scheme(reward: str, subtasks: int) -> int:
    """The subtask scheme a learned `reward` is scored with: `subtasks` for the staged rewards,
    1 for XIRL and HOLD-R (one goal)."""
    method = REWARD_METHODS.get(reward)
    return 1 if method is not None and method.single_goal else subtasks


def read_yaml_mapping(path: str | Path, what: str, empty_ok: bool = False) -> dict[str, Any]:
    """A YAML file's mapping (`empty_ok`: an empty file is an empty one); a file that cannot be
    read, is not YAML or holds no mapping is one ValueError naming it. `what`: what the mapping
    holds, for the message."""
    try:
        data = yaml.safe_load(Path(path).read_text())
    except OSError as error:
        raise ValueError(f"cannot read {path}: {error.strerror}") from None
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise ValueError(f"{path} is not valid YAML{where}: {getattr(error, 'problem', None) or error}") from None
    if data is None and empty_ok:
        return {}
    if not isinstance(data, dict):
        raise ValueError(f"{path} must hold a mapping of {what}")
    return data


@dataclass(frozen=True)
class SacConfig:
    """SAC settings (any learner of learners.py). From SB3/the SAC paper: learning rate, batch,
    tau, gamma, network, automatic entropy. Changed for CPU speed: 2 gradient steps per vector
    step of `num_envs` = 4 environments (SAC's default is one per environment step)."""

    learning_rate: float = 3e-4
    buffer_size: int = 1_000_000
    learning_starts: int = 5_000  # random-action steps before the first update
    batch_size: int = 256
    tau: float = 0.005
    gamma: float = 0.99
    train_freq: int = 1  # vector steps between updates
    gradient_steps: int = 2  # per update: 2 per vector step of 4 environments, a replay ratio of 0.5
    net_arch: tuple[int, ...] = (256, 256)
    ent_coef: str = "auto"  # the entropy coefficient: auto (tuned to a target entropy) or a number as text

    def __post_init__(self) -> None:
        for name in ("learning_rate", "buffer_size", "batch_size", "train_freq"):
            if not getattr(self, name) > 0:  # also rejects NaN
                raise ValueError(f"sac.{name} must be positive, got {getattr(self, name)}")
        for name in ("tau", "gamma"):
            if not 0 < getattr(self, name) <= 1:
                raise ValueError(f"sac.{name} must be in (0, 1], got {getattr(self, name)}")
        if self.learning_starts < 0:
            raise ValueError(f"sac.learning_starts must be >= 0, got {self.learning_starts}")
        if self.gradient_steps < 1 and self.gradient_steps != -1:
            raise ValueError(f"sac.gradient_steps must be >= 1 (-1: one per env step), got {self.gradient_steps}")
        if not self.net_arch or min(self.net_arch) < 1:
            raise ValueError(f"sac.net_arch must list positive layer widths, got {list(self.net_arch)}")


# TrainConfig settings that change how fast or how often it checkpoints, not what is trained: a
# resumed run, or a grid cell continued, may change them (a resumed run may also train further)
SPEED_ONLY_SETTINGS = frozenset({"reward_batch_steps", "overlap_updates", "checkpoint_every", "checkpoint_minutes"})


@dataclass(frozen=True)
class TrainConfig:
    # env (the oracle), a learned method (xirl, holdr, reds, inest) or topic (the reward node's, over the graph)
    reward: str = field(default="inest", metadata={CHOICES: reward_names})
    model: str | None = None  # reward model folder (inest-pretrain's model/); not used by "env"
    subtasks: Literal[TCC_SCHEMES] = 3  # inest: 1, 3 or 6; reds: the segmentation its model was trained on
    view: Literal[VIEWS] = "ego"  # the camera the learned reward reads
    intrinsic: IntrinsicConfig = field(default_factory=IntrinsicConfig)
    # how the learned reward shapes and tracks subtasks (runtime.config.RewardConfig: shaping, tracker,
    # stage_source "privileged" for the true-stage diagnostic, intrinsic_cap)
    learned_reward: RewardConfig = field(default_factory=RewardConfig)
    # robot: what a robot senses (no score, no in-goal flags) plus the reward's stage one-hot and the
    # stage block's offsets (Markov in the staged reward; observation.py); stage: the same on the
    # whole simulator state, score included (the earlier default); state: the bare 21-entry state
    observation: Literal[STATE_OBSERVATIONS] = "robot"
    # the simulator's reward (reward env): progress, or approach (progress plus reach and hold)
    oracle: Literal[ORACLE_REWARDS] = "approach"
    learner: Literal[LEARNER_NAMES] = "sbx_sac"  # the off-policy learner (learners.py)
    num_envs: int = 4  # environments stepped side by side
    # vector steps whose frames are scored in one encoder pass (speed only; see envs.RewardVecEnv);
    # the stage observation needs each step's stage at once, so only 1 goes with it
    reward_batch_steps: int = 1
    total_steps: int = 200_000  # environment steps, over all environments
    eval_every: int = 10_000  # steps between the learning curve's evaluations (validation layouts)
    eval_episodes: int = 50  # episodes per learning-curve evaluation
    final_eval_episodes: int = 150  # episodes of the final evaluation, on test and on validation layouts
    checkpoint_every: int = 20_000  # steps between checkpoints ...
    # and at least this often, so that a killed run loses minutes, whatever its speed
    checkpoint_minutes: float = 5.0
    seed: int = 0
    threads: int = 2  # torch's (and JAX's) CPU threads
    # run each update while the environments take the next step (learners.OverlappedUpdatesMixin;
    # the action then comes from a policy one update older): in process on a second thread, over
    # the graph while the simulators and the reward node work
    overlap_updates: bool = False
    # self negatives (self_negatives.py): every this many steps the stage classifier is refitted on
    # `refit_demos`' demonstrations and the agent's own unconfirmed stage claims; 0: off
    refit_every: int = 0
    refit_demos: str | None = None  # the demonstration dataset the refit keeps the classifier anchored to
    # labelled rollouts (labelled_rollouts.py): at each of these steps `label_episodes` of the agent's
    # next episodes in which the reward claimed a stage are labelled (the simulator standing in for
    # a person) and the stage classifier is refitted with them; (): none
    label_at: tuple[int, ...] = ()
    label_episodes: int = 5  # episodes labelled at each of label_at
    # the labelled episodes also raise the completion thresholds (stage_refit.py), as random play
    # raises them at calibration; False: they refit the stage classifier only
    label_raise_thresholds: bool = True
    sac: SacConfig = field(default_factory=SacConfig)

    def __post_init__(self) -> None:
        check_choices(self)
        if self.reward not in ("env", "topic") and not self.model:
            raise ValueError(f"the {self.reward} reward needs a reward model folder (model)")
        if self.reward != "inest" and self.intrinsic.mode != "none":
            raise ValueError(f"the intrinsic bonus belongs to the inest reward, not {self.reward}")
        if self.learned_reward.stage_source == "privileged" and reward_scheme(self.reward, self.subtasks) == 6:
            raise ValueError(
                "stage_source 'privileged' (a diagnostic) knows the true stage of the 1- and 3-subtask schemes only"
            )
        if self.observation != "state" and self.reward_batch_steps != 1:
            raise ValueError(
                "the stage observation needs every step's stage before the next action: "
                f"set reward_batch_steps to 1 (got {self.reward_batch_steps}) or observation to 'state'"
            )

        for name in (
            "num_envs",
            "reward_batch_steps",
            "total_steps",
            "eval_every",
            "eval_episodes",
            "final_eval_episodes",
            "checkpoint_every",
            "threads",
        ):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        if self.refit_every < 0:
            raise ValueError(f"refit_every must be >= 0 (0: no refit), got {self.refit_every}")
        if (self.refit_every or self.label_at) and (self.reward != "inest" or not self.refit_demos):
            raise ValueError("refitting the stage classifier needs the inest reward and refit_demos (a dataset)")
        steps = list(self.label_at)
        if any(type(step) is not int or step <= 0 for step in steps) or steps != sorted(set(steps)):
            raise ValueError(f"label_at must list distinct positive steps in ascending order, got {steps}")
        if self.label_episodes <= 0:
            raise ValueError(f"label_episodes must be positive, got {self.label_episodes}")
        if not self.checkpoint_minutes > 0:
            raise ValueError(f"checkpoint_minutes must be positive, got {self.checkpoint_minutes}")
        if self.seed < 0:
            raise ValueError(f"seed must be >= 0, got {self.seed}")

    @property
    def stage_subtasks(self) -> int:
        """Stages the policy's observation distinguishes: the simulator's blocks for the oracle,
        the learned reward's subtasks otherwise (XIRL and HOLD-R have one goal; REDS infers its own)."""
        if self.reward == "env":
            return NUM_BLOCKS
        return reward_scheme(self.reward, self.subtasks)

    def settings_that_matter(self, start_over: bool = False) -> set[str]:
        """Settings that change what is trained, which a resumed run must keep: all but the speed-only
        ones and `total_steps` (it may train further); none for a run trained again from step 0."""
        return set() if start_over else set(self.to_dict()) - SPEED_ONLY_SETTINGS - {"total_steps"}

    def to_dict(self) -> dict[str, Any]:
        data = asdict(self)
        data["sac"]["net_arch"] = list(self.sac.net_arch)
        data["label_at"] = list(self.label_at)
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TrainConfig:
        values = dict(data)
        if values.get("reward", "inest") != "inest" and "intrinsic" not in values:
            values["intrinsic"] = {"mode": "none"}  # the bonus belongs to the inest reward
        return build_settings(cls, values, "training setting(s)")

    @classmethod
    def from_yaml(cls, path: str | Path, overrides: dict[str, Any] | None = None) -> TrainConfig:
        """Settings from a YAML file, then `overrides` (command-line flags) on top."""
        data = read_yaml_mapping(path, "training settings", empty_ok=True)
        return cls.from_dict(merge_settings(data, overrides or {}))


def setting_defaults() -> dict[str, Any]:
    """Today's defaults of the settings a saved run's config may lack: one added since it was
    written is taken to be its default (a resumed run, a continued grid cell). New settings
    default to what runs did before them, so this changes nothing a run was trained with."""
    plain = {f.name: f.default for f in fields(TrainConfig) if f.default is not MISSING}
    return {**plain, "label_at": [], "learned_reward": RewardConfig().to_dict(), "sac": asdict(SacConfig())}
