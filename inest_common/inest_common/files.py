"""File helpers shared by the packages (datasets here, the reward model and pretraining runs in
inest_reward_node, training checkpoints in inest_agent_node): atomic writes, sha256 of a file,
JSON documents that declare their format and version, and paths in JSON made relative to the
checkout, so that results read the same in any checkout. Standard library only."""

from __future__ import annotations

import errno
import hashlib
import json
import os
import pickle
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

T = TypeVar("T")
# what reading back a damaged or missing file raises: a truncated pickle (UnpicklingError, EOFError),
# a damaged zip or npz, corrupt JSON (ValueError), torch refusing its contents (RuntimeError), a
# stable-baselines3 model.zip without its data (it asserts)
UNREADABLE = (
    OSError, EOFError, pickle.UnpicklingError, zipfile.BadZipFile, ValueError, KeyError, RuntimeError, AssertionError
)  # fmt: skip


# a node's exit status when its disk refused more bytes (full, over quota, over a file size
# limit): a restart would fail the same way, so the launcher does not restart it
NO_SPACE_EXIT = 28  # ENOSPC's number
_NO_SPACE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG})


class NoSpaceError(Exception):
    """The disk refused a run file; the message says what was being written and what was kept."""


def out_of_space(error: BaseException | None) -> bool:
    """Whether `error` (or an error it was raised from) is the disk refusing more bytes."""
    while error is not None:
        if isinstance(error, NoSpaceError) or (isinstance(error, OSError) and error.errno in _NO_SPACE_ERRNOS):
            return True
        error = error.__cause__ or error.__context__
    return False


def no_space_message(error: BaseException) -> str:
    """One line for an out-of-space failure (out_of_space(error) holds)."""
    return str(error) if isinstance(error, NoSpaceError) else f"out of disk space: {error}"


class RunFileError(ValueError):
    """A run's saved file cannot be read back; the message names it (a ValueError: a bad configuration)."""


def read_run_file(path: Path, read: Callable[[Path], T], library_errors: tuple[type[Exception], ...] = ()) -> T:
    """`read(path)`, with any failure to read or parse the file (UNREADABLE, or the reading
    library's own `library_errors`, such as safetensors') turned into one RunFileError naming it."""
    try:
        return read(path)
    except (*UNREADABLE, *library_errors) as reason:
        first_line = str(reason).strip().splitlines()[0] if str(reason).strip() else type(reason).__name__
        raise RunFileError(f"cannot read {path}: {first_line}") from reason


def checkout_relative(value: Any, root: Path) -> Any:
    """`value` (parsed JSON) with every string naming a path under `root` made relative to it."""
    if isinstance(value, str):
        return value.removeprefix(f"{root}/")
    if isinstance(value, list):
        return [checkout_relative(item, root) for item in value]
    if isinstance(value, dict):
        return {key: checkout_relative(item, root) for key, item in value.items()}
    return value


def read_json(path: Path) -> Any:
    return json.loads(path.read_text())


def sha256_of(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for chunk in iter(lambda: handle.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def write_atomic(path: Path, write: Any) -> None:
    """Call `write(temporary_path)`, then move the result into place in one rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(f".{path.name}.tmp")
    try:
        write(temporary)
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)


def read_versioned_json(
    path: Path, fmt: str, version: int | tuple[int, ...], what: str, error: type[Exception]
) -> dict[str, Any]:
    """Read a JSON document that declares its format (one of the `version`s it may be written in);
    `error` names the problem if it does not parse or match."""
    if not path.is_file():
        raise error(f"no {what} at {path.parent}: {path.name} is missing")
    try:
        document = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as reason:
        raise error(f"corrupt {path}: {reason}") from reason
    versions = version if isinstance(version, tuple) else (version,)
    if (
        not isinstance(document, dict)
        or document.get("format") != fmt
        or document.get("format_version") not in versions
    ):
        raise error(f"{path} is not an {fmt} v{'/'.join(map(str, versions))} {what}")
    return document
