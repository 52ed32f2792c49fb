"""inest-summarise: one table across seeds from run folders, finished and still training."""

from __future__ import annotations

import json

import pytest
from inest_experiments.summary import main


def write_run(root, method: str, seed: int, score: float | None, curve: list[list[float]]) -> None:
    run = root / method / f"seed{seed}"
    (run / "checkpoint").mkdir(parents=True)
    (run / "config.json").write_text(json.dumps({"seed": seed}))
    if score is None:
        (run / "checkpoint" / "history.json").write_text(json.dumps(curve))
        return
    final = {"episodes": 150, "mean_score": score, "success_rate": score / 2, "blocks_share": [0, 0, 1, 0]}
    results = {"final_evaluation": final, "steps": 300, "learning_curve": curve}
    (run / "results.json").write_text(json.dumps(results))


def test_summary_averages_finished_seeds_and_lists_runs_still_training(tmp_path, capsys):
    curve = [[100, 0.1, 0.0], [200, 0.2, 0.0], [300, 0.3, 0.0]]
    write_run(tmp_path, "oracle", 0, 0.8, curve)
    write_run(tmp_path, "oracle", 1, 0.9, curve)
    write_run(tmp_path, "oracle", 2, None, curve[:1])
    assert main([str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    oracle = summary["methods"]["oracle"]
    assert oracle["seeds"] == 2 and abs(oracle["mean_score"] - 0.85) < 1e-9
    low, high = oracle["mean_score_ci95"]
    assert 0.8 <= low <= 0.85 <= high <= 0.9
    # the t interval, 0.85 ± t(0.975, 1 d.o.f.) 12.706 x 0.05, is far wider with two seeds
    assert oracle["mean_score_t95"] == pytest.approx([0.85 - 0.6353, 0.85 + 0.6353], abs=1e-3)
    partial = [row for row in summary["runs"] if not row["final"]]
    assert partial == [{"method": "oracle", "run": "seed2", "seed": 2, "final": False, "steps": 100, "mean_score": 0.1}]
    assert (tmp_path / "learning_curves.png").exists() and "0.850" in capsys.readouterr().out
    assert main([str(tmp_path / "missing")]) == 2
