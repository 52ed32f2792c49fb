"""inest-experiments: a grid of real inest-train runs that survives a kill, Ray tasks, the report."""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from inest_experiments.config import GridConfig
from inest_experiments.experiments import export_results, main, plan, ranking, rankings
from small_training import small_train_config
from test_summary import write_run

ROOT = Path(__file__).resolve().parent.parent
STEPS = 400  # two evaluations and checkpoints (200, 400): a cell can be caught between them
HEADER = "# inest-experiments:"


def write_grid(root: Path, methods: dict, seeds: list[int], **settings) -> Path:
    """A grid of tiny runs (small_training's settings, torch SAC, checkpoint and evaluation every
    200 steps) under root/out."""
    train = small_train_config(reward="env", learner="sac")
    (root / "train.yaml").write_text(yaml.safe_dump(train.to_dict()))
    grid = {"methods": methods, "seeds": seeds, "total_steps": STEPS, "config": str(root / "train.yaml")}
    path = root / "grid.yaml"
    path.write_text(yaml.safe_dump(grid | {"out": str(root / "out")} | settings))
    return path


def cell_states(out: Path, cells: list[str]) -> dict[str, str]:
    """finished (results.json), half (a checkpoint, no results) or other, per cell."""

    def state(run: Path) -> str:
        if (run / "results.json").exists():
            return "finished"
        return "half" if (run / "checkpoint" / "checkpoint.json").exists() else "other"

    return {cell: state(out / cell) for cell in cells}


def kill_when_half_finished(runner: subprocess.Popen, out: Path, cells: list[str]) -> dict[str, str]:
    """SIGKILL the runner's process group once one cell is finished and another half-finished,
    seen with the group stopped so that nothing moves between the look and the kill."""
    while runner.poll() is None:
        time.sleep(0.2)
        if not {"finished", "half"} <= set(cell_states(out, cells).values()):
            continue
        os.killpg(runner.pid, signal.SIGSTOP)
        states = cell_states(out, cells)
        if {"finished", "half"} <= set(states.values()):
            os.killpg(runner.pid, signal.SIGKILL)
            runner.wait()
            return states
        os.killpg(runner.pid, signal.SIGCONT)
    pytest.fail(f"the grid ended (status {runner.returncode}) before a cell was caught half-finished")


def test_a_killed_grid_resumes_and_finishes_every_cell_exactly_once(tmp_path, capsys, monkeypatch):
    unused = str(tmp_path / "model")  # a path in the settings, as a learned reward's (env: unread)
    methods = {"oracle": {"args": ["--reward", "env"], "model": unused}, "bare": {"args": ["--observation", "state"]}}
    grid = write_grid(tmp_path, methods, [0, 1])
    out = tmp_path / "out"
    cells = [f"{method}/seed{seed}" for method in ("oracle", "bare") for seed in (0, 1)]
    command = [sys.executable, "-m", "inest_experiments.experiments", "run", str(grid), "--parallel", "1"]
    with open(tmp_path / "first.log", "w") as log:
        runner = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        at_kill = kill_when_half_finished(runner, out, cells)
    finished = [cell for cell, state in at_kill.items() if state == "finished"]
    halves = [cell for cell, state in at_kill.items() if state == "half"]
    started = {cell for cell, state in at_kill.items() if state == "other" and (out / cell / "config.json").exists()}
    before = {cell: (out / cell / "results.json").stat().st_mtime_ns for cell in finished}
    history = {cell: json.loads((out / cell / "checkpoint" / "history.json").read_text()) for cell in halves}
    assert json.loads((out / "grid.json").read_text())["grid"]["seeds"] == [0, 1]

    assert main(["run", str(grid), "--parallel", "1"]) == 0
    printed = capsys.readouterr().out
    assert f"4 cells, {len(finished)} finished, {4 - len(finished)} to train" in printed
    for cell in cells:
        results = json.loads((out / cell / "results.json").read_text())
        assert results["steps"] == STEPS
        log = (out / f"{cell}.log").read_text()
        starts = [line for line in log.splitlines() if line.startswith(HEADER)]
        if cell in finished:  # skipped: trained once, results untouched
            assert len(starts) == 1 and (out / cell / "results.json").stat().st_mtime_ns == before[cell]
            assert f"finished {cell}" not in printed
        elif cell in halves:  # continued from its checkpoint: the step counter and curve go on
            assert len(starts) == 2 and "--resume" not in starts[0] and starts[1].endswith("--resume")
            assert results["learning_curve"][: len(history[cell])] == history[cell]
            assert [point[0] for point in results["learning_curve"]] == [200, 400]
        elif cell in started:  # killed before its first checkpoint: trained again from step 0, and its log says so
            assert len(starts) == 2 and starts[1].endswith("--start-over")
        else:
            assert len(starts) == 1
    report = (out / "report.md").read_text()
    for method in ("oracle", "bare"):
        assert any(line.startswith(f"| {method} | 2 of 2 | 400 | ") and " [" in line for line in report.splitlines())
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["methods"]) == {"oracle", "bare"} and (out / "learning_curves.png").exists()
    # its export, paths relative to the checkout and no checkpoints, copied back continues the grid
    monkeypatch.chdir(tmp_path)
    assert main(["report", str(grid), "--export", "export"]) == 0
    shutil.rmtree(out)
    shutil.copytree(tmp_path / "export", out)
    assert main(["run", str(grid), "--parallel", "1"]) == 0
    assert "4 cells, 4 finished, 0 to train" in capsys.readouterr().out


