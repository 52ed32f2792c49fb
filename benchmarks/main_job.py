"""The main job's time to a trained agent on screen: `bash scripts/run_main.sh` from the end of the
set-up (its first `==` line) to the first episode line in which the learned subtask reached
"done" and the trained policy's score table, and to the end of the fresh agent's training.

Prints one JSON object. Target: trained agent completing all three subtasks within 300 s of the
set-up's end on an idle 2-core machine. Run it after the set-up has run once (its own time
depends on the network, not on this project).
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGET_S = 300.0


def main() -> int:
    start = time.monotonic()
    marks: dict[str, float] = {}
    process = subprocess.Popen(
        ["bash", str(ROOT / "scripts" / "run_main.sh")], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    assert process.stdout is not None
    for line in process.stdout:
        now = time.monotonic() - start
        if line.startswith("==") and "setup_done" not in marks:
            marks["setup_done"] = now
        elif "done at" in line and "first_all_three_s" not in marks:
            marks["first_all_three_s"] = now
        elif "over the graph" in line and "trained_table_s" not in marks:
            marks["trained_table_s"] = now
    status = process.wait()
    if status or "setup_done" not in marks or "first_all_three_s" not in marks:
        print(f"main_job: run_main.sh exited {status}; seen: {sorted(marks)}", file=sys.stderr)
        return 1
    setup = marks["setup_done"]
    result = {
        "setup_s": round(setup, 1),
        "all_three_subtasks_after_setup_s": round(marks["first_all_three_s"] - setup, 1),
        "trained_policy_table_after_setup_s": round(marks["trained_table_s"] - setup, 1),
        "whole_job_after_setup_s": round(time.monotonic() - start - setup, 1),
        "target_s": TARGET_S,
        "meets_target": marks["first_all_three_s"] - setup <= TARGET_S,
        "cpus": os.cpu_count(),
        "machine": platform.machine(),
    }
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
