"""`inest-summarise ROOT`: one table of the training runs under ROOT/<method>/<run>/, across seeds.

Writes ROOT/summary.json (per run: method, seed, steps, mean_score, success_rate, blocks_share,
from its 150-episode final evaluation, the layouts it was on (`test`, or `legacy` for runs before
the validation/test split), validation_mean_score, the reward's labelled_episodes and cameras
(its model's supervision record), reward_shares, training_s, its training wall-clock seconds, and
reward_diagnostics, the first and last window of its reward diagnostics (inest_agent_node/diagnostics.py); per
method: the mean over seeds with a 95 % bootstrap interval, `mean_score_ci95`, and a 95 % Student t
interval, `mean_score_t95`) and ROOT/learning_curves.png (per
method the mean evaluation score across seeds, with the band between the lowest and highest
seed). A run still training (its checkpoint's
history.json, or a copy of it beside config.json, and no results.json yet) is listed with
`"final": false` and its last periodic evaluation, and is left out of the per-method means.
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
from inest_agent_node.train import CHECKPOINT_DIR, HISTORY_FILE, RESULTS_FILE
from inest_common.settings import OneLineParser
from inest_reward_node.learning.calibrate import recorded_supervision
from inest_reward_node.runtime.model import ModelError, model_folder, read_model_metadata
from scipy import stats

SUMMARY_FILE = "summary.json"
CURVES_FILE = "learning_curves.png"


def reward_supervision(config: dict[str, Any]) -> dict[str, Any]:
    """What the run's reward was fitted on: its labelled negative episodes (the reward model's,
    and the agent's own the run labels in the loop) and the cameras it reads (the model's
    supervision record); the oracle reads the simulator."""
    if config.get("reward", "env") == "env" or not config.get("model"):
        return {"labelled_episodes": None, "cameras": ["simulator state"]}
    record = model_supervision(config["model"])
    in_loop = config.get("label_episodes", 0) * len(config.get("label_at", []))
    if record["labelled_episodes"] is None or not in_loop:
        return record
    return {**record, "labelled_episodes": record["labelled_episodes"] + in_loop}


@functools.cache
def model_supervision(model: str) -> dict[str, Any]:
    """The supervision record of one reward model, read once for all the seeds that share it."""
    try:
        record = recorded_supervision(read_model_metadata(model_folder(model)))
    except ModelError:
        return {"labelled_episodes": None, "cameras": None}  # a model no longer where it was
    return {"labelled_episodes": record["labelled_episodes"], "cameras": record["cameras"]}


def read_run(run_dir: Path) -> dict[str, Any] | None:
    """The run's final result, or its last periodic evaluation while it is still training."""
    config = json.loads((run_dir / "config.json").read_text()) if (run_dir / "config.json").exists() else {}
    row: dict[str, Any] = {"method": run_dir.parent.name, "run": run_dir.name, "seed": config.get("seed")}
    if (run_dir / RESULTS_FILE).exists():
        results = json.loads((run_dir / RESULTS_FILE).read_text())
        final = results["final_evaluation"]
        row.update(
            final=True,
            steps=results["steps"],
            episodes=final["episodes"],
            # runs before the split were evaluated on the layouts their settings were chosen on
            layouts=results.get("layouts", {}).get("final_evaluation", {}).get("name", "legacy"),
            mean_score=final["mean_score"],
            success_rate=final["success_rate"],
            blocks_share=final["blocks_share"],
            **reward_supervision(config),
        )
        if "final_validation" in results:
            row["validation_mean_score"] = results["final_validation"]["mean_score"]
        if "reward_shares" in results:
            row["reward_shares"] = results["reward_shares"]
        if "wall_clock_s" in results:  # runs before the timing was recorded have none
            row["training_s"] = results["wall_clock_s"]["training"]
        if results.get("reward_diagnostics"):  # what the reward paid for, first and last window
            row["reward_diagnostics"] = {
                "first": results["reward_diagnostics"][0],
                "last": results["reward_diagnostics"][-1],
            }
        row["curve"] = results["learning_curve"]
        return row
    histories = [path for path in (run_dir / CHECKPOINT_DIR / HISTORY_FILE, run_dir / HISTORY_FILE) if path.exists()]
    if not histories:
        return None
    curve = json.loads(histories[0].read_text())
    if not curve:
        return None
    row.update(final=False, steps=int(curve[-1][0]), mean_score=curve[-1][1], curve=curve)
    return row


def bootstrap_interval(values: list[float], samples: int = 10_000, seed: int = 0) -> list[float]:
    """95 % bootstrap interval of the mean over seeds."""
    rng = np.random.default_rng(seed)
    data = np.asarray(values, dtype=float)
    means = rng.choice(data, size=(samples, len(data))).mean(axis=1)
    return [float(np.percentile(means, 2.5)), float(np.percentile(means, 97.5))]


