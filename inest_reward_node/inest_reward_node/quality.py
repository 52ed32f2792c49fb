"""Reward quality of a trained model on held-out demonstrations (`inest-reward-quality`, thesis 5.3).

Per subtask scheme the model has (its default reward: xirl for 1 subtask, inest for 3 and 6,
holdr for HOLD-R models), over the validation demonstrations:
- reward vs environment: both per-frame traces are min-max normalised to [0, 1] within each
  demonstration (the learned and the oracle reward live on unrelated scales; only the shape
  is comparable), then MSE, MAE and bias = mean(learned - env) are averaged over demonstrations.
- cosine-similarity Gaussians: for each subtask, the cosine similarity of every frame's
  embedding to the subtask's goal embedding, min-max normalised per demonstration, against the
  ground truth: a Gaussian centred on the frame where the subtask really ends, with a standard
  deviation of half that subtask's length; MSE averaged over subtasks and demonstrations.
- Spearman rank correlation of the reward with progress (frame index / length; the
  demonstrations are near-optimal, so time is progress) and with the environment reward.
- tracker replay: share of demonstrations on which a fresh subtask tracker completes every
  subtask in order, and how many frames each completion lands from the true subtask end.
Writes report.json (with the model's config) and PNG plots into --out.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from inest_sim_node.dataset import DatasetError
from scipy.stats import spearmanr
from tqdm import tqdm

from .calibrate import subtask_starts
from .data import Demo, load_demos
from .model import ModelError, RewardModel, load_model
from .rewards import Replay, default_variant, replay

REPORT_FILE = "report.json"


def min_max(values: np.ndarray) -> np.ndarray:
    values = np.asarray(values, dtype=np.float64)
    span = values.max() - values.min()
    return (values - values.min()) / span if span > 0 else np.zeros_like(values)


def cosine_similarity(embeddings: np.ndarray, goal: np.ndarray) -> np.ndarray:
    norms = np.linalg.norm(embeddings, axis=1) * np.linalg.norm(goal)
    return embeddings @ goal / np.maximum(norms, 1e-12)


def ground_truth_gaussian(length: int, start: int, end: int) -> np.ndarray:
    sigma = max((end - start + 1) / 2.0, 1.0)
    return np.exp(-0.5 * ((np.arange(length) - end) / sigma) ** 2)


def rank_correlation(a: np.ndarray, b: np.ndarray) -> float:
    if np.ptp(a) == 0 or np.ptp(b) == 0:
        return 0.0
    return float(spearmanr(a, b).statistic)


@dataclass
class DemoQuality:
    """One demonstration's numbers under one scheme."""

    reward: np.ndarray  # learned reward per frame
    env: np.ndarray  # environment reward per frame (frame 0 repeats frame 1's)
    cosine: np.ndarray  # (frames, subtasks)
    gaussians: np.ndarray  # (frames, subtasks)
    replay: Replay
    ends: np.ndarray
    metrics: dict[str, float] = field(default_factory=dict)


def demo_quality(model: RewardModel, demo: Demo, embeddings: np.ndarray, scheme: int, variant: str) -> DemoQuality:
    played = replay(model, embeddings, scheme, variant)
    env = np.concatenate([demo.rewards[:1], demo.rewards]).astype(np.float64)
    goals = model.goals(scheme).goals
    ends = demo.ends[scheme]
    starts = subtask_starts(ends)
    cosine = np.stack([cosine_similarity(embeddings, goal) for goal in goals], axis=1)
    gaussians = np.stack([ground_truth_gaussian(len(demo), s, e) for s, e in zip(starts, ends, strict=True)], axis=1)
    learned, oracle = min_max(played.rewards), min_max(env)
    progress = np.arange(len(demo)) / max(len(demo) - 1, 1)
    offsets = [frame - int(end) for frame, end in zip(played.completion_frames, ends, strict=False)]
    metrics = {
        "mse": float(np.mean((learned - oracle) ** 2)),
        "mae": float(np.mean(np.abs(learned - oracle))),
        "bias": float(np.mean(learned - oracle)),
        "cosine_gaussian_mse": float(
            np.mean([np.mean((min_max(cosine[:, i]) - gaussians[:, i]) ** 2) for i in range(len(goals))])
        ),
        "spearman_progress": rank_correlation(played.rewards, progress),
        "spearman_env": rank_correlation(played.rewards, env),
        "tracker_all_completed": float(played.all_completed),
        "completion_offset_frames": float(np.mean(offsets)) if offsets else float("nan"),
    }
    return DemoQuality(played.rewards, env, cosine, gaussians, played, ends, metrics)


