"""Demonstration datasets: write/read round trip, labels, corruption, resume, video export."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from inest_sim_node.collect import CollectConfig, collect_dataset, record_episode
from inest_sim_node.dataset import DatasetError, DemoDataset
from inest_sim_node.expert import ScriptedExpert
from inest_sim_node.subtasks import DESCRIPTIONS, subtask_labels
from inest_sim_node.video import episode_frames, write_video
from PIL import Image

from inest_sim_node import EnvConfig, SweepToTopEnv

SMALL = CollectConfig(episodes=5, valid_fraction=0.4, image_size=48, workers=2)


@pytest.fixture(scope="module")
def dataset_dir(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("demos")
    collect_dataset(root, SMALL, show_progress=False)
    return root


def test_round_trip_matches_a_fresh_recording(dataset_dir):
    dataset = DemoDataset(dataset_dir)
    assert len(dataset.entries("train")) == 3 and len(dataset.entries("valid")) == 2
    episode = dataset.load("valid", 1)
    env = SweepToTopEnv(config=EnvConfig(image_size=48))
    fresh = record_episode(env, ScriptedExpert(), episode.seed)
    for name, value in fresh.to_arrays().items():
        np.testing.assert_array_equal(value, episode.to_arrays()[name], err_msg=name)
    assert episode.ego.shape == episode.allo.shape == (len(episode), 48, 48, 3)
    assert len(episode.actions) == len(episode.rewards) == len(episode) - 1
    assert episode.progress[-1] == 3 and episode.progress[-2] == 2  # ends where the task is done


def test_labels_and_text_follow_the_task(dataset_dir):
    episode = DemoDataset(dataset_dir).load("train", 0)
    for scheme in (1, 3, 6):
        labels, ends = episode.labels[scheme], episode.ends[scheme]
        assert np.all(np.diff(labels) >= 0) and labels.min() == 0 and labels.max() == scheme - 1
        assert np.all(np.diff(ends) > 0) and ends[-1] == len(episode) - 1
        for i, end in enumerate(ends):
            assert labels[end] == i  # the frame where subtask i ends is its last frame
    block_done = [int(np.argmax(episode.progress >= k)) for k in (1, 2, 3)]
    np.testing.assert_array_equal(episode.ends[3], block_done)
    np.testing.assert_array_equal(episode.ends[6][1::2], block_done)  # push ends = block placed
    assert set(episode.text) == set(DESCRIPTIONS[3])
    assert episode.text[0] == "The robot pushes the red block into the green zone"


def test_subtask_labels_by_construction():
    progress = np.array([0, 0, 0, 1, 1, 1, 2, 2, 3])
    held = np.array([0, 1, 0, 0, 0, 1, 1, 0, 0], dtype=bool)
    labels, ends = subtask_labels(progress, held, 6)
    # yellow is held on the very frame blue counts: "push blue" and "reach yellow" end together
    np.testing.assert_array_equal(labels, [0, 0, 1, 1, 2, 2, 3, 5, 5])
    np.testing.assert_array_equal(ends, [1, 3, 5, 6, 6, 8])
    labels3, ends3 = subtask_labels(progress, held, 3)
    np.testing.assert_array_equal(labels3, [0, 0, 0, 0, 1, 1, 1, 2, 2])
    np.testing.assert_array_equal(ends3, [3, 6, 8])


def test_corrupt_and_missing_files_are_named(dataset_dir, tmp_path):
    copy = tmp_path / "copy"
    subprocess.run(["cp", "-r", str(dataset_dir), str(copy)], check=True)
    dataset = DemoDataset(copy)
    victim = copy / dataset.entries("train")[1]["file"]
    data = bytearray(victim.read_bytes())
    data[len(data) // 2] ^= 0xFF
    victim.write_bytes(bytes(data))
    with pytest.raises(DatasetError, match=f"corrupt episode file .*{victim.name}"):
        dataset.load("train", 1)
    with pytest.raises(DatasetError, match=victim.name):
        dataset.verify()
    assert dataset.load("train", 0).seed >= 0  # the others still load
    other = copy / dataset.entries("valid")[0]["file"]
    other.unlink()
    with pytest.raises(DatasetError, match=f"missing episode file .*{other.name}"):
        dataset.load("valid", 0)
    (copy / "metadata.json").unlink()
    with pytest.raises(DatasetError, match=r"metadata\.json is missing"):
        DemoDataset(copy)


def test_resume_reuses_and_other_settings_are_refused_without_loss(dataset_dir):
    before = {p.name: p.stat().st_mtime_ns for p in (dataset_dir / "episodes").iterdir()}
    metadata = collect_dataset(dataset_dir, SMALL, show_progress=False)  # same settings: nothing to do
    assert metadata["complete"]
    with pytest.raises(DatasetError, match=r"other settings \(differs in: collect.image_size, env.image_size\)"):
        collect_dataset(dataset_dir, CollectConfig(episodes=5, valid_fraction=0.4, image_size=64), show_progress=False)
    after = {p.name: p.stat().st_mtime_ns for p in (dataset_dir / "episodes").iterdir()}
    assert before == after
    DemoDataset(dataset_dir).verify()


def test_interrupted_collection_resumes(tmp_path):
    root = tmp_path / "partial"
    small = CollectConfig(episodes=2, valid_fraction=0.5, image_size=32, workers=1)
    collect_dataset(root, small, show_progress=False)
    meta = json.loads((root / "metadata.json").read_text())
    meta["kept"] = meta["kept"][:1]  # as if killed after the first episode
    meta["complete"] = False
    meta["next_seed"] = meta["kept"][0]["seed"] + 1
    (root / "metadata.json").write_text(json.dumps(meta))
    with pytest.raises(DatasetError, match="incomplete"):
        DemoDataset(root)
    collect_dataset(root, small, show_progress=False)
    DemoDataset(root).verify()


def test_the_content_hash_names_the_demonstrations_not_the_files(tmp_path):
    """Two collections of the same seeds hash alike, even without recorded content hashes."""
    small = CollectConfig(episodes=2, valid_fraction=0.5, image_size=32, workers=1)
    first, second = tmp_path / "first", tmp_path / "second"
    for root in (first, second):
        collect_dataset(root, small, show_progress=False)
    assert DemoDataset(first).content_hash() == DemoDataset(second).content_hash()
    meta = json.loads((second / "metadata.json").read_text())
    for entries in meta["episodes"].values():
        for entry in entries:
            del entry["content_sha256"]  # as a dataset collected before they were recorded
    (second / "metadata.json").write_text(json.dumps(meta))
    assert DemoDataset(first).content_hash() == DemoDataset(second).content_hash()
    other = CollectConfig(episodes=2, valid_fraction=0.5, image_size=32, workers=1, seed=7)
    collect_dataset(tmp_path / "other", other, show_progress=False)
    assert DemoDataset(tmp_path / "other").content_hash() != DemoDataset(first).content_hash()


def test_refuses_a_non_empty_foreign_folder(tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(DatasetError, match="not empty"):
        collect_dataset(tmp_path, SMALL, show_progress=False)
    assert (tmp_path / "notes.txt").read_text() == "mine"


@pytest.mark.parametrize("suffix", [".gif", ".mp4"])
def test_video_export(dataset_dir, tmp_path, suffix):
    episode = DemoDataset(dataset_dir).load("train", 0)
    frames = episode_frames(episode, "both", scale=2)
    assert frames[0].shape == (96, 192, 3)
    path = write_video(frames, tmp_path / f"episode{suffix}")
    assert path.stat().st_size > 1000
    if suffix == ".gif":
        assert Image.open(path).n_frames == len(episode)


def test_command_line_tools(tmp_path):
    bin_dir = Path(sys.executable).parent
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    out = tmp_path / "cli"
    run = subprocess.run(
        [bin_dir / "inest-collect-demos", "--out", out, "--episodes", "2", "--image-size", "32", "--workers", "1"],
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    assert "wrote 2 train + 0 valid" in run.stdout or "wrote 2 train" in run.stdout
    gif = tmp_path / "cli.gif"
    run = subprocess.run(
        [bin_dir / "inest-export-video", out, "--out", gif], capture_output=True, text=True, check=False
    )
    assert run.returncode == 0 and gif.exists(), run.stderr
    bad = subprocess.run(
        [bin_dir / "inest-collect-demos", "--out", out, "--episodes", "0"], capture_output=True, text=True, check=False
    )
    assert bad.returncode == 2 and "episodes must be positive" in bad.stderr