def test_a_failed_cell_is_named_with_its_log_and_the_others_go_on(tmp_path, capsys):
    broken = tmp_path / "broken-model"
    broken.mkdir()
    (broken / "model.json").write_text("{}")  # passes the grid's check, fails in inest-train
    methods = {"broken": {"args": ["--reward", "inest"], "model": str(broken)}, "oracle": {"args": ["--reward", "env"]}}
    grid = write_grid(tmp_path, methods, [0])
    assert main(["run", str(grid)]) == 1
    printed = capsys.readouterr().out
    log = tmp_path / "out" / "broken" / "seed0.log"
    assert f"broken/seed0 failed (exit status 2); see {log}" in printed and "inest-train:" in log.read_text()
    assert (tmp_path / "out" / "oracle" / "seed0" / "results.json").exists()
    report = (tmp_path / "out" / "report.md").read_text()
    assert "| broken | 0 of 1 | | | not finished |" in report and "Not started" in report

    recorded = json.loads((tmp_path / "out" / "grid.json").read_text())
    del recorded["cells"]["oracle/seed0"]["config"]["checkpoint_minutes"]  # recorded before it existed
    del recorded["cells"]["oracle/seed0"]["config"]["refit_every"]  # and a setting of what it trains, off then
    (tmp_path / "out" / "grid.json").write_text(json.dumps(recorded))
    assert main(["run", str(grid), "oracle"]) == 0  # neither is a change: the cell stays finished
    methods["oracle"]["args"] += ["--observation", "state"]  # the finished cell's settings changed
    grid.write_text(yaml.safe_dump(yaml.safe_load(grid.read_text()) | {"methods": methods}))
    assert main(["run", str(grid), "oracle"]) == 2
    assert "oracle/seed0 was trained with other settings (observation)" in capsys.readouterr().err


def test_a_headline_method_runs_its_own_seeds():
    from inest_experiments.config import GridConfig

    grid = GridConfig.from_dict({"methods": {"oracle": {"seeds": [0, 1, 2, 3, 4]}, "other": {}}, "seeds": [0, 1, 2]})
    assert grid.seeds_of("oracle") == (0, 1, 2, 3, 4) and grid.seeds_of("other") == (0, 1, 2)


