"""Training configuration, one typed place, loadable from YAML (`configs/train.yaml`)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

import yaml
from inest_reward_node.intrinsic import IntrinsicConfig
from inest_reward_node.runs import merge_settings

REWARDS = ("env", "xirl", "holdr", "inest", "topic")  # topic: served by inest_reward_node (graph only)


@dataclass(frozen=True)
class SacConfig:
    """stable-baselines3 SAC. From SB3/the SAC paper: learning rate, batch, tau, gamma, network,
    automatic entropy. Changed for CPU speed: one gradient step per vector step of `num_envs`
    environments (SAC's default is one per environment step), as the platform facts measured."""

    learning_rate: float = 3e-4
    buffer_size: int = 1_000_000
    learning_starts: int = 5_000  # random-action steps before the first update
    batch_size: int = 256
    tau: float = 0.005
    gamma: float = 0.99
    train_freq: int = 1  # vector steps between updates
    gradient_steps: int = 1
    net_arch: tuple[int, ...] = (256, 256)
    ent_coef: str = "auto"


@dataclass(frozen=True)
class TrainConfig:
    reward: str = "inest"  # env (oracle) | xirl | holdr | inest | topic (the reward node's, over the graph)
    model: str | None = None  # reward model folder (inest-pretrain's model/); not used by "env"
    subtasks: int = 3  # inest: 1, 3 or 6
    view: str = "ego"
    intrinsic: IntrinsicConfig = field(default_factory=IntrinsicConfig)
    num_envs: int = 4
    # vector steps whose frames are scored in one encoder pass (speed only; see envs.LearnedRewardVecEnv)
    reward_batch_steps: int = 4
    total_steps: int = 200_000
    eval_every: int = 10_000
    eval_episodes: int = 50
    final_eval_episodes: int = 150
    checkpoint_every: int = 20_000
    seed: int = 0
    threads: int = 2
    sac: SacConfig = field(default_factory=SacConfig)

    def __post_init__(self) -> None:
        if self.reward not in REWARDS:
            raise ValueError(f"unknown reward {self.reward!r}; expected one of {REWARDS}")
        if self.reward not in ("env", "topic") and not self.model:
            raise ValueError(f"the {self.reward} reward needs a reward model folder (model)")
        if self.reward != "inest" and self.intrinsic.mode != "none":
            raise ValueError(f"the intrinsic bonus belongs to the inest reward, not {self.reward}")
        for name in (
            "num_envs",
            "reward_batch_steps",
            "total_steps",
            "eval_every",
            "eval_episodes",
            "checkpoint_every",
        ):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")

    def to_dict(self) -> dict[str, Any]:
        data = asdict(self)
        data["sac"]["net_arch"] = list(self.sac.net_arch)
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TrainConfig:
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"unknown training setting(s) {unknown}; expected some of {sorted(known)}")
        values = dict(data)
        if values.get("reward", "inest") != "inest" and "intrinsic" not in values:
            values["intrinsic"] = IntrinsicConfig(mode="none")  # the bonus belongs to the inest reward
        if isinstance(values.get("intrinsic"), dict):
            values["intrinsic"] = IntrinsicConfig(**values["intrinsic"])
        if isinstance(values.get("sac"), dict):
            sac = dict(values["sac"])
            if "net_arch" in sac:
                sac["net_arch"] = tuple(sac["net_arch"])
            values["sac"] = SacConfig(**sac)
        return cls(**values)

    @classmethod
    def from_yaml(cls, path: str | Path, overrides: dict[str, Any] | None = None) -> TrainConfig:
        """Settings from a YAML file, then `overrides` (command-line flags) on top."""
        data = yaml.safe_load(Path(path).read_text()) or {}
        if not isinstance(data, dict):
            raise ValueError(f"{path} must hold a mapping of training settings")
        return cls.from_dict(merge_settings(data, overrides or {}))
