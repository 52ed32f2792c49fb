"""What the intrinsic bonus did: each WITH:WITHOUT pair of method folders (seed*/results.json,
the same reward with and without the bonus) compared seed for seed and window by window.

Per pair: each side's final scores, the difference of the means with a 95 % Welch t interval
and its p-value (with 3 seeds a bootstrap interval is only the seeds' range); then, from the
runs' reward diagnostics, when the two sides part (blocks in order at episode end, mean over
seeds, per training window), the bonus's share of the reward paid, and the stage's claims of
unplaced blocks; with runs that recorded them, the bonus paid per step on steps of a falsely
claimed stage against the others (whether the bonus pays for a false claim). Writes --out.

    python scripts/experiments/bonus_effect.py results/long-horizon/inest3-embedding:results/long-horizon/inest3-none \
        --out results/bonus/bonus-effect-legacy.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

# diagnostics compared window by window (diagnostics.py), when the runs recorded them
WINDOW_KEYS = (
    "final_progress_mean",
    "intrinsic_share",
    "intrinsic_per_step",
    "reward_per_step",
    "unearned_completion_rate",
    "unplaced_claim_rate",
    "unearned_step_per_step",
    "intrinsic_unearned_per_step",
    "intrinsic_earned_per_step",
)


def runs(folder: Path) -> list[dict[str, Any]]:
    found = [json.loads(path.read_text()) for path in sorted(folder.glob("seed*/results.json"))]
    if not found:
        raise ValueError(f"no seed*/results.json under {folder}")
    return found


def with_share(window: dict[str, float]) -> dict[str, float]:
    """The window with the bonus's share of the reward's parts, derived where a run predates it."""
    parts = ("shaping_per_step", "bonus_per_step", "intrinsic_per_step")
    if "intrinsic_share" in window or not all(part in window for part in parts):
        return window
    total = sum(abs(window[part]) for part in parts)
    return {**window, "intrinsic_share": abs(window["intrinsic_per_step"]) / total if total else 0.0}


def window_means(results: list[dict[str, Any]]) -> list[dict[str, float]]:
    """Per training window (the windows all seeds share), each key's mean over seeds."""
    count = min(len(result["reward_diagnostics"]) for result in results)
    means = []
    for index in range(count):
        windows = [with_share(result["reward_diagnostics"][index]) for result in results]
        row: dict[str, float] = {"steps": windows[0]["steps"]}
        for key in WINDOW_KEYS:
            values = [window[key] for window in windows if key in window]
            if len(values) == len(windows):
                row[key] = float(np.mean(values))
        means.append(row)
    return means


def score_difference(with_bonus: list[float], without: list[float]) -> dict[str, Any]:
    """Mean difference (with - without), its 95 % Welch t interval and the test's p-value."""
    a, b = np.asarray(with_bonus), np.asarray(without)
    difference = float(a.mean() - b.mean())
    variance_a, variance_b = a.var(ddof=1) / len(a), b.var(ddof=1) / len(b)
    error = float(np.sqrt(variance_a + variance_b))
    freedom = (variance_a + variance_b) ** 2 / (variance_a**2 / (len(a) - 1) + variance_b**2 / (len(b) - 1))
    half = float(stats.t.ppf(0.975, freedom) * error)
    p_value = float(stats.ttest_ind(a, b, equal_var=False).pvalue)
    return {"difference": difference, "t95": [difference - half, difference + half], "p_value": p_value}


def parting_step(with_rows: list[dict[str, float]], without_rows: list[dict[str, float]]) -> int | None:
    """The first window from which the side without the bonus places more blocks in every later window."""
    gaps = [
        (row["steps"], other["final_progress_mean"] - row["final_progress_mean"])
        for row, other in zip(with_rows, without_rows, strict=False)
    ]
    for index, (steps, _) in enumerate(gaps):
        if all(gap > 0 for _, gap in gaps[index:]):
            return int(steps)
    return None


def compare(with_folder: Path, without_folder: Path) -> dict[str, Any]:
    with_runs, without_runs = runs(with_folder), runs(without_folder)
    scores = {
        side: [result["final_evaluation"]["mean_score"] for result in found]
        for side, found in (("with", with_runs), ("without", without_runs))
    }
    with_rows, without_rows = window_means(with_runs), window_means(without_runs)
    record: dict[str, Any] = {
        "with": str(with_folder),
        "without": str(without_folder),
        "scores": scores,
        "layouts": sorted(
            {result.get("layouts", {}).get("final_evaluation", {}).get("name", "legacy") for result in with_runs}
        ),
        "mean_difference": score_difference(scores["with"], scores["without"]),
        "blocks_part_from_step": parting_step(with_rows, without_rows),
        "windows": {"with": with_rows, "without": without_rows},
    }
    late = with_rows[len(with_rows) // 2 :]  # the second half of training
    for key in ("intrinsic_share", "intrinsic_unearned_per_step", "intrinsic_earned_per_step"):
        if all(key in row for row in late):
            record[f"{key}_second_half"] = float(np.mean([row[key] for row in late]))
    return record


def describe(record: dict[str, Any]) -> str:
    difference = record["mean_difference"]
    low, high = difference["t95"]
    lines = [
        f"{record['with']} against {record['without']} ({', '.join(record['layouts'])} layouts)",
        f"  scores with {np.round(record['scores']['with'], 3).tolist()}, "
        f"without {np.round(record['scores']['without'], 3).tolist()}",
        f"  difference {difference['difference']:+.3f}, 95 % Welch t [{low:+.3f}, {high:+.3f}], "
        f"p = {difference['p_value']:.2f}",
        f"  without the bonus, more blocks in order in every later window from step {record['blocks_part_from_step']}"
        if record["blocks_part_from_step"] is not None
        else "  without the bonus, never more blocks in order in every later window",
    ]
    for key in ("intrinsic_share", "intrinsic_unearned_per_step", "intrinsic_earned_per_step"):
        if f"{key}_second_half" in record:
            lines.append(f"  {key}, second half of training: {record[f'{key}_second_half']:.4g}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("pairs", nargs="+", help="WITH:WITHOUT method folders")
    parser.add_argument("--out", type=Path, required=True, help="the JSON file to write")
    args = parser.parse_args(argv)
    try:
        records = []
        for pair in args.pairs:
            with_folder, separator, without_folder = pair.partition(":")
            if not separator:
                raise ValueError(f"{pair}: give WITH:WITHOUT")
            records.append(compare(Path(with_folder), Path(without_folder)))
    except (ValueError, KeyError) as error:
        print(f"bonus_effect: {error}", file=sys.stderr)
        return 2
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"command": " ".join(sys.argv), "pairs": records}, indent=2) + "\n")
    print("\n\n".join(describe(record) for record in records))
    return 0


if __name__ == "__main__":
    sys.exit(main())
