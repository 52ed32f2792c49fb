"""A checkpoint is one unit: written whole into a new folder, renamed into place, read only whole."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest
from inest_agent_node.checkpoint import (
    CHECKPOINT_DIR,
    PARTIAL_DIR,
    PREVIOUS_DIR,
    checkpoint_folder,
    read_manifest,
    write_checkpoint,
)
from inest_agent_node.train import check_resume
from inest_common.files import NoSpaceError, RunFileError, out_of_space


def writer(**files: str):
    def write(folder: Path) -> None:
        for name, text in files.items():
            (folder / name).write_text(text)

    return write


def test_each_checkpoint_replaces_the_last_whole_and_leaves_no_other_folder(tmp_path):
    assert checkpoint_folder(tmp_path) is None
    write_checkpoint(tmp_path, writer(a="old", b="old"), {"steps": 10})
    size = write_checkpoint(tmp_path, writer(a="newer"), {"steps": 20})
    folder = checkpoint_folder(tmp_path)
    assert folder == tmp_path / CHECKPOINT_DIR and sorted(path.name for path in tmp_path.iterdir()) == [CHECKPOINT_DIR]
    assert sorted(path.name for path in folder.iterdir()) == ["a", "checkpoint.json"]  # nothing of the old one
    manifest = read_manifest(folder)
    assert manifest["steps"] == 20 and manifest["files"] == {"a": 5} and size == manifest["bytes"] == 5


def test_a_full_disk_drops_the_new_checkpoint_and_keeps_the_last(tmp_path):
    write_checkpoint(tmp_path, writer(a="first"), {"steps": 10})

    def fill(folder: Path) -> None:
        (folder / "a").write_text("half")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(folder / "b"))

    with pytest.raises(NoSpaceError, match=r"checkpoint at step 20 .*; the checkpoint at step 10 is kept") as caught:
        write_checkpoint(tmp_path, fill, {"steps": 20})
    assert out_of_space(caught.value) and not (tmp_path / PARTIAL_DIR).exists()
    assert (
        read_manifest(tmp_path / CHECKPOINT_DIR)["steps"] == 10
        and (tmp_path / CHECKPOINT_DIR / "a").read_text() == "first"
    )
    with pytest.raises(ValueError, match="not a disk error"):  # any other failure is not dressed up as one
        write_checkpoint(tmp_path, lambda folder: (_ for _ in ()).throw(ValueError("not a disk error")), {"steps": 30})
    assert not (tmp_path / PARTIAL_DIR).exists()


def test_a_crash_between_the_two_renames_leaves_the_previous_checkpoint_readable(tmp_path):
    write_checkpoint(tmp_path, writer(a="first"), {"steps": 10})
    os.replace(tmp_path / CHECKPOINT_DIR, tmp_path / PREVIOUS_DIR)  # where such a crash stops
    assert (
        checkpoint_folder(tmp_path) == tmp_path / PREVIOUS_DIR and read_manifest(tmp_path / PREVIOUS_DIR)["steps"] == 10
    )
    write_checkpoint(tmp_path, writer(a="second"), {"steps": 20})
    assert sorted(path.name for path in tmp_path.iterdir()) == [CHECKPOINT_DIR]


def test_a_file_of_another_size_than_its_manifest_s_makes_the_checkpoint_unreadable(tmp_path):
    write_checkpoint(tmp_path, writer(a="12345", b="xy"), {"steps": 10})
    (tmp_path / CHECKPOINT_DIR / "a").write_text("12")
    (tmp_path / CHECKPOINT_DIR / "b").unlink()
    with pytest.raises(RunFileError, match="is not whole: a is 2 bytes, its manifest says 5 bytes"):
        read_manifest(tmp_path / CHECKPOINT_DIR)
    (tmp_path / CHECKPOINT_DIR / "a").write_text("12345")
    with pytest.raises(RunFileError, match="is not whole: b is missing"):
        read_manifest(tmp_path / CHECKPOINT_DIR)


def test_a_file_changed_in_place_makes_the_checkpoint_unreadable(tmp_path):
    write_checkpoint(tmp_path, writer(a="12345"), {"steps": 10})
    (tmp_path / CHECKPOINT_DIR / "a").write_text("12346")  # same size, one byte changed
    with pytest.raises(RunFileError, match="is damaged: a is not the file its manifest's sha256 names"):
        read_manifest(tmp_path / CHECKPOINT_DIR)


def test_checkpoint_files_without_a_manifest_are_neither_resumed_nor_started_over(tmp_path):
    (tmp_path / "config.json").write_text("{}")
    write_checkpoint(tmp_path, writer(a="saved"), {"steps": 10})
    (tmp_path / CHECKPOINT_DIR / "checkpoint.json").unlink()
    for resume, start_over in ((True, False), (False, True)):
        with pytest.raises(RunFileError, match="holds checkpoint files but no manifest"):
            check_resume(tmp_path, resume, start_over)
    assert (tmp_path / CHECKPOINT_DIR / "a").read_text() == "saved"