@pytest.mark.parametrize(
    ("grid", "extra", "message"),
    [
        ("methods: {oracle: {args: [--reward, env]}\n", [], "is not valid YAML at line 2"),
        ("methods: {oracle: {args: [--reward, env]}}\nsteps: 5\n", [], "unknown grid setting(s) ['steps']"),
        ("methods: {oracle: {arg: [--reward, env]}}\n", [], "unknown setting(s) of method oracle ['arg']"),
        ("methods: {oracle: {args: [--reward, env]}}\n", ["inest3"], "unknown method(s) ['inest3']"),
        ("methods: {oracle: {args: [--reward, envv]}}\n", [], "method oracle: argument --reward: invalid choice"),
        ("methods: {oracle: {args: [--seed, '4']}}\n", [], "method oracle: the grid sets ['--seed'] itself"),
        ("methods: {x: {args: [--reward, xirl], model: nowhere}}\n", [], "method x: no reward model at"),
        ("methods: {x: {args: [--reward, xirl]}}\n", [], "method x: the xirl reward needs a reward model folder"),
        ("methods: {x: {args: [--reward, xirl]}}\nconfig: t.yaml\n", [], "method x: no reward model at"),
        ("methods: {oracle: {}}\nseeds: [1, 1]\n", [], "seeds must differ"),
        ("methods: {oracle: {seeds: [2, -1]}}\n", [], "method oracle: seeds must be a non-empty list"),
        ("methods: {oracle: {}}\ndemos: nowhere\n", [], "no demonstration dataset at"),
        ("methods: {oracle: {}}\nout: [a]\n", [], "out must be a path"),
        ("methods: {oracle: {reference: {score: 73}}}\n", [], "reference score must be a number in [0, 1]"),
        ("methods: {oracle: {reference: {rate: 0.2}}}\n", [], "unknown reference setting(s) of oracle ['rate']"),
        ("methods: {oracle: {}}\ntables: {t: {methods: [holdr]}}\n", [], "table t: methods must be some of"),
        ("methods: {oracle: {}}\ntables: {t: {methods: oracle}}\n", [], "table t must be a mapping of a title"),
        ("methods: {oracle: {}}\ntables: {t: {methods: [[oracle]]}}\n", [], "table t: methods must be some of"),
        ("methods: {oracle: {}}\ntables: {t: {methods: [oracle, oracle]}}\n", [], "table t: methods must differ"),
        ("methods: {oracle: {}}\ntables: {t: {title: ' ', methods: [oracle]}}\n", [], "title must be one line"),
        ("methods: {oracle: {}}\ntables: {5: {methods: [oracle]}}\n", [], "table name 5 must be a file name"),
        ("methods: {oracle: {}}\ntables: 0\n", [], "tables must be a mapping of table name"),
        ("methods: {oracle: {}}\nreference_label: a | b\n", [], "reference_label must be one line of text"),
        ("methods: {oracle: {reference: {score: 0.5, 1: 2, x: 3}}}\n", [], "unknown reference setting(s) of oracle"),
    ],
)
def test_bad_grids_are_one_line_and_exit_2(tmp_path, capsys, monkeypatch, grid, extra, message):
    monkeypatch.chdir(tmp_path)
    write_grid(tmp_path, {}, [0])  # the tiny train.yaml
    train = yaml.safe_load((tmp_path / "train.yaml").read_text())
    (tmp_path / "t.yaml").write_text(yaml.safe_dump(train | {"model": "nowhere"}))  # a model that is not there
    (tmp_path / "bad.yaml").write_text(grid if "config:" in grid else grid + "config: train.yaml\n")
    assert main(["run", "bad.yaml", *extra]) == 2
    error = capsys.readouterr().err
    assert message in error and error.count("\n") == 1, error
    assert not (tmp_path / "runs").exists()


