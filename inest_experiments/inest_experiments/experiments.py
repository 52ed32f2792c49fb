"""`inest-experiments`: the thesis's experiments as one resumable grid of `inest-train` runs.

`inest-experiments run GRID.yaml [METHOD ...]` trains every method x seed of the grid
(config.GridConfig; example: inest_agent_node/config/grid.yaml) in OUT/<method>/seed<N>/, the layout
`inest-summarise` reads, with the cell's output in OUT/<method>/seed<N>.log. A cell holding
results.json is finished and skipped; one with a checkpoint is continued with `--resume`, one
stopped before its first checkpoint trained again (`--start-over`); so
a grid killed at any point continues where it stopped when the same command runs again.
OUT/grid.json records the grid and every cell's command and full training config; a cell that
has a run folder but whose settings have since changed is refused. Each cell is an inest-train
subprocess on one torch/JAX thread (`--threads 1`): `--parallel N` at a time on this machine
(the default), or with `--executor ray --address ADDR` Ray tasks of one CPU each on an existing
Ray cluster (`--address local` starts a private one of N CPUs). Ray workers run the same
command and write to the same paths, so every node must see the checkout, the virtual
environment and OUT at the same paths (a shared filesystem). A failed cell is named with its
log and the others go on; the exit status is 1 if any failed, 2 for bad input. At the end the
report is written.

`inest-experiments report GRID.yaml|OUT` writes OUT/report.md (per method: mean score with a
95 % bootstrap interval over seeds, success rate, 0/1/2/3-block shares and the method's
`reference` result if the grid gives one; per run; cells not finished), OUT/summary.json and
OUT/learning_curves.png (summary.py); with the grid's `tables`, each comparison first as its own
table with its figure OUT/learning_curves_<table>.png; with the grid's `demos`,
also every method's reward error against the environment's reward on those held-out
demonstrations (grid_quality.py). `--export DIR` then copies the report and every run's small
files, without checkpoints, into DIR: a results folder to commit or share.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import itertools
import json
import shlex
import shutil
import signal
import subprocess
import sys
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from inest_agent_node.diagnostics import EARLY_CLAIM_STEPS
from inest_agent_node.policy_export import ACTOR_FILE, POLICY_DIR, POLICY_FILE
from inest_agent_node.train import (
    CHECKPOINT_DIR,
    DIAGNOSTICS_FILE,
    HISTORY_FILE,
    RESULTS_FILE,
    continuation_flags,
    parse_args,
)
from inest_common.files import checkout_relative, read_json, read_run_file, write_atomic
from inest_common.processes import dies_with_parent
from inest_common.progress import track
from inest_common.settings import OneLineParser
from inest_reward_node.learning.labelled_rollouts import LABELLED_FILE
from inest_reward_node.learning.runs import CONFIG_FILE, merge_settings
from inest_reward_node.learning.stage_refit import REFIT_MODEL_DIR
from inest_reward_node.runtime.model import MODEL_FILE, WEIGHTS_FILE

from inest_agent_node.config import SPEED_ONLY_SETTINGS, setting_defaults

from .config import GridConfig, ReferenceResult
from .grid_quality import QUALITY_DIR, quality_table
from .summary import CURVES_FILE, SUMMARY_FILE, plot_curves, read_run, summarise, write_summary

GRID_FILE = "grid.json"
REPORT_FILE = "report.md"
# what `report --export` copies: the report's files, a run's own files, and while a run still
# trains its learning curve and reward diagnostics so far (from its checkpoint, export_results)
REPORT_FILES = (REPORT_FILE, SUMMARY_FILE, CURVES_FILE, GRID_FILE)
# a finished run's files an export keeps, at the same paths: with its exported policy and the
# stage classifier it refitted, `inest-evaluate` re-evaluates the copy (and the episodes it labelled
# in the loop say what the refit read)
RUN_FILES = (
    *(CONFIG_FILE, RESULTS_FILE, "learning_curve.png", "coverage.png", LABELLED_FILE),
    *(f"{POLICY_DIR}/{name}" for name in (ACTOR_FILE, POLICY_FILE)),
    *(f"{REFIT_MODEL_DIR}/{name}" for name in (MODEL_FILE, WEIGHTS_FILE)),
)
EXECUTORS = ("local", "ray")


@dataclass(frozen=True)
class Cell:
    """One method x seed: its run folder and the inest-train flags that train it (without --resume,
    which is decided when it starts). Paths are absolute, so a Ray worker anywhere finds them."""

    method: str
    seed: int
    run_dir: Path
    train_args: tuple[str, ...]
    workdir: Path  # the grid's working directory: relative paths in a method's args are read from it
    settings: dict[str, Any] = field(hash=False, compare=False, repr=False)  # the full TrainConfig

    @property
    def name(self) -> str:
        return f"{self.method}/seed{self.seed}"

    @property
    def log(self) -> Path:
        return self.run_dir.with_name(f"{self.run_dir.name}.log")

    @property
    def finished(self) -> bool:
        return (self.run_dir / RESULTS_FILE).is_file()


def train_settings(argv: list[str]) -> dict[str, Any]:
    """The training config inest-train would run `argv` with; its complaint as one ValueError line."""
    complaint = io.StringIO()
    try:
        with contextlib.redirect_stderr(complaint), contextlib.redirect_stdout(complaint):
            config, _ = parse_args(argv)
    except SystemExit:
        lines = complaint.getvalue().strip().splitlines() or ["not a valid inest-train command"]
        raise ValueError(lines[-1].removeprefix("inest-train: ")) from None
    except yaml.YAMLError as error:
        raise ValueError(" ".join(str(error).split())) from None
    return json.loads(json.dumps(config.to_dict()))  # as grid.json holds it: tuples as lists


def plan(grid: GridConfig, selected: list[str], workdir: Path) -> list[Cell]:
    """The cells of the `selected` methods (all if none), each checked by parsing its inest-train
    command, so that a typo fails here and not hours into the grid."""
    unknown = sorted(set(selected) - set(grid.methods))
    if unknown:
        raise ValueError(f"unknown method(s) {unknown}; the grid has {list(grid.methods)}")
    config = workdir / grid.config
    if not config.is_file():
        raise ValueError(f"no training config file at {config} (the grid's `config`)")
    if grid.demos is not None and not (workdir / grid.demos).is_dir():
        raise ValueError(f"no demonstration dataset at {workdir / grid.demos} (the grid's `demos`)")
    out = workdir / grid.out
    cells = []
    for method in selected or list(grid.methods):
        spec = grid.methods[method]
        model_args = ["--model", str(workdir / spec.model)] if spec.model is not None else []
        for seed in grid.seeds_of(method):
            run_dir = out / method / f"seed{seed}"
            args = ("--config", str(config), "--out", str(run_dir), "--seed", str(seed), "--threads", "1")
            args += ("--total-steps", str(grid.total_steps), *model_args, *spec.args)
            try:
                settings = train_settings(list(args))
            except ValueError as error:
                raise ValueError(f"method {method}: {error}") from None
            model = settings["model"]  # the grid's, else the training config's
            if settings["reward"] != "env" and model and not (workdir / model / "model.json").is_file():
                raise ValueError(f"method {method}: no reward model at {workdir / model} (model.json missing)")
            cells.append(Cell(method, seed, run_dir, args, workdir, settings))
    return cells


def record_grid(grid: GridConfig, cells: list[Cell], out: Path) -> None:
    """Write OUT/grid.json, keeping the cells an earlier run of a subset of methods recorded;
    refuse a cell whose run folder was made with other settings. Settings are compared with paths
    under the working directory relative to it, so an export copied back to OUT (`cp -r
    results/grid runs/grid`) continues as the grid it came from."""
    path = out / GRID_FILE
    recorded = read_run_file(path, read_json)["cells"] if path.exists() else {}
    root = Path.cwd().resolve()
    for cell in cells:
        before = recorded.get(cell.name)
        if before is not None and (cell.run_dir / CONFIG_FILE).exists():
            earlier = merge_settings(setting_defaults(), checkout_relative(before["config"], root))
            settings = checkout_relative(cell.settings, root)
            if differing := sorted(
                key
                for key in (earlier.keys() | settings.keys()) - SPEED_ONLY_SETTINGS
                if earlier.get(key) != settings.get(key)
            ):
                raise ValueError(
                    f"{cell.run_dir} was trained with other settings ({', '.join(differing)}): "
                    "remove that folder or pick another `out`"
                )
        recorded[cell.name] = {"command": ["inest-train", *cell.train_args], "config": cell.settings}
    document = {"grid": grid.to_dict(), "cells": recorded}
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(path, lambda temporary: temporary.write_text(json.dumps(document, indent=2) + "\n"))


def run_cell(cell: Cell) -> int:
    """Train one cell as an inest-train subprocess (continuing it if it had started), its output
    appended to its log; the exit status. The same function runs here and in a Ray worker."""
    command = [sys.executable, "-m", "inest_agent_node.train", *cell.train_args, *continuation_flags(cell.run_dir)]
    cell.run_dir.parent.mkdir(parents=True, exist_ok=True)
    with open(cell.log, "a") as log:
        log.write(f"# inest-experiments: {shlex.join(command)}\n")
        log.flush()
        return subprocess.run(
            command,
            stdout=log,
            stderr=subprocess.STDOUT,
            cwd=cell.workdir,
            check=False,
            # killed when the runner or Ray worker that started it dies, so that no orphaned run
            # trains on beside the one a rerun resumes
            preexec_fn=dies_with_parent(signal.SIGKILL),
        ).returncode


def failure(run: Callable[[], int]) -> str | None:
    """Why the cell that `run()` waits for failed (its exit status, or what waiting raised), or None."""
    try:
        status = run()
    except Exception as error:  # a cell that could not start or whose Ray task died: report it, go on
        return f"{type(error).__name__}: {error}".splitlines()[0]
    return None if status == 0 else f"exit status {status}"


def run_local(cells: list[Cell], parallel: int) -> Iterator[tuple[Cell, str | None]]:
    """Each cell as a subprocess of this process, `parallel` at a time, as they finish."""
    with ThreadPoolExecutor(max_workers=parallel) as pool:
        futures = {pool.submit(run_cell, cell): cell for cell in cells}
        for future in as_completed(futures):
            yield futures[future], failure(future.result)


def run_ray(cells: list[Cell], address: str, parallel: int) -> Iterator[tuple[Cell, str | None]]:
    """Each cell as a Ray task of one CPU on the cluster at `address` (`local`: a private instance
    of `parallel` CPUs), as they finish."""
    import ray

    try:
        if address == "local":
            ray.init(address="local", num_cpus=parallel, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, log_to_driver=False)
    except (ConnectionError, RuntimeError) as error:
        raise ValueError(f"cannot reach the Ray cluster at {address}: {error}".splitlines()[0]) from None
    try:
        task = ray.remote(num_cpus=1, max_retries=0)(run_cell)
        pending = {task.remote(cell): cell for cell in cells}
        while pending:
            [done], _ = ray.wait(list(pending), num_returns=1)
            yield pending.pop(done), failure(partial(ray.get, done))
    finally:
        ray.shutdown()


def run_grid(grid: GridConfig, selected: list[str], executor: str, address: str | None, parallel: int) -> int:
    """Train the grid's unfinished cells; 0 if every cell finished, 1 if any failed."""
    workdir = Path.cwd()
    cells = plan(grid, selected, workdir)
    out = workdir / grid.out
    record_grid(grid, cells, out)
    pending = [cell for cell in cells if not cell.finished]
    print(f"{len(cells)} cells, {len(cells) - len(pending)} finished, {len(pending)} to train in {out}", flush=True)
    results: Iterator[tuple[Cell, str | None]] = iter(())
    if pending and executor == "ray":
        results = run_ray(pending, address or "local", parallel)
    elif pending:
        results = run_local(pending, parallel)
    failed = []
    with track(total=len(pending), unit="cell", desc="grid", disable=not pending) as bar:
        for cell, problem in results:
            if problem is None:
                bar.write(f"finished {cell.name}")
            else:
                failed.append(cell)
                bar.write(f"inest-experiments: {cell.name} failed ({problem}); see {cell.log}")
            bar.update()
    if any(cell.finished for cell in cells):
        print(f"wrote {write_report(out, grid)}")
    if failed:
        print(f"inest-experiments: {len(failed)} of {len(pending)} cells failed: {', '.join(c.name for c in failed)}")
        return 1
    return 0


