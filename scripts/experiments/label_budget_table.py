"""The Markdown tables of docs/reports/robot-reward.md from the label-budget reports: per labelling budget
and stage-evidence setting, red / blue / yellow within-subtask shaping rho (own tracker), misses,
false completions on random and wrong-order play, and those not merely early; for the labelling
path (labelling_path_timing.sh, folders with a timings.json), per path the label rows written and
the seconds of each step before the same figures.

    python scripts/experiments/label_budget_table.py results/robot-reward/label-budget/selection
    python scripts/experiments/label_budget_table.py results/robot-reward/labelling-path
    python scripts/experiments/label_budget_table.py results/robot-reward/exploit-check
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

BUDGETS = {"labels0": 0, "labels10": 10, "labels20": 20, "labels50": 50}


def triple(values: list[float], spec: str, scale: float = 1.0) -> str:
    return " / ".join(format(scale * value, spec) for value in values)


FIGURES = (
    "shaping ρ red / blue / yellow | missed | false: random | false: wrong order "  # noqa: RUF001
    "| not early: random | not early: wrong order"
)
CLIPS = " | false: the policy's rollouts"  # reports made with --clips
TIMED_STEPS = ("record", "template", "label", "recalibrate", "check")


def has_clips(report: Path) -> bool:
    return "clips" in json.loads(report.read_text())["schemes"]["3"]["per_subtask"][0]["false_completion_rate"]


def figures(report: Path) -> list[str]:
    subtasks = json.loads(report.read_text())["schemes"]["3"]["per_subtask"]
    rho = triple([sub["spearman_shaping_within"]["median"] for sub in subtasks], ".2f")
    missed = triple([sub["miss_rate"] for sub in subtasks], ".3g", 100)
    cells = [rho, f"{missed} %"]
    for rates in ("false_completion_rate", "false_not_early_rate"):
        for kind in ("random", "wrong_order"):
            cells.append(f"{triple([sub[rates][kind] for sub in subtasks], '.3g', 100)} %")
    if "clips" in subtasks[0]["false_completion_rate"]:
        cells.append(f"{triple([sub['false_completion_rate']['clips'] for sub in subtasks], '.3g', 100)} %")
    return cells


def budget_row(report: Path) -> str:
    budget, _, setting = report.parent.name.partition("-")
    return "| " + " | ".join([f"{BUDGETS[budget]}", setting, *figures(report)]) + " |"


def path_row(report: Path) -> str:
    timings = json.loads((report.parent / "timings.json").read_text())
    seconds = " / ".join(f"{timings['seconds'][step]:.1f}" for step in TIMED_STEPS)
    cells = [report.parent.name, str(timings["label_rows"]), "yes" if timings["clips_raise_thresholds"] else "no"]
    return "| " + " | ".join([*cells, seconds, *figures(report)]) + " |"


def main(folder: str) -> None:
    reports = sorted(Path(folder).glob("*/report.json"))
    timed = [report for report in reports if (report.parent / "timings.json").exists()]
    if timed:
        print(f"| episodes | label rows | they raise the thresholds | seconds: {' / '.join(TIMED_STEPS)} | {FIGURES} |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for report in timed:
            print(path_row(report))
        return
    clips = all(has_clips(report) for report in reports)
    print(f"| labelled episodes | stage evidence | {FIGURES}{CLIPS if clips else ''} |")
    print("|---|---|---|---|---|---|---|---|" + ("---|" if clips else ""))
    for report in sorted(reports, key=lambda p: (BUDGETS[p.parent.name.split("-")[0]], p)):
        print(budget_row(report))


if __name__ == "__main__":
    main(sys.argv[1])
