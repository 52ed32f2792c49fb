"""The reward-quality report runs end to end and its metrics mean what they say."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from inest_reward_node.learning.quality import ground_truth_gaussian, min_max, rank_correlation


def test_report_end_to_end(tiny_tcc_run, tmp_path):
    config, run_dir = tiny_tcc_run
    out = tmp_path / "quality"
    run = subprocess.run(
        [
            Path(sys.executable).parent / "inest-reward-quality",
            run_dir / "model",
            config.dataset,
            "--out",
            out,
            "--negative-episodes",
            "2",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    assert "spearman(progress, total incl. bonus)" in run.stdout
    assert "shaping rho" in run.stdout and "false rand" in run.stdout
    report = json.loads((out / "report.json").read_text())
    assert report["model"]["view"] == "ego"
    assert set(report["schemes"]) == {"1", "3", "6"}
    assert [report["schemes"][s]["variant"] for s in ("1", "3", "6")] == ["xirl", "inest", "inest"]
    assert report["scorer_options"] == {}
    for kind in ("random", "wrong_order"):
        assert report["negatives"][kind]["episodes"] == 2
    assert report["negatives"]["random"]["first_seed"] == 41_000_000
    assert report["negatives"]["wrong_order"]["first_seed"] == 41_500_000
    assert report["negatives"]["wrong_order"]["true_progress_max"] <= 1  # blue first: the env counts red at most
    for scheme, row in report["schemes"].items():
        assert row["demos"] == 2
        assert row["scorer"]["variant"] == row["variant"]
        total = row["spearman_progress_total_incl_bonus"]
        assert -1.0 <= total["median"] <= 1.0
        assert row["spearman_progress"] == total  # the old key still reads the same numbers
        assert 0.0 <= row["tracker_pass_rate"] <= 1.0
        assert 0.0 <= row["reward_vs_env"]["mse"] <= 1.0
        assert (out / row["plot"]).stat().st_size > 5000
        assert [sub["subtask"] for sub in row["per_subtask"]] == list(range(int(scheme)))
        for sub in row["per_subtask"]:
            for key in ("spearman_shaping_within", "spearman_embedding_within"):
                assert set(sub[key]) == {"median", "mean", "demos"}
                assert sub[key]["median"] is None or -1.0 <= sub[key]["median"] <= 1.0
            assert set(sub["switch_dip"]) == {"median", "min", "switches"}
            assert set(sub["completion_lag_frames"]) == {"median", "mean", "completed"}
            assert sub["completion_lag_frames"]["completed"] == round(2 * (1 - sub["miss_rate"]))
            assert set(sub["false_completion_rate"]) == {"random", "wrong_order"}
            assert all(0.0 <= rate <= 1.0 for rate in sub["false_completion_rate"].values())
        assert set(row["false_completion_any"]) == {"random", "wrong_order"}


def test_report_refuses_reward_settings_the_scorer_does_not_take(tiny_tcc_run, tmp_path):
    config, run_dir = tiny_tcc_run
    run = subprocess.run(
        [
            Path(sys.executable).parent / "inest-reward-quality",
            run_dir / "model",
            config.dataset,
            "--out",
            tmp_path,
            "--stage-confidence",
            "1.5",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 2 and "stage_confidence must be in (0, 1)" in run.stderr, run.stderr
    assert len(run.stderr.strip().splitlines()) == 1, run.stderr


def test_report_refuses_a_scheme_the_model_lacks(tiny_tcc_run, tmp_path):
    config, run_dir = tiny_tcc_run
    run = subprocess.run(
        [
            Path(sys.executable).parent / "inest-reward-quality",
            run_dir / "model",
            config.dataset,
            "--out",
            tmp_path,
            "--schemes",
            "4",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 2 and "not 4" in run.stderr


def test_metric_helpers():
    np.testing.assert_allclose(min_max(np.array([2.0, 4.0, 3.0])), [0.0, 1.0, 0.5])
    assert min_max(np.ones(3)).tolist() == [0.0, 0.0, 0.0]
    curve = ground_truth_gaussian(20, start=5, end=12)
    assert curve.argmax() == 12 and curve.max() == pytest.approx(1.0)
    assert curve[12 - 4] == pytest.approx(np.exp(-0.5))  # sigma = half the subtask's 8 frames
    assert rank_correlation(np.arange(10.0), np.arange(10.0) ** 3) == pytest.approx(1.0)
    assert rank_correlation(np.arange(10.0), -np.arange(10.0)) == pytest.approx(-1.0)