def format_steps(steps: list[int]) -> str:
    return ", ".join(f"{step // 1000}k" if step >= 1000 and step % 1000 == 0 else str(step) for step in steps)


def markdown_row(cells: list[str]) -> str:
    """One Markdown table row; an empty cell is written as `| |`, the same in every table."""
    return "|" + "".join(f" {cell} |" if cell else " |" for cell in cells)


def percent(share: float) -> str:
    return f"{100 * share:.0f}"


def reference_cell(reference: ReferenceResult | None) -> str:
    if reference is None:
        return ""
    success = "" if reference.success is None else f", {100 * reference.success:g} %"
    return f"{reference.score:g}{success}"  # as precise as the source gives it


def method_table(methods: list[str], summary: dict[str, Any], grid: GridConfig | None) -> list[str]:
    """The Markdown table of `methods`' final evaluations across seeds, with the grid's reference
    column when any of them has a reference result."""
    references = {m: grid.methods[m].reference for m in methods if m in grid.methods} if grid else {}
    label = f" {grid.reference_label}: score, success |" if grid and any(references.values()) else ""
    lines = [
        "| method | seeds | steps | layouts | mean score [95 % CI over seeds] | success | 0 / 1 / 2 / 3 blocks "
        f"| validation score | labelled episodes | cameras |{label}",
        "|---|---|---|---|---|---|---|---|---|---|" + ("---|" if label else ""),
    ]
    for method in methods:
        entry = summary["methods"].get(method)
        expected = len(grid.seeds_of(method)) if grid and method in grid.methods else None
        seeds = f"{entry['seeds'] if entry else 0}" + (f" of {expected}" if expected else "")
        reference = [reference_cell(references.get(method))] if label else []
        if entry is None:
            lines.append(markdown_row([method, seeds, "", "", "not finished", "", "", "", "", "", *reference]))
            continue
        low, high = entry["mean_score_ci95"]
        blocks = " / ".join(percent(share) for share in entry["blocks_share"])
        score = f"{entry['mean_score']:.3f} [{low:.3f}, {high:.3f}]"
        success = f"{100 * entry['success_rate']:.1f} %"
        validation = f"{entry['validation_mean_score']:.3f}" if "validation_mean_score" in entry else ""
        labelled = "" if entry.get("labelled_episodes") is None else str(entry["labelled_episodes"])
        cells = [method, seeds, format_steps(entry["steps"]), ", ".join(entry.get("layouts", [])), score, success]
        cells += [f"{blocks} %", validation, labelled, " + ".join(entry.get("cameras") or []), *reference]
        lines.append(markdown_row(cells))
    return lines


