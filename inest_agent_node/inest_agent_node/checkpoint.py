"""A training checkpoint as one unit: written whole into a new folder, its manifest last, then
renamed into place; read only whole.

Why: a checkpoint whose files were replaced one at a time could pair an old model with a newer
replay buffer when the disk filled between them, and every resume then went on from that mix.
Here the folder `checkpoint/` always holds one checkpoint: `.checkpoint.partial/` is written
(and flushed) first, the old folder steps aside as `.checkpoint.previous/`, the new one takes its
name and the old one is deleted. A crash between the two renames leaves `.checkpoint.previous/`,
which is then the checkpoint. The manifest (checkpoint.json: step, training seconds, each file's
size and sha256) is written last, so a folder without it is not a checkpoint, and a file whose
size or content differs from the manifest's makes the checkpoint unreadable rather than half read
(a flipped byte in the learner's weights would otherwise train on, or fail far from its cause).
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

from inest_common.files import NoSpaceError, RunFileError, out_of_space, read_json, read_run_file, sha256_of

CHECKPOINT_DIR = "checkpoint"
# the manifest: the checkpoint's step, its size in bytes, the training seconds up to it
# (periodic evaluations included, summed over resumes: the time between a run's last checkpoint
# and its kill is lost with the steps it trained) and the size of each of its files
CHECKPOINT_INFO = "checkpoint.json"
PARTIAL_DIR = ".checkpoint.partial"
PREVIOUS_DIR = ".checkpoint.previous"


def checkpoint_folder(run_dir: Path) -> Path | None:
    """The folder of the run's checkpoint, None if it has none."""
    for name in (CHECKPOINT_DIR, PREVIOUS_DIR):
        if (run_dir / name / CHECKPOINT_INFO).is_file():
            return run_dir / name
    return None


def read_manifest(folder: Path) -> dict[str, Any]:
    """The checkpoint's manifest, once every file it lists is there with its size and sha256."""
    manifest = read_run_file(folder / CHECKPOINT_INFO, read_json)
    for name, size in manifest.get("files", {}).items():
        path = folder / name
        if not path.is_file() or path.stat().st_size != size:
            found = f"{path.stat().st_size} bytes" if path.is_file() else "missing"
            raise RunFileError(f"checkpoint {folder} is not whole: {name} is {found}, its manifest says {size} bytes")
        if name in manifest.get("sha256", {}) and sha256_of(path) != manifest["sha256"][name]:
            raise RunFileError(f"checkpoint {folder} is damaged: {name} is not the file its manifest's sha256 names")
    return manifest


def write_checkpoint(run_dir: Path, write_files: Callable[[Path], None], info: dict[str, Any]) -> int:
    """`write_files(folder)` into a new folder, the manifest (`info` plus each file's size) last,
    then the folder renamed into place. Returns the checkpoint's size in bytes. NoSpaceError
    when the disk fills: the partial folder is removed and the last checkpoint stays as it was."""
    partial = run_dir / PARTIAL_DIR
    shutil.rmtree(partial, ignore_errors=True)
    try:
        partial.mkdir(parents=True)
        write_files(partial)
        paths = sorted(partial.iterdir())
        files = {path.name: path.stat().st_size for path in paths}
        hashes = {path.name: sha256_of(path) for path in paths}
        manifest = {**info, "bytes": sum(files.values()), "files": files, "sha256": hashes}
        (partial / CHECKPOINT_INFO).write_text(json.dumps(manifest) + "\n")
        flush(partial)
    except Exception as error:
        shutil.rmtree(partial, ignore_errors=True)
        if out_of_space(error):
            kept = checkpoint_folder(run_dir)
            last = f"the checkpoint at step {read_json(kept / CHECKPOINT_INFO)['steps']}" if kept else "no checkpoint"
            raise NoSpaceError(
                f"no space left on the device for the checkpoint at step {info['steps']} in {run_dir}; "
                f"{last} is kept (free some space, then resume)"
            ) from error
        raise
    current, previous = run_dir / CHECKPOINT_DIR, run_dir / PREVIOUS_DIR
    if current.exists():
        shutil.rmtree(previous, ignore_errors=True)
        os.replace(current, previous)
    os.replace(partial, current)
    shutil.rmtree(previous, ignore_errors=True)
    return manifest["bytes"]


def flush(folder: Path) -> None:
    """Every file of `folder` on the disk before the folder is renamed into place."""
    for path in folder.iterdir():
        with open(path, "rb") as handle:
            os.fsync(handle.fileno())
    descriptor = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)
