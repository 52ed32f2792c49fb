"""The locked test set's ledger: every scoring of a run on the locked layouts, once per run, with
the release it was for and the commit of the code that scored it.

Why: a test set that every run is scored on while the work goes on informs its direction; one that
is looked at once per result, and says when and by what code, still measures what a release
claims. The ledger is a JSON file in the repository (by default `results/locked-test/ledger.json`
of the git repository the command runs in, whatever folder in it); the commit it records is that
repository's HEAD, which must hold every tracked change but the ledger's own (commit first, then
score; files git does not track are not looked at).
"""

from __future__ import annotations

import json
import subprocess
import time
from pathlib import Path
from typing import Any

from inest_common.files import write_atomic

LEDGER = Path("results/locked-test/ledger.json")
FORMAT = "inest-locked-test-ledger"


class LedgerError(ValueError):
    """The locked set cannot be scored now; the message says why."""


def _git(folder: Path, *args: str) -> str:
    try:
        done = subprocess.run(["git", "-C", str(folder), *args], capture_output=True, text=True, check=True)
    except (OSError, subprocess.CalledProcessError) as error:
        raise LedgerError(f"{folder} is not in a git repository the locked scoring can record ({error})") from None
    return done.stdout


def repository(ledger: Path) -> Path:
    """The top folder of the git repository the ledger is (to be) written in."""
    folder = next(parent for parent in [ledger.parent, *ledger.parent.parents] if parent.is_dir())
    return Path(_git(folder, "rev-parse", "--show-toplevel").strip()).resolve()


def in_repository(path: Path, top: Path) -> str:
    """`path` relative to the repository when inside it (how the ledger names runs), else absolute."""
    resolved = path.resolve()
    return resolved.relative_to(top).as_posix() if resolved.is_relative_to(top) else resolved.as_posix()


def scoring_commit(ledger: Path) -> str:
    """HEAD of the repository that holds the ledger; refused while anything tracked but the ledger has changed."""
    top = repository(ledger)
    own = in_repository(ledger, top)
    status = _git(top, "status", "--porcelain", "-z", "--untracked-files=no").split("\0")
    changed = [entry[3:] for entry in status if len(entry) > 3 and entry[3:] != own]
    if changed:
        raise LedgerError(f"commit first: the ledger records the commit that scored, and {changed[0]} has changes")
    return _git(top, "rev-parse", "HEAD").strip()


def default_ledger() -> Path:
    """LEDGER in the git repository of the working folder, from any folder in it."""
    return repository(Path.cwd() / "ledger") / LEDGER


def check_distinct(names: list[str]) -> None:
    if len(set(names)) != len(names):
        raise LedgerError("a run is named twice: the locked set is scored once per run")


def read_ledger(ledger: Path) -> dict[str, Any]:
    if not ledger.exists():
        return {"format": FORMAT, "entries": []}
    try:
        data = json.loads(ledger.read_text())
    except (OSError, ValueError) as error:
        raise LedgerError(f"{ledger}: not a locked-test ledger ({error})") from None
    if data.get("format") != FORMAT:
        raise LedgerError(f"{ledger}: not a locked-test ledger")
    return data


def check_unscored(ledger: dict[str, Any], run: str) -> None:
    for entry in ledger["entries"]:
        if entry["run"] == run:
            raise LedgerError(
                f"{run} was scored on the locked test layouts already (release {entry['release']}, "
                f"commit {entry['commit'][:12]}): the locked set is scored once per run"
            )


def record(ledger_path: Path, ledger: dict[str, Any], run: str, release: str, commit: str, scored: dict) -> None:
    """Append one scoring and write the ledger (atomically: a killed write never loses the others)."""
    stamp = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    ledger["entries"].append({"release": release, "run": run, "commit": commit, "scored_at": stamp, **scored})
    write_atomic(ledger_path, lambda path: path.write_text(json.dumps(ledger, indent=2) + "\n"))