# the intervals the report ranks methods by: summary.json's key and the ranking line's wording
RANKINGS = {
    "mean_score_ci95": (
        "Ranking by mean score, methods with 2 or more seeds: {} ('>': the 95 % bootstrap intervals are apart;"
        " '≈': they overlap)."
    ),
    "mean_score_t95": "The same by 95 % Student t intervals, wider with few seeds: {}.",
}


def ranking(methods: list[str], summary: dict[str, Any], interval: str = "mean_score_ci95") -> str:
    """The `methods` with at least two finished seeds from the highest mean score down, each pair
    joined by '>' where the higher one's `interval` (a key of RANKINGS) lies wholly above the next
    one's, '≈' where the two overlap (one seed has no interval to compare). Overlap is not
    transitive, so the pairs further apart that the chain would misstate follow it: apart although
    only '≈' joins them (a ≈ b ≈ c with a > c), or overlapping although a '>' lies between them."""
    entries = summary["methods"]
    finished = sorted(
        (m for m in methods if m in entries and entries[m]["seeds"] > 1), key=lambda m: -entries[m]["mean_score"]
    )
    if len(finished) < 2:
        return ""

    def apart(higher: str, lower: str) -> bool:
        return entries[higher][interval][0] > entries[lower][interval][1]

    links = [apart(higher, lower) for higher, lower in itertools.pairwise(finished)]
    text = finished[0] + "".join(
        f" {'>' if link else '≈'} {lower}" for link, lower in zip(links, finished[1:], strict=True)
    )
    misread = [
        f"{finished[i]} {'>' if apart(finished[i], finished[j]) else '≈'} {finished[j]}"
        for i, j in itertools.combinations(range(len(finished)), 2)
        if j > i + 1 and apart(finished[i], finished[j]) != any(links[i:j])
    ]
    beyond = f" Not neighbours, where the chain reads otherwise: {', '.join(misread)}." if misread else ""
    return RANKINGS[interval].format(text) + beyond


