"""The Markdown table of docs/robot-reward.md from the label-budget reports: per labelling budget
and stage-evidence setting, red / blue / yellow within-subtask shaping rho (own tracker), misses,
false completions on random and wrong-order play, and those not merely early.

    python scripts/experiments/label_budget_table.py results/robot-reward/label-budget/selection
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

BUDGETS = {"labels0": 0, "labels10": 10, "labels50": 50}


def triple(values: list[float], spec: str, scale: float = 1.0) -> str:
    return " / ".join(format(scale * value, spec) for value in values)


def row(report: Path) -> str:
    budget, _, setting = report.parent.name.partition("-")
    subtasks = json.loads(report.read_text())["schemes"]["3"]["per_subtask"]
    rho = triple([sub["spearman_shaping_within"]["median"] for sub in subtasks], ".2f")
    missed = triple([sub["miss_rate"] for sub in subtasks], "g", 100)
    cells = [f"{BUDGETS[budget]}", setting, rho, f"{missed} %"]
    for rates in ("false_completion_rate", "false_not_early_rate"):
        for kind in ("random", "wrong_order"):
            cells.append(f"{triple([sub[rates][kind] for sub in subtasks], 'g', 100)} %")
    return "| " + " | ".join(cells) + " |"


def main(folder: str) -> None:
    print(
        "| labelled episodes | stage evidence | shaping ρ red / blue / yellow | missed | false: random "  # noqa: RUF001
        "| false: wrong order | not early: random | not early: wrong order |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for report in sorted(Path(folder).glob("*/report.json"), key=lambda p: (BUDGETS[p.parent.name.split("-")[0]], p)):
        print(row(report))


if __name__ == "__main__":
    main(sys.argv[1])
