"""Gather representation_probe.sh's variants into one JSON object on stdout: per variant its encoder
and training settings, and per subtask the within-subtask Spearman of the
embedding distance and of the shaping (with its own tracker and with the true stage), the tracker's
lag, misses and false completions.
`representation_summary.py OUT` (the folder representation_probe.sh wrote).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any


def subtask_rows(report: dict[str, Any]) -> list[dict[str, Any]]:
    return report["schemes"]["3"]["per_subtask"]


def summarise(variant: Path) -> dict[str, Any]:
    config = json.loads((variant / "config.json").read_text())
    tracker = json.loads((variant / "quality-tracker" / "report.json").read_text())
    privileged = json.loads((variant / "quality-privileged" / "report.json").read_text())
    per_subtask = []
    for own, true in zip(subtask_rows(tracker), subtask_rows(privileged), strict=True):
        per_subtask.append(
            {
                "subtask": own["name"],
                "embedding_rho": round(own["spearman_embedding_within"]["median"], 3),
                "shaping_rho_own_tracker": round(own["spearman_shaping_within"]["median"], 3),
                "shaping_rho_true_stage": round(true["spearman_shaping_within"]["median"], 3),
                "lag_frames": own["completion_lag_frames"]["median"],
                "miss_rate": own["miss_rate"],
                "false_completion_rate": own["false_completion_rate"],
            }
        )
    return {
        "encoder": config["encoder"],
        "iterations": config["iterations"],
        "augment": config["augment"],
        "device": config.get("device", "cpu"),
        "spearman_progress_total_incl_bonus": round(
            tracker["schemes"]["3"]["spearman_progress_total_incl_bonus"]["median"], 3
        ),
        "per_subtask": per_subtask,
    }


def main() -> None:
    root = Path(sys.argv[1])
    variants = {
        folder.name: summarise(folder)
        for folder in sorted(path.parent.parent for path in root.glob("*/quality-privileged/report.json"))
        if (folder / "quality-tracker" / "report.json").is_file()
    }
    print(json.dumps({"experiment": "representation_probe", "variants": variants}, indent=1))


if __name__ == "__main__":
    main()