def rankings(methods: list[str], summary: dict[str, Any]) -> list[str]:
    """The report's ranking lines under a table: by the bootstrap intervals, then by the t intervals."""
    return [line for interval in RANKINGS if (line := ranking(methods, summary, interval))]


# the reward diagnostics the report shows (inest_agent_node/diagnostics.py), as column title and key
DIAGNOSTIC_COLUMNS = {
    "reward / step": "reward_per_step",
    "shaping / step": "shaping_per_step",
    "bonus / step": "bonus_per_step",
    "intrinsic / step": "intrinsic_per_step",
    "blocks in order at episode end": "final_progress_mean",
    "episodes with an unearned completion": "unearned_completion_rate",
    "... claimed early, then earned": "early_claim_rate",
    "... never placed in time": "unplaced_claim_rate",
    "... never placed in the episode": "never_placed_claim_rate",
    "episodes with a placed block never claimed": "missed_rate",
}


def diagnostic(value: float, key: str) -> str:
    return f"{percent(value)} %" if key.endswith("_rate") else f"{value:.3g}"


def diagnostics_table(methods: list[str], rows: list[dict[str, Any]]) -> list[str]:
    """Per method, the mean over its finished seeds of what its reward paid for in the first and in
    the last diagnostics window of training: a reward the agent exploits shows its own reward
    rising while the blocks placed fall."""
    lines = [
        "",
        "What each reward paid for in training (each run's `reward_diagnostics`: its first → its last",
        "window of training episodes, mean over finished seeds; an unearned completion: the reward's",
        "stage claimed a block that had never been placed, split into claims its block earned within",
        f"{EARLY_CLAIM_STEPS} steps and claims of a block not placed in time; a placed block never claimed: one the",
        "reward missed, as long as the episode lasted; blank: the reward has no such part).",
        "",
        f"| method | {' | '.join(DIAGNOSTIC_COLUMNS)} |",
        "|---|" + "---|" * len(DIAGNOSTIC_COLUMNS),
    ]
    shown = False
    for method in methods:
        windows = [row["reward_diagnostics"] for row in rows if row["method"] == method and "reward_diagnostics" in row]
        if not windows:
            continue
        cells = []
        for key in DIAGNOSTIC_COLUMNS.values():
            first, last = ([window[which].get(key) for window in windows] for which in ("first", "last"))
            known = None not in first + last
            cells.append(f"{diagnostic(np.mean(first), key)} → {diagnostic(np.mean(last), key)}" if known else "")
        lines.append(markdown_row([method, *cells]))
        shown = True
    return lines if shown else []


