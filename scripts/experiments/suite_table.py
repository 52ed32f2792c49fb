"""The exploit-suite tables of docs/reports/exploit-suite.md from inest-exploit-suite's JSON files:
claims (the default) or, with --pay, what the reward pays for per frame. A file named suite*.json
is named by its folder (results/robot-reward-v2/scene-labels20/suite-retract10.json:
`scene-labels20-retract10`).

.venv/bin/python scripts/experiments/suite_table.py [--pay] results/exploit-suite/scores/*.json
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


def percents(values: list[float | None]) -> str:
    return " / ".join("-" if value is None else f"{100 * value:.1f}" for value in values) + " %"


def percent(value: float) -> str:
    return f"{100 * value:.1f} %"


def name(path: Path) -> str:
    return path.parent.name + path.stem[len("suite") :] if path.stem.startswith("suite") else path.stem


def main(arguments: list[str]) -> None:
    pay = "--pay" in arguments
    paths = [Path(argument) for argument in arguments if argument != "--pay"]
    if pay:
        print(
            "| reward | unplaced claim, any block | frames paid for a block not in the goal | frames paid short "
            "| episodes ending overclaimed | misses red / blue / yellow | false: wrong order |"
        )
    else:
        print(
            "| reward | unplaced claim, any block | unplaced claims red / blue / yellow | early claims | misses "
            "| false: random play | false: wrong order |"
        )
    print("|---|---|---|---|---|---|---|")
    for path in paths:
        report = json.loads(path.read_text())
        row = report["schemes"]["3"]
        subtasks = row["per_subtask"]
        play = report.get("play", {}).get("false_completion_rate", {}).get("3", {})
        cells = [percent(row["unplaced_claim_any"])]
        if pay:
            cells += [percent(row[key]) for key in ("overpaid_frame_share", "underpaid_frame_share")]
            cells += [percent(row["ends_overclaimed_rate"]), percents([sub["miss_rate"] for sub in subtasks])]
            cells.append(percents(play["wrong_order"]) if "wrong_order" in play else "-")
        else:
            for key in ("unplaced_claim_rate", "early_claim_rate", "miss_rate"):
                cells.append(percents([sub[key] for sub in subtasks]))
            cells += [percents(play[kind]) if kind in play else "-" for kind in ("random", "wrong_order")]
        print(f"| `{name(path)}` | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main(sys.argv[1:])
