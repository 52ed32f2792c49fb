"""Policy evaluation as in thesis 5.1.3: N episodes on fresh layouts, mean score, success rate and
the share of episodes ending with 0, 1, 2 or 3 blocks placed in order; learning-curve plot.

Layouts are named sets (`LAYOUT_SETS`), each episode's layout drawn from its own seed, never one
training or the demonstrations draw: settings are chosen on `validation` scores (the learning
curves, `final_validation`), results are reported on `test` (`final_evaluation`, the development
test set: every run is scored on it, so over many runs it has informed the direction of the
work). `legacy` are the layouts every run before the split was evaluated on (10,000,000 + the
run's seed + i), on which its settings were also chosen. `locked` is the test set a release's
headline rows are scored on once each (`inest-evaluate --layouts locked --release NAME`, which
records the commit that scored them); `layouts` refuses it, and any seed range reaching into it,
to everything else, and so does inest-record-clips (`check_not_locked`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from inest_sim_node.scoring import NUM_BLOCKS
from stable_baselines3.common.vec_env import VecEnv

from inest_sim_node import EnvConfig, SweepToTopEnv

LAYOUT_SETS = {"legacy": 10_000_000, "validation": 20_000_000, "test": 30_000_000}  # the first layout seed
LOCKED = "locked"
LOCKED_SEEDS = range(50_000_000, 51_000_000)  # the locked test set's layouts; nothing else draws from them


@dataclass(frozen=True)
class Layouts:
    """Episode i of an evaluation plays the layout of seed `first + i`."""

    name: str
    first: int
    size: int | None = None  # how many layouts the set has (None: as many as asked for)

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "first_seed": self.first}

    def check(self, episodes: int) -> None:
        if self.size is not None and episodes > self.size:
            raise ValueError(f"{episodes} episodes asked of the {self.size} layouts {self.name}")


def seed_range(spec: str) -> Layouts:
    first, colon, stop = spec.partition(":")
    if not (colon and first.isdigit() and stop.isdigit() and int(stop) > int(first)):
        names = sorted([*LAYOUT_SETS, LOCKED])
        raise ValueError(f"layouts must be one of {names} or a seed range FIRST:STOP, got {spec!r}")
    return Layouts(spec, int(first), int(stop) - int(first))


def layouts(spec: str, run_seed: int = 0, release: bool = False) -> Layouts:
    """`validation`, `test`, `legacy` (of the run's seed) or a seed range `FIRST:STOP`; `locked`,
    or a range reaching into it, only for a `release`'s recorded scoring."""
    if spec in LAYOUT_SETS:
        return Layouts(spec, LAYOUT_SETS[spec] + (run_seed if spec == "legacy" else 0))
    chosen = Layouts(LOCKED, LOCKED_SEEDS.start, len(LOCKED_SEEDS)) if spec == LOCKED else seed_range(spec)
    assert chosen.size is not None
    if not release:
        check_not_locked(chosen.first, chosen.size, f"layouts {spec!r}")
    return chosen


def check_not_locked(first: int, count: int, what: str) -> None:
    """Refuse layout seeds first .. first + count - 1 that reach into the locked test set."""
    if first < LOCKED_SEEDS.stop and LOCKED_SEEDS.start < first + count:
        raise ValueError(
            f"{what} reach into the locked test set's layouts ({LOCKED_SEEDS.start}:{LOCKED_SEEDS.stop}): "
            "they are scored once per run, for a release, by inest-evaluate --layouts locked --release NAME"
        )


VALIDATION, TEST = layouts("validation"), layouts("test")

Policy = Callable[[np.ndarray, SweepToTopEnv], np.ndarray]


@dataclass
class EvalResult:
    episodes: int
    mean_score: float
    score_std: float
    success_rate: float
    blocks_share: list[float]  # share of episodes ending with 0, 1, 2, 3 blocks in order

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_scores(cls, scores: list[float]) -> EvalResult:
        """From each episode's final score (k / 3)."""
        scores_array = np.array(scores, dtype=float)
        blocks = np.rint(scores_array * NUM_BLOCKS).astype(int)
        return cls(
            episodes=len(scores),
            mean_score=float(scores_array.mean()),
            score_std=float(scores_array.std()),
            success_rate=float(np.mean(blocks == NUM_BLOCKS)),
            blocks_share=[float(np.mean(blocks == count)) for count in range(NUM_BLOCKS + 1)],
        )


def evaluate(
    policy: Policy, episodes: int = 150, env_config: EnvConfig | None = None, on: Layouts = TEST
) -> EvalResult:
    """Run `policy(observation, env)` for `episodes` full episodes; the score is the one at the end."""
    on.check(episodes)
    env = SweepToTopEnv(config=env_config or EnvConfig())
    scores = []
    for episode in range(episodes):
        observation, info = env.reset(seed=on.first + episode)
        done = False
        while not done:
            observation, _, terminated, truncated, info = env.step(policy(observation, env))
            done = terminated or truncated
        scores.append(float(info["score"]))
    env.close()
    return EvalResult.from_scores(scores)


def evaluate_vec_env(
    env: VecEnv, predict: Callable[[np.ndarray], np.ndarray], episodes: int, on: Layouts
) -> EvalResult:
    """`episodes` episodes of `predict(observations) -> actions` on the layouts `on`, N at a time
    (environment i of a batch on the next seed + i), through whatever observation path `env` has:
    in process or over the graph. Episodes are truncated at a fixed length, so a batch ends together."""
    on.check(episodes)
    scores: list[float] = []
    while len(scores) < episodes:
        count = min(env.num_envs, episodes - len(scores))
        env.seed(on.first + len(scores))
        observations = env.reset()
        finished: dict[int, float] = {}
        while len(finished) < count:
            observations, _, dones, infos = env.step(predict(observations))
            for index in range(count):
                if dones[index] and index not in finished:
                    finished[index] = float(infos[index]["score"])
        scores += [finished[index] for index in range(count)]
    return EvalResult.from_scores(scores)


def format_table(rows: dict[str, EvalResult]) -> str:
    width = max(17, *map(len, rows))
    lines = [f"{'policy':<{width}} episodes  mean score  success   0 blocks  1 block  2 blocks  3 blocks"]
    for name, result in rows.items():
        shares = "  ".join(f"{share:>7.1%}" for share in result.blocks_share)
        lines.append(
            f"{name:<{width}} {result.episodes:>8}  {result.mean_score:>10.3f}  {result.success_rate:>7.1%}  {shares}"
        )
    return "\n".join(lines)


def moving_average(values: np.ndarray, window: int) -> np.ndarray:
    return np.array([values[max(0, i - window + 1) : i + 1].mean() for i in range(len(values))])


def plot_learning_curve(
    curves: dict[str, list[list[float]]], path: str | Path, reference: list[list[float]] | None = None, window: int = 5
) -> None:
    """curves: name -> [[step, mean score, std], ...]; moving average over `window` evaluation points
    with a std band; `reference` (the env-reward run) dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(7, 4))
    for name, points in curves.items():
        if not points:
            continue
        steps, means, stds = (np.array(column) for column in zip(*points, strict=True))
        mean, std = moving_average(means, window), moving_average(stds, window)
        axis.plot(steps, mean, label=name)
        axis.fill_between(steps, np.clip(mean - std, 0, 1), np.clip(mean + std, 0, 1), alpha=0.2)
    if reference:
        steps, means, _ = (np.array(column) for column in zip(*reference, strict=True))
        axis.plot(steps, moving_average(means, window), "k--", label="env reward (reference)")
    axis.set(xlabel="environment steps", ylabel="evaluation score", ylim=(0, 1.02), title="evaluation score")
    if axis.get_legend_handles_labels()[0]:  # a run too short for any evaluation has no curve
        axis.legend()
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)