def table_curves_file(key: str) -> str:
    return f"{Path(CURVES_FILE).stem}_{key}.png"


def write_report(out: Path, grid: GridConfig | None) -> Path:
    """OUT/report.md, summary.json and learning_curves.png from the runs under OUT. Methods in the
    grid's order (the given one, else OUT/grid.json's, else sorted), those without a finished run
    too; with the grid's `tables`, one table and learning-curve figure per comparison."""
    if grid is None and (out / GRID_FILE).exists():
        grid = GridConfig.from_dict(read_run_file(out / GRID_FILE, read_json)["grid"])
    summary = summarise(out)
    if not summary["runs"]:
        raise ValueError(f"no training runs under {out}/<method>/<run>/")
    found = sorted({row["method"] for row in summary["runs"]})
    methods = list(grid.methods) + [m for m in found if m not in grid.methods] if grid else found
    quality_lines: list[str] = []
    if grid and grid.demos:
        quality_lines, summary["reward_quality"] = quality_table(out, methods, Path(grid.demos))
    tables = grid.tables if grid else {}
    if grid:
        summary["tables"] = {key: asdict(table) for key, table in tables.items()}
        summary["references"] = {
            method: {"label": grid.reference_label, **asdict(spec.reference)}
            for method, spec in grid.methods.items()
            if spec.reference is not None
        }
    write_summary(out, summary, methods)
    lines = [
        f"# Experiment grid: {out}",
        "",
        "Final evaluations (each run's `final_eval_episodes` on the layouts in its row: `test`, which no",
        "choice of setting saw, or `legacy` for runs made before the validation/test split, evaluated where",
        "their settings were chosen); the mean score's 95 % bootstrap interval is over seeds; success: all",
        "three blocks in order; validation score: the same policies on the validation layouts.",
    ]
    for stale in set(out.glob(table_curves_file("*"))) - {out / table_curves_file(key) for key in tables}:
        stale.unlink()  # a table the grid no longer has
    for key, table in tables.items():
        figure = table_curves_file(key)
        plot_curves(summary["runs"], out / figure, list(table.methods), table.title, palette=methods)
        lines += ["", f"## {table.title}", "", *method_table(list(table.methods), summary, grid)]
        for order in rankings(list(table.methods), summary):
            lines += ["", order]
        lines += ["", f"![{table.title}: mean over seeds, band from the lowest to the highest seed]({figure})"]
    if tables:
        lines += ["", "## Every method"]
    lines += ["", *method_table(methods, summary, grid)]
    for order in rankings(methods, summary):
        lines += ["", order]
    lines += ["", "| run | steps | mean score | success | 0 / 1 / 2 / 3 blocks |", "|---|---|---|---|---|"]
    for row in sorted(summary["runs"], key=lambda row: (methods.index(row["method"]), row["run"])):
        name = f"{row['method']}/{row['run']}"
        steps = format_steps([row["steps"]])
        if row["final"]:
            blocks = " / ".join(percent(share) for share in row["blocks_share"])
            success = f"{100 * row['success_rate']:.1f} %"
            lines.append(markdown_row([name, steps, f"{row['mean_score']:.3f}", success, f"{blocks} %"]))
        else:
            lines.append(
                markdown_row([f"{name} (training)", steps, f"{row['mean_score']:.3f} (last evaluation)", "", ""])
            )
    if grid:
        started = {f"{row['method']}/{row['run']}" for row in summary["runs"]}
        missing = [f"{m}/seed{s}" for m in grid.methods for s in grid.seeds_of(m) if f"{m}/seed{s}" not in started]
        if missing:
            lines += ["", f"Not started, or before their first evaluation: {', '.join(missing)}."]
    lines += diagnostics_table(methods, [row for row in summary["runs"] if row["final"]])
    lines += quality_lines
    lines += [
        "",
        "![learning curves: mean over seeds, band from the lowest to the highest seed](learning_curves.png)",
    ]
    if not quality_lines:
        lines += ["", "Reward quality: set the grid's `demos` to a dataset to add each method's reward error."]
    (out / REPORT_FILE).write_text("\n".join(lines) + "\n")
    return out / REPORT_FILE


