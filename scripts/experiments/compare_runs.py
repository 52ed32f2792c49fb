"""Compare the JSON outputs of two behaviour-check pipelines (behaviour_check.sh): every number
equal, apart from keys that record time, paths or versions. Prints a JSON verdict."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any

FILES = ("pretrain/model/model.json", "quality/report.json", "train/results.json")
IGNORED = {"path", "dataset", "model", "out", "seconds", "wall_s", "steps_per_s", "time", "elapsed_s", "sha256"}


def differences(a: Any, b: Any, where: str = "") -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        found = [f"{where}/{key}: only on one side" for key in sorted(set(a) ^ set(b)) if key not in IGNORED]
        for key in sorted(set(a) & set(b)):
            if key not in IGNORED and not any(word in key for word in ("time", "speed", "per_s")):
                found += differences(a[key], b[key], f"{where}/{key}")
        return found
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{where}: {len(a)} vs {len(b)} items"]
        return [line for x, y in zip(a, b, strict=True) for line in differences(x, y, f"{where}[]")]
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return []
    return [] if a == b else [f"{where}: {a!r} vs {b!r}"]


def main() -> None:
    base, head = (Path(arg) for arg in sys.argv[1:3])
    verdict = {}
    for name in FILES:
        found = differences(json.loads((base / name).read_text()), json.loads((head / name).read_text()))
        verdict[name] = {"identical": not found, "differences": found[:20]}
    print(json.dumps(verdict, indent=2))


if __name__ == "__main__":
    main()