def test_report_of_a_results_folder_lists_every_method_with_intervals(tmp_path, capsys):
    curve = [[100, 0.1, 0.0], [200, 0.2, 0.0], [300, 0.3, 0.0]]
    write_run(tmp_path, "oracle", 0, 0.8, curve)
    write_run(tmp_path, "oracle", 1, 0.9, curve)
    write_run(tmp_path, "oracle", 2, None, curve[:1])
    assert main(["report", str(tmp_path)]) == 0
    lines = (tmp_path / "report.md").read_text().splitlines()
    row = next(line for line in lines if line.startswith("| oracle |"))
    expected = "| oracle | 2 | 300 | legacy | 0.850 [0.800, 0.900] | 42.5 % | 0 / 0 / 100 / 0 % | | | simulator state |"
    assert row == expected
    assert "| oracle/seed2 (training) | 100 | 0.100 (last evaluation) | | |" in lines
    assert (tmp_path / "summary.json").exists() and (tmp_path / "learning_curves.png").exists()
    assert not any(line.startswith("Ranking") for line in lines)  # one finished method ranks nothing
    grid = tmp_path / "grid.yaml"
    grid.write_text(f"methods: {{oracle: {{}}, holdr: {{}}}}\nseeds: [0, 1, 2]\nout: {tmp_path}\n")
    assert main(["report", str(grid)]) == 0
    report = (tmp_path / "report.md").read_text()
    assert "| oracle | 2 of 3 |" in report and "| holdr | 0 of 3 | | | not finished |" in report
    assert main(["report", str(tmp_path / "nothing")]) == 2
    assert capsys.readouterr().err.count("\n") == 1
    # comparisons as their own tables and figures, with a published result beside the method's own
    grid.write_text(
        yaml.safe_dump(
            {
                "methods": {"oracle": {"reference": {"score": 0.7, "success": 0.2245}}, "holdr": {}},
                "out": str(tmp_path),
                "reference_label": "thesis",
                "tables": {"main": {"title": "Oracle against HOLD-R", "methods": ["holdr", "oracle"]}},
            }
        )
    )
    assert main(["report", str(grid)]) == 0
    report = (tmp_path / "report.md").read_text()
    table = report.split("## Oracle against HOLD-R")[1].split("## Every method")[0]
    assert "| labelled episodes | cameras | thesis: score, success |" in table
    holdr = table.index("| holdr | 0 of 3 | | | not finished | | | | | |")
    assert holdr < table.index("| oracle | 2 of 3 | 300 | legacy | 0.850")  # made without layouts: before the split
    assert "| 0.7, 22.45 % |" in table and "(learning_curves_main.png)" in table
    assert (tmp_path / "learning_curves_main.png").exists()
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["tables"] == {"main": {"title": "Oracle against HOLD-R", "methods": ["holdr", "oracle"]}}
    assert summary["references"] == {"oracle": {"label": "thesis", "score": 0.7, "success": 0.2245}}
    # the export: report and runs' small files, a training run's curve so far, no checkpoints
    export = tmp_path.with_name(f"{tmp_path.name}-export")
    (tmp_path / "oracle" / "seed0" / "checkpoint" / "replay_buffer.npz").write_bytes(b"large")
    (tmp_path / "oracle" / "seed0" / "policy").mkdir()
    (tmp_path / "oracle" / "seed0" / "policy" / "actor.safetensors").write_bytes(b"weights")
    assert main(["report", str(grid), "--export", str(export)]) == 0
    assert (export / "report.md").read_text() == (tmp_path / "report.md").read_text()
    assert (export / "summary.json").exists() and (export / "learning_curves.png").exists()
    assert (export / "learning_curves_main.png").exists()
    finished = export / "oracle" / "seed0"
    assert (finished / "results.json").exists() and not (finished / "checkpoint").exists()
    assert (
        finished / "policy" / "actor.safetensors"
    ).read_bytes() == b"weights"  # the policy, where inest-evaluate looks
    assert json.loads((export / "oracle" / "seed2" / "history.json").read_text()) == curve[:1]
    # a run that evaluated after the report read it is exported as the report read it
    reported = json.loads((tmp_path / "summary.json").read_text())["runs"]
    (tmp_path / "oracle" / "seed2" / "checkpoint" / "history.json").write_text(json.dumps(curve[:2]))
    export_results(tmp_path, export, {f"{row['method']}/{row['run']}": row for row in reported})
    assert json.loads((export / "oracle" / "seed2" / "history.json").read_text()) == curve[:1]
    # paths under the checkout it ran in are relative in the copies: the same in any checkout
    config = tmp_path / "oracle" / "seed0" / "config.json"
    config.write_text(json.dumps({"model": str(Path.cwd().resolve() / "results" / "m"), "other": "/elsewhere/m"}))
    assert main(["report", str(tmp_path), "--export", str(export)]) == 0
    assert json.loads((finished / "config.json").read_text()) == {"model": "results/m", "other": "/elsewhere/m"}
    # that report had no tables: the table's figure is gone from the grid's folder and the export
    assert not (tmp_path / "learning_curves_main.png").exists() and not (export / "learning_curves_main.png").exists()
    assert main(["report", str(tmp_path), "--export", str(tmp_path)]) == 2
    assert capsys.readouterr().err.startswith("inest-experiments: --export")