def export_results(out: Path, target: Path, runs: dict[str, dict[str, Any]]) -> None:
    """Copy OUT's report, the small files of the `runs` it covers (`method/run`: its row in
    summary.json) and each method's reward-quality report into `target` (checkpoints, replay
    buffers and TensorBoard logs stay behind); earlier copies of those runs and reports are
    replaced, not merged. A run the report read while it trained is copied as the report read it
    (its learning curve up to the report's step), even if it has evaluated or finished since.
    Paths under the working directory (the checkout the grid ran in) are written relative to it
    in the JSON copies, so they read the same in any checkout."""
    if target.resolve() == out.resolve():
        raise ValueError(f"--export {target} is the grid's own folder")
    target.mkdir(parents=True, exist_ok=True)
    copy = partial(copy_relative, root=Path.cwd().resolve())
    for name in REPORT_FILES:
        if (out / name).is_file():
            copy(out / name, target / name)
    for figure in target.glob(table_curves_file("*")):  # an earlier export's, perhaps of other tables
        figure.unlink()
    for figure in out.glob(table_curves_file("*")):  # the report's figure per table
        copy(figure, target / figure.name)
    for name, row in sorted(runs.items()):
        run, run_copy = out / name, target / name
        shutil.rmtree(run_copy, ignore_errors=True)
        run_copy.mkdir(parents=True)
        if row["final"]:
            files: tuple[str, ...] = RUN_FILES
        else:
            files = (CONFIG_FILE, f"{CHECKPOINT_DIR}/{DIAGNOSTICS_FILE}")
            now = read_run(run)  # its checkpoint's history, or the curve of a run finished since
            if now is not None:
                reported = [point for point in now["curve"] if point[0] <= row["steps"]]
                (run_copy / HISTORY_FILE).write_text(json.dumps(reported) + "\n")
        for file in files:
            if (run / file).is_file():
                kept = run_copy / (Path(file).name if file.startswith(CHECKPOINT_DIR) else file)
                kept.parent.mkdir(exist_ok=True)
                copy(run / file, kept)
    for quality in out.glob(f"*/{QUALITY_DIR}"):
        shutil.rmtree(target / quality.relative_to(out), ignore_errors=True)
        shutil.copytree(quality, target / quality.relative_to(out), copy_function=copy)


