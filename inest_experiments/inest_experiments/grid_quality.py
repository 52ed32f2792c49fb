"""The grid report's reward-quality columns: each method's learned reward, scored as its runs
scored it (reward model, subtask scheme, RewardConfig), by `inest-reward-quality`'s report on
held-out demonstrations (the grid's `demos`, validation split).

The figures are the report's: MSE and MAE of the min-max-normalised learned reward against the
min-max-normalised environment reward per demonstration, and the goal-similarity error (each
subtask goal's min-max cosine similarity against a Gaussian bump over the subtask's true
frames), means over demonstrations. Each method's report is kept in OUT/<method>/quality/ with
what it scored (`scored.json`: dataset, model, scheme, reward settings) and reused while those
are the same (compared with paths relative to the working directory, so the copy `report
--export` makes, with paths relative to the checkout, is reused from the checkout's root without
the dataset); otherwise it is scored again.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from inest_common.files import checkout_relative, read_json, read_run_file, write_atomic
from inest_reward_node.learning.data import load_demos
from inest_reward_node.learning.quality import REPORT_FILE, evaluate, load_stage_frames
from inest_reward_node.learning.runs import CONFIG_FILE
from inest_reward_node.runtime.config import RewardConfig
from inest_reward_node.runtime.model import ModelError, load_model
from inest_sim_node.dataset import DatasetError

from inest_agent_node.config import reward_scheme

QUALITY_DIR = "quality"
SCORED_FILE = "scored.json"  # what the kept report scored: reused only for the same


def scored_reward(run_config: dict[str, Any]) -> tuple[str, int, dict[str, Any]] | None:
    """(model folder, subtask scheme, RewardScorer options) a run's learned reward used; None for
    the environment's reward."""
    reward = run_config["reward"]
    if reward == "env":
        return None
    options = {"config": RewardConfig(**run_config["learned_reward"])}
    return run_config["model"], reward_scheme(reward, run_config["subtasks"]), options


def method_quality(
    method_dir: Path, demos: Path, loaded: dict[tuple[str, int], list], progress_bar: bool = False
) -> dict[str, Any] | None:
    """The quality figures of the method whose runs lie in `method_dir` (from its first run's
    config), scoring them first if no report is kept; None for the environment's reward or a
    method without a run. `loaded` caches the demonstrations per (camera, image size)."""
    configs = sorted(method_dir.glob(f"*/{CONFIG_FILE}"))
    if not configs:
        return None
    run_config = read_run_file(configs[0], read_json)
    scored = scored_reward(run_config)
    if scored is None:
        return None
    model_dir, scheme, options = scored
    folder = method_dir / QUALITY_DIR
    what = {
        "demos": str(demos.resolve()),
        "model": str(Path(model_dir).resolve()),
        "subtasks": scheme,
        "learned_reward": run_config["learned_reward"],
    }
    kept = folder / SCORED_FILE
    root = Path.cwd().resolve()
    if (
        not (folder / REPORT_FILE).is_file()
        or not kept.is_file()
        or checkout_relative(read_run_file(kept, read_json), root) != checkout_relative(what, root)
    ):
        try:
            model = load_model(model_dir, view=run_config["view"], scheme=scheme)
            key = (model.view, model.image_size)
            if key not in loaded:
                loaded[key] = load_demos(demos, "valid", model.view, model.image_size, progress_bar=progress_bar)
            if not loaded[key]:
                raise DatasetError(f"{demos} has no validation demonstrations")
            frames = load_stage_frames(model, [scheme], options, demos, "valid", progress_bar=progress_bar)
            evaluate(
                model, loaded[key], [scheme], folder, progress_bar, options, negative_episodes=0, stage_frames=frames
            )
        except (ModelError, DatasetError) as error:
            raise ValueError(f"reward quality of {method_dir.name}: {error}") from None
        write_atomic(kept, lambda temporary: temporary.write_text(json.dumps(what, indent=2) + "\n"))
    summary = read_run_file(folder / REPORT_FILE, read_json)["schemes"][str(scheme)]
    return {
        "model": model_dir,
        "subtasks": scheme,
        "variant": summary["variant"],
        "demos": summary["demos"],
        **{f"reward_{key}": summary["reward_vs_env"][key] for key in ("mse", "mae")},
        "cosine_gaussian_mse": summary["cosine_gaussian_mse"],
    }


def quality_table(out: Path, methods: list[str], demos: Path) -> tuple[list[str], dict[str, dict[str, Any]]]:
    """The report's Markdown lines for the quality table and the figures per method."""
    loaded: dict[tuple[str, int], list] = {}
    figures = {}
    for method in methods:
        found = method_quality(out / method, demos, loaded)
        if found is not None:
            figures[method] = found
    if not figures:
        return [], figures
    lines = [
        "",
        f"Reward quality on the validation demonstrations of `{demos}`",
        "(`inest-reward-quality`'s report, kept in `<method>/quality/`): the learned reward against",
        "the environment's reward, both min-max normalised per demonstration; goal error: each",
        "subtask goal's cosine similarity against a Gaussian over the subtask's true frames. Lower",
        "is better; the oracle has none.",
        "",
        "| method | reward | subtasks | demos | reward MSE | reward MAE | goal error (cosine MSE) |",
        "|---|---|---|---|---|---|---|",
    ]
    for method, row in figures.items():
        lines.append(
            f"| {method} | {row['variant']} | {row['subtasks']} | {row['demos']} | {row['reward_mse']:.4f}"
            f" | {row['reward_mae']:.4f} | {row['cosine_gaussian_mse']:.4f} |"
        )
    return lines, figures