def test_the_ranking_joins_neighbours_by_whether_their_intervals_overlap():
    summary = {
        "methods": {
            "a": {"seeds": 3, "mean_score": 0.9, "mean_score_ci95": [0.85, 0.95]},
            "b": {"seeds": 2, "mean_score": 0.8, "mean_score_ci95": [0.7, 0.86]},
            "c": {"seeds": 3, "mean_score": 0.2, "mean_score_ci95": [0.1, 0.3]},
            "one seed": {"seeds": 1, "mean_score": 0.5, "mean_score_ci95": [0.5, 0.5]},
        }
    }
    order = ranking(["c", "a", "one seed", "b", "unfinished"], summary)
    assert order.startswith("Ranking by mean score, methods with 2 or more seeds: a ≈ b > c (")
    assert "Not neighbours" not in order  # a > c follows from the chain
    # then the same by the t intervals, wider with few seeds, on a line of its own
    t_intervals = {"a": [0.8, 1.0], "b": [0.6, 0.9], "c": [0.0, 0.65], "one seed": [0.5, 0.5]}
    for method, interval in t_intervals.items():
        summary["methods"][method]["mean_score_t95"] = interval
    assert rankings(["c", "a", "one seed", "b"], summary) == [
        order,
        "The same by 95 % Student t intervals, wider with few seeds: a ≈ b ≈ c."
        " Not neighbours, where the chain reads otherwise: a > c.",
    ]
    assert ranking(["a", "one seed", "unfinished"], summary) == ""
    # overlap is not transitive: the pairs further apart that the chain misstates are named
    summary["methods"]["b"]["mean_score_ci95"] = [0.25, 0.88]
    order = ranking(["a", "b", "c"], summary)
    assert "seeds: a ≈ b ≈ c (" in order and order.endswith("Not neighbours, where the chain reads otherwise: a > c.")
    summary["methods"]["c"]["mean_score_ci95"] = [0.1, 0.86]
    summary["methods"]["b"]["mean_score_ci95"] = [0.87, 0.88]
    order = ranking(["a", "b", "c"], summary)
    assert "seeds: a ≈ b > c (" in order and order.endswith("Not neighbours, where the chain reads otherwise: a ≈ c.")


def test_report_shows_what_each_reward_paid_for_from_its_first_to_its_last_window(tmp_path):
    curve = [[100, 0.1, 0.0]]
    first = {"reward_per_step": -0.7, "shaping_per_step": -0.7, "bonus_per_step": 0.0, "intrinsic_per_step": 0.0}
    first |= {"final_progress_mean": 0.04, "unearned_completion_rate": 0.0, "early_claim_rate": 0.0}
    first |= {"unplaced_claim_rate": 0.0, "never_placed_claim_rate": 0.0, "missed_rate": 0.0}
    for seed, (shaping, unearned) in enumerate([(-0.1, 0.2), (-0.2, 0.3)]):
        write_run(tmp_path, "hacked", seed, 0.0, curve)
        results_file = tmp_path / "hacked" / f"seed{seed}" / "results.json"
        last = first | {"reward_per_step": shaping, "shaping_per_step": shaping, "final_progress_mean": 0.0}
        last |= {"unearned_completion_rate": unearned, "early_claim_rate": 0.1, "unplaced_claim_rate": unearned - 0.1}
        last |= {"never_placed_claim_rate": unearned - 0.15, "missed_rate": 0.05}  # and missed a block placed
        results_file.write_text(
            json.dumps(json.loads(results_file.read_text()) | {"reward_diagnostics": [first, last]})
        )
    write_run(tmp_path, "oracle", 0, 0.9, curve)
    oracle = tmp_path / "oracle" / "seed0" / "results.json"
    oracle_window = {"reward_per_step": 0.1, "final_progress_mean": 1.0}
    oracle.write_text(json.dumps(json.loads(oracle.read_text()) | {"reward_diagnostics": [oracle_window] * 2}))
    assert main(["report", str(tmp_path)]) == 0
    lines = (tmp_path / "report.md").read_text().splitlines()
    # the reward rose while the blocks placed fell to none, and the stage claimed unplaced blocks
    hacked = "| hacked | -0.7 → -0.15 | -0.7 → -0.15 | 0 → 0 | 0 → 0 | 0.04 → 0 |"
    assert f"{hacked} 0 % → 25 % | 0 % → 10 % | 0 % → 15 % | 0 % → 10 % | 0 % → 5 % |" in lines
    assert "| oracle | 0.1 → 0.1 | | | | 1 → 1 | | | | | |" in lines  # the environment's reward has no parts
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert [row["reward_diagnostics"]["last"]["shaping_per_step"] for row in summary["runs"][:2]] == [-0.1, -0.2]