def copy_relative(source: Path | str, destination: Path | str, root: Path) -> None:
    """shutil.copy2, except that a JSON file's strings naming paths under `root` become relative to it."""
    if Path(source).suffix != ".json":
        shutil.copy2(source, destination)
        return
    document = checkout_relative(json.loads(Path(source).read_text()), root)
    Path(destination).write_text(json.dumps(document, indent=2) + "\n")


def positive(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(
        prog="inest-experiments", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    commands = parser.add_subparsers(dest="command", required=True, parser_class=OneLineParser)
    run = commands.add_parser("run", help="train the grid's unfinished cells, then write the report")
    run.add_argument("grid", type=Path, help="grid YAML file (inest_agent_node/config/grid.yaml)")
    run.add_argument("methods", nargs="*", help="only these methods (default: all)")
    run.add_argument("--parallel", type=positive, default=2, help="cells at a time (ray --address local: its CPUs)")
    run.add_argument("--executor", choices=EXECUTORS, default="local")
    run.add_argument("--address", help="the Ray cluster's address (ray start --head prints it), or local")
    report = commands.add_parser("report", help="write OUT/report.md, summary.json and learning_curves.png")
    report.add_argument("grid", type=Path, help="grid YAML file, or the grid's OUT folder")
    report.add_argument("--export", type=Path, metavar="DIR", help="then copy the results, without checkpoints, here")
    args = parser.parse_args(argv)
    try:
        if args.command == "report":
            grid = None if args.grid.is_dir() else GridConfig.from_yaml(args.grid)
            out = args.grid if grid is None else Path(grid.out)
            print(f"wrote {write_report(out, grid)}")
            if args.export:
                summary = read_run_file(out / SUMMARY_FILE, read_json)
                export_results(out, args.export, {f"{row['method']}/{row['run']}": row for row in summary["runs"]})
                print(f"exported the results to {args.export}")
            return 0
        if args.address and args.executor != "ray":
            raise ValueError("--address is for --executor ray")
        if args.executor == "ray":
            try:
                import ray  # noqa: F401  (checked before any cell starts)
            except ImportError:
                raise ValueError("--executor ray needs the ray package (pinned in requirements.txt)") from None
        return run_grid(GridConfig.from_yaml(args.grid), args.methods, args.executor, args.address, args.parallel)
    except ValueError as error:
        print(f"inest-experiments: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
