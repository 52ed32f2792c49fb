"""The rehearsal's two arms side by side, over pretraining seeds: summary.json and report.md in
OUT, from each model's reward-quality report (scheme 3) and steps.tsv (seconds per step).
Per arm the mean over seeds with its 95 % Student t and bootstrap intervals; the difference robot
minus native with a Welch t interval and a bootstrap one (seeds resampled within each arm).
`summarise.py OUT`
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
from inest_experiments.summary import bootstrap_interval, t_interval
from scipy import stats

ARMS = {"robot": "recorded over the graph, imported, labelled +-2 frames", "native": "inest-collect-demos"}


def subtask_mean(key: str, inner: str | None = None):
    """The mean over the 3 subtasks of a per-subtask figure of a quality report."""
    return lambda s: np.mean([p[key][inner] if inner else p[key] for p in s["per_subtask"]])


METRICS = {  # name -> (what, per-seed value from a scheme-3 quality report)
    "within_subtask_rho": (
        "within-subtask shaping rho, mean of the 3 subtasks",
        subtask_mean("spearman_shaping_within", "mean"),
    ),
    "miss_rate": ("missed completions, mean of the 3 subtasks", subtask_mean("miss_rate")),
    "false_any_random": ("random-play episodes with a false completion", lambda s: s["false_completion_any"]["random"]),
    "false_any_wrong_order": (
        "wrong-order episodes with a false completion",
        lambda s: s["false_completion_any"]["wrong_order"],
    ),
    "rho_progress": ("rho of the reward with progress", lambda s: s["spearman_progress"]["mean"]),
}


def welch_interval(a: list[float], b: list[float]) -> list[float]:
    """95 % Welch t interval of mean(a) - mean(b)."""
    va, vb = np.var(a, ddof=1) / len(a), np.var(b, ddof=1) / len(b)
    freedom = (va + vb) ** 2 / (va**2 / (len(a) - 1) + vb**2 / (len(b) - 1)) if va + vb > 0 else 1.0
    half = float(stats.t.ppf(0.975, freedom) * np.sqrt(va + vb))
    difference = float(np.mean(a) - np.mean(b))
    return [difference - half, difference + half]


def bootstrap_difference(a: list[float], b: list[float], samples: int = 10_000) -> list[float]:
    rng = np.random.default_rng(0)
    means = rng.choice(a, (samples, len(a))).mean(1) - rng.choice(b, (samples, len(b))).mean(1)
    return [float(np.percentile(means, 2.5)), float(np.percentile(means, 97.5))]


def main() -> None:
    out = Path(sys.argv[1])
    with open(out / "steps.tsv", newline="") as handle:
        steps = {row["step"]: int(row["seconds"]) for row in csv.DictReader(handle, delimiter="\t")}
    per_seed: dict[str, dict[str, list[float]]] = {arm: {name: [] for name in METRICS} for arm in ARMS}
    seeds: dict[str, list[int]] = {arm: [] for arm in ARMS}
    for arm in ARMS:
        for folder in sorted(out.glob(f"quality-{arm}-seed*")):
            scheme = json.loads((folder / "report.json").read_text())["schemes"]["3"]
            seeds[arm].append(int(folder.name.rsplit("seed", 1)[1]))
            for name, (_, value) in METRICS.items():
                per_seed[arm][name].append(float(value(scheme)))
    arms = {
        arm: {
            "data": ARMS[arm],
            "seeds": seeds[arm],
            **{
                name: {
                    "per_seed": v,
                    "mean": float(np.mean(v)),
                    "t95": t_interval(v),
                    "bootstrap95": bootstrap_interval(v),
                }
                for name, v in per_seed[arm].items()
            },
        }
        for arm in ARMS
    }
    differences = {
        name: {
            "mean": float(np.mean(per_seed["robot"][name]) - np.mean(per_seed["native"][name])),
            "welch_t95": welch_interval(per_seed["robot"][name], per_seed["native"][name]),
            "bootstrap95": bootstrap_difference(per_seed["robot"][name], per_seed["native"][name]),
        }
        for name in METRICS
    }
    revision = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    summary = {
        "what": "the robot path rehearsed with the simulator as the robot, against the simulator-native pipeline",
        "command": "bash scripts/experiments/rehearsal/run.sh",
        "revision": revision,
        "heldout": "20 simulator demonstrations, seeds from 5000 (validation split of runs/rehearsal/heldout)",
        "metrics": {name: what for name, (what, _) in METRICS.items()},
        "arms": arms,
        "robot_minus_native": differences,
        "step_seconds": steps,
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")

    def cell(stat: dict) -> str:
        low, high = stat.get("t95", stat.get("welch_t95"))
        return f"{stat['mean']:.2f} [{low:.2f}, {high:.2f}]"

    lines = [
        "# Rehearsal: the robot path with the simulator as the robot",
        "",
        f"`{summary['command']}` (revision {revision}); seeds {seeds['robot']} per arm; scheme 3 on 20",
        "held-out simulator demonstrations; mean over seeds [95 % t interval].",
        "",
        "| metric | robot path | simulator-native | robot - native [Welch t] |",
        "|---|---|---|---|",
        *(
            f"| {METRICS[name][0]} | {cell(arms['robot'][name])} | {cell(arms['native'][name])} | "
            f"{cell(differences[name])} |"
            for name in METRICS
        ),
        "",
        "| step | seconds |",
        "|---|---|",
        *(f"| {step} | {seconds} |" for step, seconds in steps.items()),
    ]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