def t_interval(values: list[float]) -> list[float]:
    """95 % Student t interval of the mean over seeds. With few seeds it is the wider, more honest
    one: the bootstrap's never leaves the seeds' own range (with 3 seeds it is that range). One
    seed has no spread: its interval is the score itself."""
    data = np.asarray(values, dtype=float)
    mean = float(data.mean())
    if len(data) < 2:
        return [mean, mean]
    half = float(stats.t.ppf(0.975, len(data) - 1) * data.std(ddof=1) / np.sqrt(len(data)))
    return [mean - half, mean + half]


def summarise(root: Path) -> dict[str, Any]:
    rows = [row for path in sorted(root.glob("*/*/config.json")) if (row := read_run(path.parent)) is not None]
    methods: dict[str, Any] = {}
    for method in sorted({row["method"] for row in rows}):
        finals = [row for row in rows if row["method"] == method and row["final"]]
        if not finals:
            continue
        scores = [row["mean_score"] for row in finals]
        methods[method] = {
            "seeds": len(finals),
            "steps": sorted({row["steps"] for row in finals}),
            "mean_score": float(np.mean(scores)),
            "mean_score_ci95": bootstrap_interval(scores),
            "mean_score_t95": t_interval(scores),
            "success_rate": float(np.mean([row["success_rate"] for row in finals])),
            "blocks_share": np.mean([row["blocks_share"] for row in finals], axis=0).tolist(),
            "layouts": sorted({row["layouts"] for row in finals}),
            "labelled_episodes": finals[0]["labelled_episodes"],
            "cameras": finals[0]["cameras"],
        }
        validation = [row["validation_mean_score"] for row in finals if "validation_mean_score" in row]
        if len(validation) == len(finals):
            methods[method]["validation_mean_score"] = float(np.mean(validation))
    return {"runs": rows, "methods": methods}


def plot_curves(
    rows: list[dict[str, Any]],
    path: Path,
    methods: list[str] | None = None,
    title: str = "",
    palette: list[str] | None = None,
) -> None:
    """Per method (`methods`, in that order; default: every method, sorted) the mean evaluation
    score across finished seeds with a band from the lowest to the highest, and each run still
    training dotted in its method's colour. A method's colour is its place in `palette` (default:
    `methods`), so that figures of different subsets of one grid colour each method alike."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    methods = methods if methods is not None else sorted({row["method"] for row in rows})
    palette = palette if palette is not None else methods
    figure, axis = plt.subplots(figsize=(7, 4))
    for method in methods:
        color = f"C{palette.index(method) % 10}" if method in palette else None
        finals = [np.asarray(row["curve"], dtype=float) for row in rows if row["method"] == method and row["final"]]
        if finals:
            length = min(len(curve) for curve in finals)
            steps = finals[0][:length, 0]
            scores = np.stack([curve[:length, 1] for curve in finals])
            axis.plot(steps, scores.mean(axis=0), color=color, label=f"{method} ({len(finals)} seeds)")
            axis.fill_between(steps, scores.min(axis=0), scores.max(axis=0), alpha=0.2, color=color)
        for row in rows:
            if row["method"] == method and not row["final"]:
                curve = np.asarray(row["curve"], dtype=float)
                axis.plot(curve[:, 0], curve[:, 1], ":", color=color, label=f"{method} {row['run']} (still training)")
    axis.set(xlabel="environment steps", ylabel="evaluation score (50 episodes)", ylim=(0, 1.02))
    axis.set_title(f"{title}{': ' if title else ''}mean over seeds; band: lowest to highest seed", fontsize=10)
    if axis.get_legend_handles_labels()[0]:
        axis.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)


def write_summary(root: Path, summary: dict[str, Any], methods: list[str] | None = None) -> None:
    """ROOT/summary.json (the runs without their curves) and ROOT/learning_curves.png (`methods`
    in that order and colours; default: every method, sorted)."""
    found = {row["method"] for row in summary["runs"]}
    shown = [method for method in methods if method in found] if methods else None
    plot_curves(summary["runs"], root / CURVES_FILE, shown, palette=methods)
    runs = [{key: value for key, value in row.items() if key != "curve"} for row in summary["runs"]]
    (root / SUMMARY_FILE).write_text(json.dumps({**summary, "runs": runs}, indent=2) + "\n")


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("root", type=Path, help="folder of <method>/<run>/ training runs")
    args = parser.parse_args(argv)
    if not args.root.is_dir():
        print(f"inest-summarise: {args.root} is not a folder", file=sys.stderr)
        return 2
    summary = summarise(args.root)
    if not summary["runs"]:
        print(f"inest-summarise: no training runs under {args.root}/<method>/<run>/", file=sys.stderr)
        return 2
    write_summary(args.root, summary)
    for method, entry in summary["methods"].items():
        low, high = entry["mean_score_ci95"]
        print(
            f"{method:<24} {entry['seeds']} seeds  score {entry['mean_score']:.3f} [{low:.3f}, {high:.3f}]"
            f"  success {entry['success_rate']:.1%}"
        )
    print(f"wrote {args.root / SUMMARY_FILE} and {CURVES_FILE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
