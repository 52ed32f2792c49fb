"""Run folders shared by the training commands: the full config is written next to the results,
and a resumed run must keep every setting that changes what it trains."""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from inest_common.files import read_json, read_run_file

CONFIG_FILE = "config.json"


def merge_settings(base: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    """`overrides` on top of `base`, nested mappings (a config's sub-configs) merged key by key."""
    merged = dict(base)
    for key, value in overrides.items():
        merged[key] = {**(merged.get(key) or {}), **value} if isinstance(value, dict) else value
    return merged


def check_run_dir(
    run_dir: Path,
    settings: dict[str, Any],
    resume: bool,
    must_match: Iterable[str],
    defaults: dict[str, Any] | None = None,
) -> None:
    """Refuse to overwrite a run unless resuming it unchanged, writing nothing (a launcher checks
    its agent's run folder before any node starts). A setting the saved run lacks (added since)
    counts as its value in `defaults`."""
    path = run_dir / CONFIG_FILE
    if not path.exists():
        return
    if not resume:
        raise FileExistsError(f"{run_dir} already holds a run; pass --resume to continue it or pick --out")
    as_json = json.loads(json.dumps({"settings": settings, "defaults": defaults or {}}))  # tuples -> lists
    saved = merge_settings(as_json["defaults"], read_run_file(path, read_json))
    differing = sorted(key for key in must_match if saved.get(key) != as_json["settings"][key])
    if differing:
        raise ValueError(f"cannot resume {run_dir}: settings differ from the saved run: {', '.join(differing)}")


def prepare_run_dir(
    run_dir: Path,
    settings: dict[str, Any],
    resume: bool,
    must_match: Iterable[str],
    defaults: dict[str, Any] | None = None,
) -> None:
    """`check_run_dir`, then create `run_dir` and write config.json."""
    check_run_dir(run_dir, settings, resume, must_match, defaults)
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / CONFIG_FILE).write_text(json.dumps(settings, indent=2) + "\n")
