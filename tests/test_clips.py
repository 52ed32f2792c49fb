"""Labelled clips: a trained policy's own rollouts recorded with their true progress, and the
learned reward's stage classifier refitted on them (hard-negative mining)."""

from __future__ import annotations

import dataclasses
import json
import shutil

import numpy as np
import pytest
from inest_agent_node.train import Trainer
from inest_reward_node.learning.clips import Clip, ClipError, load_clips, save_clips
from inest_reward_node.learning.pretrain import main as pretrain_main
from inest_reward_node.learning.pretrain import pretrain
from inest_reward_node.runtime.model import load_model
from small_training import small_train_config

from inest_agent_node.config import TrainConfig
from inest_experiments import record_clips


def test_clip_files_round_trip_and_refuse_what_does_not_fit(tmp_path):
    clip = Clip(np.zeros((5, 8, 8, 3), np.uint8), np.array([0, 0, 1, 1, 2]), np.zeros(5, bool))
    save_clips(tmp_path / "c.npz", [clip, clip], "ego", "test")
    loaded = load_clips(tmp_path / "c.npz", "ego", 8)
    assert len(loaded) == 2 and loaded[1].progress.tolist() == [0, 0, 1, 1, 2]
    with pytest.raises(ClipError, match="'ego' view; the model uses 'allo'"):
        load_clips(tmp_path / "c.npz", "allo", 8)
    with pytest.raises(ClipError, match="the model needs 16x16x3"):
        load_clips(tmp_path / "c.npz", "ego", 16)
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(ClipError, match="not a clip file"):
        load_clips(tmp_path / "bad.npz", "ego", 8)
    with pytest.raises(ClipError, match="not a clip file"):
        load_clips(tmp_path / "missing.npz", "ego", 8)


def test_a_policy_s_rollouts_become_clips_the_stage_classifier_is_refitted_on(tiny_tcc_run, tmp_path, capsys):
    pretrain_config, reward_run = tiny_tcc_run
    config = small_train_config(reward="inest", model=str(reward_run / "model"))
    Trainer(config, tmp_path / "policy", progress_bar=False).train()
    clips_file = tmp_path / "clips" / "policy.npz"  # the folder does not exist yet
    assert record_clips.main([str(tmp_path / "policy"), "--episodes", "3", "--out", str(clips_file)]) == 0
    assert "3 clips" in capsys.readouterr().out
    clips = load_clips(clips_file, "ego", 48)
    assert len(clips) == 3 and all(len(clip.frames) == 100 for clip in clips)
    assert all(clip.progress.min() >= 0 and clip.progress.max() <= 3 and clip.held.dtype == bool for clip in clips)

    refit_run = tmp_path / "refit"
    shutil.copytree(reward_run, refit_run)
    calibration = dataclasses.replace(
        pretrain_config.calibration, random_episodes=2, wrong_order_episodes=1, clips=(str(clips_file),)
    )
    pretrain(dataclasses.replace(pretrain_config, calibration=calibration), refit_run, resume=True, progress_bar=False)
    refitted, original = load_model(refit_run / "model"), load_model(reward_run / "model")
    assert refitted.metadata.calibration["clips"] == [str(clips_file)]
    assert not np.allclose(refitted.goals(3).stage_classifier.out_weight, original.goals(3).stage_classifier.out_weight)
    np.testing.assert_allclose(refitted.goals(3).goals, original.goals(3).goals)  # the encoder is untouched


def test_bad_clip_input_gets_one_line_and_saves_nothing(tiny_tcc_run, tmp_path, capsys):
    pretrain_config, reward_run = tiny_tcc_run
    assert record_clips.main([str(tmp_path / "nowhere"), "--out", str(tmp_path / "c.npz")]) == 2
    assert "holds no checkpoint" in capsys.readouterr().err
    oracle = tmp_path / "oracle"  # a run whose evaluations render no camera
    (oracle / "checkpoint").mkdir(parents=True)
    (oracle / "checkpoint" / "checkpoint.json").write_text('{"steps": 0}')
    (oracle / "config.json").write_text(json.dumps(TrainConfig.from_dict({"reward": "env"}).to_dict()))
    assert record_clips.main([str(oracle), "--out", str(tmp_path / "c.npz")]) == 2
    assert "score no camera frames" in capsys.readouterr().err and not (tmp_path / "c.npz").exists()
    shutil.copytree(reward_run, tmp_path / "run")
    before = (tmp_path / "run" / "model" / "model.json").read_text()
    argv = [pretrain_config.dataset, "--out", str(tmp_path / "run"), "--resume", "--image-size", "48"]
    argv += ["--iterations", "40", "--videos-per-batch", "6", "--frames-per-video", "16", "--clips", "missing.npz"]
    assert pretrain_main(argv) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "missing.npz: not a clip file" in error
    assert (tmp_path / "run" / "model" / "model.json").read_text() == before
    assert json.loads((tmp_path / "run" / "config.json").read_text())["calibration"]["clips"] == []
