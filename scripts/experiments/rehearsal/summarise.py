"""The rehearsal's two arms side by side: summary.json and report.md in OUT, from each arm's
reward-quality report (scheme 3) and steps.tsv (seconds per step).
`summarise.py OUT`
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

ARMS = {"robot": "recorded over the graph, imported, labelled +-2 frames", "native": "inest-collect-demos"}


def arm_summary(report: dict) -> dict:
    scheme = report["schemes"]["3"]
    return {
        "heldout_demos": scheme["demos"],
        "within_subtask_spearman_mean": [s["spearman_shaping_within"]["mean"] for s in scheme["per_subtask"]],
        "miss_rate": [s["miss_rate"] for s in scheme["per_subtask"]],
        "false_completion_rate_random": [s["false_completion_rate"]["random"] for s in scheme["per_subtask"]],
        "false_completion_rate_wrong_order": [s["false_completion_rate"]["wrong_order"] for s in scheme["per_subtask"]],
        "false_completion_any": scheme["false_completion_any"],
        "completion_lag_frames_mean": [s["completion_lag_frames"]["mean"] for s in scheme["per_subtask"]],
        "spearman_progress_mean": scheme["spearman_progress"]["mean"],
        "tracker_pass_rate": scheme["tracker_pass_rate"],
        "segmented_by": report["model"]["supervision"]["demonstrations"]["segmented_by"],
        "demonstrations": report["model"]["supervision"]["demonstrations"]["episodes"],
    }


def main() -> None:
    out = Path(sys.argv[1])
    with open(out / "steps.tsv", newline="") as handle:
        steps = {row["step"]: int(row["seconds"]) for row in csv.DictReader(handle, delimiter="\t")}
    arms = {arm: arm_summary(json.loads((out / f"quality-{arm}" / "report.json").read_text())) for arm in ARMS}
    revision = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    summary = {
        "what": "the robot path rehearsed with the simulator as the robot, against the simulator-native pipeline",
        "command": "bash scripts/experiments/rehearsal/run.sh",
        "revision": revision,
        "seeds": "one pretraining seed per arm: an anecdote, not a comparison with an interval",
        "arms": {arm: {"data": ARMS[arm], **values} for arm, values in arms.items()},
        "step_seconds": steps,
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")

    def row(name: str, key: str, digits: int = 2) -> str:
        cells = []
        for arm in ARMS:
            values = arms[arm][key] if isinstance(arms[arm][key], list) else [arms[arm][key]]
            cells.append(" / ".join(f"{value:.{digits}f}" for value in values))
        return f"| {name} | " + " | ".join(cells) + " |"

    lines = [
        "# Rehearsal: the robot path with the simulator as the robot",
        "",
        f"`{summary['command']}` (revision {revision}); models in `model-robot/`, `model-native/`; one",
        "pretraining seed per arm (an anecdote). Scheme 3, 20 held-out simulator demonstrations.",
        "",
        "| | robot path | simulator-native |",
        "|---|---|---|",
        row("within-subtask shaping rho, red / blue / yellow", "within_subtask_spearman_mean"),
        row("missed completions", "miss_rate"),
        row("false completions, random play", "false_completion_rate_random"),
        row("false completions, wrong order", "false_completion_rate_wrong_order"),
        row("completion lag (frames)", "completion_lag_frames_mean", 1),
        row("rho with progress", "spearman_progress_mean"),
        "",
        "| step | seconds |",
        "|---|---|",
        *(f"| {step} | {seconds} |" for step, seconds in steps.items()),
    ]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
