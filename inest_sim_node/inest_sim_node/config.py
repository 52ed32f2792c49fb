"""Typed configuration of the task world and the gymnasium environment.

Defaults follow X-MAGICAL's SweepToTop with the gripper embodiment (fps 8, 10 physics
substeps, 100-step episodes, robot radius 0.2, block side sqrt(pi) * 0.12) so results
stay comparable with XIRL and the INEST-IRL thesis.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any

VIEWS = ("ego", "allo")
OBSERVATIONS = ("state", "pixels", "state_pixels")
LAYOUTS = ("random", "demo")
ORACLE_REWARDS = ("progress", "approach")  # scoring.dense_reward without / with its approach parts


@dataclass(frozen=True)
class WorldConfig:
    """Physical constants of the arena, the blocks and the gripper."""

    arena_half_size: float = 1.1
    goal_bottom: float = 0.76  # the goal strip spans y in [goal_bottom, top wall]
    block_side: float = math.sqrt(math.pi) * 0.12
    block_mass: float = 0.01
    block_slide_friction: float = 1.5  # max force of the ground-friction pivot joint
    block_spin_friction: float = 0.1  # max torque of the ground-friction gear joint
    robot_radius: float = 0.2
    robot_mass: float = 1.0
    robot_drive_force: float = 12.5  # X-MAGICAL's 5 scaled with the speed: same time to full speed
    robot_turn_torque: float = 1.0
    finger_force: float = 4.0
    finger_open_angle: float = math.pi / 8
    # X-MAGICAL drives at 0.8 units/s and turns at 2.5 rad/s. The ordered task needs three
    # separate trips; at those rates our expert needs a median of 119 steps (p95 139), so
    # it cannot fit the 100-step episodes. Measured at 2.0 and 4.0: median 73, p95 94.
    max_speed: float = 2.0  # world units per second at action[0] = 1
    max_turn_rate: float = 4.0  # rad/s at action[1] = 1
    control_hz: float = 8.0
    substeps: int = 10
    solver_iterations: int = 10

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not math.isfinite(value) or value <= 0:
                raise ValueError(f"WorldConfig.{f.name} must be a positive finite number, got {value!r}")
        if self.goal_bottom >= self.arena_half_size - self.block_side:
            raise ValueError("WorldConfig.goal_bottom leaves no room for a block inside the goal strip")


@dataclass(frozen=True)
class LayoutConfig:
    """How block and robot start poses are drawn from the episode seed."""

    kind: str = "random"  # "random": X-MAGICAL TestLayout; "demo": one fixed layout
    row_y_range: tuple[float, float] = (-0.1, 0.5)  # blocks share one row, as in X-MAGICAL
    slot_xs: tuple[float, ...] = (-0.8, -0.32, 0.16, 0.64)  # X-MAGICAL's slots, 4 block radii apart
    block_jitter: float = 0.03  # extra per-block xy jitter for more varied demonstrations
    robot_start: tuple[float, float] = (0.0, -0.6)
    robot_jitter: float = 0.05
    robot_angle_jitter: float = 0.1

    def __post_init__(self) -> None:
        if self.kind not in LAYOUTS:
            raise ValueError(f"unknown layout {self.kind!r}; expected one of {LAYOUTS}")
        if len(self.slot_xs) < 3:
            raise ValueError("LayoutConfig.slot_xs needs at least 3 slots for 3 blocks")
        for name in ("block_jitter", "robot_jitter", "robot_angle_jitter"):
            value = getattr(self, name)
            if not math.isfinite(value) or value < 0:
                raise ValueError(f"LayoutConfig.{name} must be >= 0, got {value!r}")


@dataclass(frozen=True)
class EnvConfig:
    """Everything `SweepToTopEnv` needs; gymnasium.make keyword arguments map onto it."""

    observation: str = "state"  # "state", "pixels" (camera `view`) or "state_pixels" (dict of both)
    view: str = "ego"  # camera for pixel observations: egocentric or allocentric
    image_size: int = 96  # square side in pixels; 96 keeps the ResNet-18 fast on 2 CPU cores
    render_size: int = 256  # size of env.render() frames, for people watching
    max_steps: int = 100
    reward: str = "progress"  # the oracle (scoring.dense_reward): "progress" or "approach" (+ reach and hold)
    world: WorldConfig = field(default_factory=WorldConfig)
    layout: LayoutConfig = field(default_factory=LayoutConfig)

    def __post_init__(self) -> None:
        if self.observation not in OBSERVATIONS:
            raise ValueError(f"unknown observation {self.observation!r}; expected one of {OBSERVATIONS}")
        if self.reward not in ORACLE_REWARDS:
            raise ValueError(f"unknown oracle reward {self.reward!r}; expected one of {ORACLE_REWARDS}")
        if self.view not in VIEWS:
            raise ValueError(f"unknown view {self.view!r}; expected one of {VIEWS}")
        for name in ("image_size", "render_size", "max_steps"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
                raise ValueError(f"{name} must be a positive integer, got {value!r}")

    @classmethod
    def from_kwargs(cls, **kwargs: Any) -> EnvConfig:
        """Build from flat keyword arguments, nested configs given as dicts or instances."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(kwargs) - known)
        if unknown:
            raise ValueError(f"unknown environment argument(s) {unknown}; expected some of {sorted(known)}")
        if isinstance(kwargs.get("world"), dict):
            kwargs["world"] = WorldConfig(**kwargs["world"])
        if isinstance(kwargs.get("layout"), dict):
            kwargs["layout"] = LayoutConfig(**kwargs["layout"])
        return cls(**kwargs)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)
