"""The exploit-suite table of docs/reports/exploit-suite.md from inest-exploit-suite's JSON files.

.venv/bin/python scripts/experiments/suite_table.py results/exploit-suite/scores/*.json
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


def percents(values: list[float | None]) -> str:
    return " / ".join("-" if value is None else f"{100 * value:.1f}" for value in values) + " %"


def main(paths: list[str]) -> None:
    print(
        "| reward | unplaced claim, any block | unplaced claims red / blue / yellow | early claims | misses "
        "| false: random play | false: wrong order |"
    )
    print("|---|---|---|---|---|---|---|")
    for path in paths:
        report = json.loads(Path(path).read_text())
        row = report["schemes"]["3"]
        subtasks = row["per_subtask"]
        cells = [f"{100 * row['unplaced_claim_any']:.1f} %"]
        for key in ("unplaced_claim_rate", "early_claim_rate", "miss_rate"):
            cells.append(percents([sub[key] for sub in subtasks]))
        play = report.get("play", {}).get("false_completion_rate", {}).get("3", {})
        cells += [percents(play[kind]) if kind in play else "-" for kind in ("random", "wrong_order")]
        print(f"| `{Path(path).stem}` | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main(sys.argv[1:])