def test_report_scores_each_learned_reward_on_the_grids_demonstrations(
    tmp_path, capsys, monkeypatch, tiny_model, tiny_demos
):
    curve = [[100, 0.1, 0.0]]
    runs = {
        "oracle": small_train_config(reward="env"),
        "inest3": small_train_config(reward="inest", model=str(tiny_model)),
    }
    for method, config in runs.items():
        write_run(tmp_path, method, 0, 0.5, curve)
        (tmp_path / method / "seed0" / "config.json").write_text(json.dumps(config.to_dict()))
    grid = tmp_path / "grid.yaml"
    grid.write_text(
        yaml.safe_dump(
            {"methods": {"oracle": {}, "inest3": {}}, "seeds": [0], "out": str(tmp_path), "demos": str(tiny_demos)}
        )
    )
    assert main(["report", str(grid)]) == 0
    lines = (tmp_path / "report.md").read_text().splitlines()
    row = next(line for line in lines if line.startswith("| inest3 | inest | 3 | 2 |"))
    mse, mae = (float(cell) for cell in row.split("|")[5:7])
    assert 0 < mse <= mae < 1  # min-max normalised rewards: |error| <= 1, so MSE <= MAE
    assert not any(line.startswith("| oracle | env") for line in lines)  # the oracle has no learned reward
    report = tmp_path / "inest3" / "quality" / "report.json"
    kept = report.stat().st_mtime_ns
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["reward_quality"]["inest3"]["reward_mse"] == pytest.approx(mse, abs=1e-4)
    assert main(["report", str(grid)]) == 0 and report.stat().st_mtime_ns == kept  # kept, not scored again
    other = tmp_path / "other-demos"  # another dataset: scored again, labelled with it
    shutil.copytree(tiny_demos, other)
    grid.write_text(grid.read_text().replace(str(tiny_demos), str(other)))
    assert main(["report", str(grid)]) == 0 and report.stat().st_mtime_ns != kept
    assert json.loads((report.parent / "scored.json").read_text())["demos"] == str(other.resolve())
    # the export, its paths relative to the checkout, reports from the checkout's root without the dataset
    monkeypatch.chdir(tmp_path.parent)
    export = Path(f"{tmp_path.name}-export")
    assert main(["report", str(grid), "--export", str(export)]) == 0
    assert (
        json.loads((export / "inest3" / "quality" / "scored.json").read_text())["demos"]
        == f"{tmp_path.name}/other-demos"
    )
    shutil.rmtree(other)
    exported = export / "grid.yaml"
    exported.write_text(
        yaml.safe_dump(
            {
                "methods": {"oracle": {}, "inest3": {}},
                "seeds": [0],
                "out": str(export),
                "demos": f"{tmp_path.name}/other-demos",
            }
        )
    )
    assert main(["report", str(exported)]) == 0
    assert f"| inest3 | inest | 3 | 2 | {mse:.4f} |" in (export / "report.md").read_text()
    (tmp_path / "inest3" / "quality").rename(tmp_path / "scored")
    (tmp_path / "inest3" / "seed0" / "config.json").write_text(
        json.dumps(small_train_config(reward="inest", model=str(tmp_path / "gone")).to_dict())
    )
    capsys.readouterr()
    assert main(["report", str(grid)]) == 2
    error = capsys.readouterr().err
    assert "reward quality of inest3" in error and error.count("\n") == 1, error