def summarise(results: list[DemoQuality]) -> dict[str, Any]:
    table = {key: np.array([r.metrics[key] for r in results]) for key in results[0].metrics}
    return {
        "demos": len(results),
        "reward_vs_env": {key: float(table[key].mean()) for key in ("mse", "mae", "bias")},
        "cosine_gaussian_mse": float(table["cosine_gaussian_mse"].mean()),
        "spearman_progress": {
            "median": float(np.median(table["spearman_progress"])),
            "mean": float(table["spearman_progress"].mean()),
        },
        "spearman_env": {
            "median": float(np.median(table["spearman_env"])),
            "mean": float(table["spearman_env"].mean()),
        },
        "tracker_pass_rate": float(table["tracker_all_completed"].mean()),
        "completion_offset_frames_mean": float(np.nanmean(table["completion_offset_frames"]))
        if np.isfinite(table["completion_offset_frames"]).any()
        else None,
    }


def plot_scheme(results: list[DemoQuality], title: str, path: Path, examples: int = 3) -> None:
    """Top row: learned vs environment reward (normalised); bottom row: cosine curves vs ground truth."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = results[:examples]
    figure, axes = plt.subplots(2, len(shown), figsize=(4.2 * len(shown), 6), squeeze=False)
    colours = plt.get_cmap("tab10")
    for column, result in enumerate(shown):
        top, bottom = axes[0, column], axes[1, column]
        top.plot(min_max(result.reward), label="learned (normalised)")
        top.plot(min_max(result.env), "--", label="environment (normalised)")
        for frame in result.replay.completion_frames:
            top.axvline(frame, color="grey", alpha=0.4, linewidth=0.8)
        top.set(title=f"demo {column}: reward", xlabel="frame")
        for i in range(result.cosine.shape[1]):
            bottom.plot(min_max(result.cosine[:, i]), color=colours(i), label=f"subtask {i + 1}")
            bottom.plot(result.gaussians[:, i], "--", color=colours(i), alpha=0.6)
        bottom.set(title="cosine to goal (solid) vs ground truth (dashed)", xlabel="frame")
    axes[0, 0].legend(fontsize=8)
    axes[1, 0].legend(fontsize=8)
    figure.suptitle(title)
    figure.tight_layout()
    figure.savefig(path, dpi=90)
    plt.close(figure)


def evaluate(
    model: RewardModel, demos: list[Demo], schemes: list[int], out: Path, progress_bar: bool = True
) -> dict[str, Any]:
    out.mkdir(parents=True, exist_ok=True)
    embeddings = [
        model.embed(demo.frames) for demo in tqdm(demos, desc="embedding", disable=not progress_bar, leave=False)
    ]
    report: dict[str, Any] = {"model": model.metadata, "normalisation": __doc__, "schemes": {}}
    for scheme in schemes:
        variant = default_variant(model, scheme)
        results = [demo_quality(model, demo, emb, scheme, variant) for demo, emb in zip(demos, embeddings, strict=True)]
        summary = {"variant": variant, **summarise(results)}
        plot_path = out / f"quality_{variant}_{scheme}.png"
        plot_scheme(results, f"{variant}, {scheme} subtask(s), {model.view} camera", plot_path)
        summary["plot"] = plot_path.name
        report["schemes"][str(scheme)] = summary
    (out / REPORT_FILE).write_text(json.dumps(report, indent=2) + "\n")
    return report


def format_summary(report: dict[str, Any]) -> str:
    lines = ["variant  subtasks  spearman(progress)  tracker pass  MSE    MAE    bias    cosine-MSE"]
    for scheme, row in report["schemes"].items():
        env = row["reward_vs_env"]
        lines.append(
            f"{row['variant']:<8} {scheme:>8}  {row['spearman_progress']['median']:>18.3f}  "
            f"{row['tracker_pass_rate']:>12.1%}  {env['mse']:.3f}  {env['mae']:.3f}  {env['bias']:+.3f}  "
            f"{row['cosine_gaussian_mse']:.3f}"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("model", help="model folder (a pretraining run's model/)")
    parser.add_argument("dataset", help="demonstration dataset; its validation split is used")
    parser.add_argument("--out", required=True, help="folder for report.json and the plots")
    parser.add_argument("--schemes", type=int, nargs="*", help="subtask schemes (default: all the model has)")
    parser.add_argument("--split", default="valid", choices=("train", "valid"))
    parser.add_argument("--limit", type=int, help="use only the first N demonstrations")
    args = parser.parse_args(argv)
    try:
        model = load_model(args.model)
        schemes = args.schemes or sorted(model.subtasks)
        for scheme in schemes:
            model.goals(scheme)
        demos = load_demos(args.dataset, args.split, model.view, model.image_size, args.limit)
        if not demos:
            raise DatasetError(f"{args.dataset} has no {args.split} demonstrations")
        report = evaluate(model, demos, schemes, Path(args.out))
    except (ModelError, DatasetError) as error:
        print(f"inest-reward-quality: {error}", file=sys.stderr)
        return 2
    print(format_summary(report))
    print(f"wrote {Path(args.out) / REPORT_FILE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