def test_the_shipped_grid_is_the_thesis_grid_and_its_methods_parse(monkeypatch):
    monkeypatch.chdir(ROOT)
    grid = GridConfig.from_yaml(ROOT / "inest_agent_node" / "config" / "grid.yaml")
    assert grid.demos == "runs/demos"
    grid = dataclasses.replace(grid, demos=None)  # the user's dataset, which plan checks is there
    assert (grid.seeds, grid.total_steps) == ((0, 1, 2), 500_000)
    ready = [name for name, method in grid.methods.items() if not method.model or Path(method.model).is_dir()]
    cells = {cell.name: cell.settings for cell in plan(grid, ready, ROOT)}
    expected = {  # method: reward, subtasks, intrinsic bonus, camera
        "inest3-embedding": ("inest", 3, "embedding", "ego"),
        "inest3-state": ("inest", 3, "state", "ego"),
        "inest3-none": ("inest", 3, "none", "ego"),
        "inest6-none": ("inest", 6, "none", "ego"),
        "xirl-ego": ("xirl", 3, "none", "ego"),
        "xirl-allo": ("xirl", 3, "none", "allo"),
        "holdr": ("holdr", 3, "none", "ego"),
        "reds": ("reds", 3, "none", "ego"),
        "oracle": ("env", 3, "none", "ego"),
    }
    assert set(grid.methods) == set(expected)
    thesis = {  # the thesis's tables 5.2-5.4 and 5.7: mean score, success rate
        "inest3-embedding": (0.73, 0.2245),
        "inest3-state": (0.51, 0.0),
        "inest3-none": (0.59, 0.1311),
        "inest6-none": (0.31, 0.0),
        "xirl-ego": (0.24, 0.0),
        "xirl-allo": (0.16, 0.0),
        "holdr": (0.05, 0.0),
        "reds": (0.0, 0.0),
    }
    references = {name: method.reference for name, method in grid.methods.items() if method.reference}
    assert {name: (ref.score, ref.success) for name, ref in references.items()} == thesis
    assert {key: set(table.methods) for key, table in grid.tables.items()} == {
        "subtasks": {"xirl-ego", "inest3-none", "inest6-none"},
        "intrinsic": {"inest3-none", "inest3-embedding", "inest3-state"},
        "baselines": {"inest3-embedding", "xirl-ego", "xirl-allo", "holdr", "reds", "oracle"},
    }
    assert {"inest3-embedding", "xirl-ego", "oracle"} <= set(ready)  # the committed model serves these
    for method in ready:
        settings = cells[f"{method}/seed2"]
        shown = (settings["reward"], settings["subtasks"], settings["intrinsic"]["mode"], settings["view"])
        assert shown == expected[method] and settings["total_steps"] == 500_000 and settings["threads"] == 1


@pytest.mark.parametrize(
    "path", sorted(p for p in (ROOT / "inest_agent_node" / "config").glob("*.yaml") if "methods:" in p.read_text())
)
def test_every_shipped_grid_parses_and_its_committed_models_serve_it(monkeypatch, path):
    monkeypatch.chdir(ROOT)
    grid = dataclasses.replace(GridConfig.from_yaml(path), demos=None)
    models = [method.model for method in grid.methods.values() if method.model]
    assert all((ROOT / model / "model.json").is_file() for model in models if model.startswith("results/"))
    ready = [name for name, method in grid.methods.items() if not method.model or Path(method.model).is_dir()]
    assert len(plan(grid, ready, ROOT)) == sum(len(grid.seeds_of(method)) for method in ready)


@pytest.mark.skipif(importlib.util.find_spec("ray") is None, reason="ray is not installed")
def test_ray_tasks_train_the_same_cells_into_the_same_layout(tmp_path, capsys, tiny_model):
    methods = {
        "oracle": {"args": ["--reward", "env"]},
        "inest3": {"args": ["--reward", "inest", "--intrinsic", "embedding"], "model": str(tiny_model)},
    }
    grid = write_grid(tmp_path, methods, [0])
    assert main(["run", str(grid), "--executor", "ray", "--address", "local", "--parallel", "2"]) == 0
    assert "finished oracle/seed0" in capsys.readouterr().out
    out = tmp_path / "out"
    for cell in ("oracle/seed0", "inest3/seed0"):
        assert json.loads((out / cell / "results.json").read_text())["steps"] == STEPS
        assert (out / f"{cell}.log").read_text().startswith(HEADER)
    inest = json.loads((out / "inest3" / "seed0" / "results.json").read_text())
    assert inest["config"]["reward"] == "inest" and inest["config"]["intrinsic"]["mode"] == "embedding"
    assert "coverage" in inest  # the learned reward's visited embeddings: it really scored frames
    report = (out / "report.md").read_text()
    assert "| oracle | 1 of 1 | 400 |" in report and "| inest3 | 1 of 1 | 400 |" in report
