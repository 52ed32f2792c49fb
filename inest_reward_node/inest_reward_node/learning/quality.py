"""Reward quality of a trained model on held-out demonstrations (`inest-reward-quality`, thesis 5.3).

Per subtask scheme the model has (its default reward: xirl for 1 subtask, inest for 3 and 6,
holdr for HOLD-R models, reds for REDS models on their own segmentation; a REDS model's
"goal embeddings" are its subtask embeddings), over the validation demonstrations:
- reward vs environment: both per-frame traces are min-max normalised to [0, 1] within each
  demonstration (the learned and the oracle reward live on unrelated scales; only the shape
  is comparable), then MSE, MAE and bias = mean(learned - env) are averaged over demonstrations.
- cosine-similarity Gaussians: for each subtask, the cosine similarity of every frame's
  embedding to the subtask's goal embedding, min-max normalised per demonstration, against the
  ground truth: a Gaussian centred on the frame where the subtask really ends, with a standard
  deviation of half that subtask's length; MSE averaged over subtasks and demonstrations.
- Spearman rank correlation of the total reward with progress (frame index / length; the
  demonstrations are near-optimal, so time is progress) and with the environment reward.
  The total includes the subtask bonus, a staircase that rises with every tracker completion
  and so is monotone by construction: it flatters a reward whose shaping within a subtask is
  flat (report key `spearman_progress_total_incl_bonus`, also kept as `spearman_progress`).
- tracker replay: share of demonstrations on which a fresh subtask tracker marks every subtask
  done, and how many frames each (first) completion lands from the true subtask end.

Per subtask k (report key `per_subtask`, one entry per subtask, in order):
- spearman_shaping_within: Spearman of the shaping term (RewardParts.shaping: the reward
  without subtask bonus and without intrinsic bonus) against time, over the frames whose TRUE
  stage is k (k subtasks really done, task_stages.demo_stages: the frame on which subtask k counts
  is already stage k + 1, as it is for the reward, which pays that frame the bonus and shapes
  it towards the next goal); median and mean over the demonstrations that have at least 3
  such frames. spearman_embedding_within: the same for the negated raw
  embedding distance to goal k, so the representation and the shaping can be told apart.
- switch_dip: total reward on the frame after the tracker's completion of k minus the frame
  before it (total[s + 1] - total[s - 1], s = the frame on which the tracker first marks k
  done); negative = a dip, the agent is paid less just after the switch than just before it.
  Median and worst (min) over the demonstrations where both frames exist (the last subtask
  usually completes on a demonstration's final frame, so it rarely has one).
- completion_lag_frames: the tracker's (first) completion frame minus the true end frame
  (negative = early), median and mean over the demonstrations where it completed; miss_rate:
  share of demonstrations on which it never marked k done.
- false_completion_rate: on negatives, share of episodes in which a fresh tracker marks k done
  (at least once) on a frame where k is not really complete: the environment's ordered
  progress < k + 1 for 3 subtasks, per the scheme's labels for 6, progress < 3 for 1.
  Negatives: `random` (uniform random actions, clips.random_play) and `wrong_order` (the
  scripted expert placing blue, then red, then yellow), --negative-episodes of each, 100 steps,
  on layout seeds no other episode uses (random from 41,000,000, wrong order from 41,500,000;
  calibration's random and wrong-order play use 40,000,000 and 40,500,000 on;
  --negative-seed-offset moves both, for a selection set); the camera frame after every step is
  scored, as in training. `false_completion_any`: with any subtask.
- false_not_early_rate: the same, counting only false completions that no true completion of
  k followed within NOT_EARLY_AFTER frames (an early switch is false, but the episode earned it).

With --exploit-suite, the report adds `exploit_suite`: per scheme, the suite part's unplaced
claims, early claims and misses per subtask and per policy (exploit_suite: trained policies' own
rollouts, re-rendered through this model's cameras), beside the random and wrong-order rates.

Every reward is scored through `RewardScorer` (`rewards.replay`) with the RewardConfig that
inest-train's flags of the same names set, so the report can be run per shaping / tracker
variant, e.g. `--shaping thesis --tracker threshold`. `--stage-source privileged` (DIAGNOSTIC)
replays every episode with its true stage and bonus, from its recorded progress: the shaping
columns then measure the shaping alone, without the tracker's lag or errors. Writes
report.json (with the model's config, the scorer options and each scheme's resulting scorer
config) and PNG plots into --out.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from inest_common.progress import track
from inest_common.settings import OneLineParser, add_setting_flags, build_settings
from inest_sim_node.dataset import DatasetError
from inest_sim_node.expert import WRONG_ORDER
from inest_sim_node.world import BLOCK_COLOURS
from scipy.stats import spearmanr

from ..runtime.config import RewardConfig
from ..runtime.methods import default_variant
from ..runtime.model import ModelError, RewardModel, load_model
from ..runtime.rewards import Replay, RewardScorer, replay
from .calibrate import describe_supervision, recorded_supervision, subtask_starts
from .clips import Clip, ClipError, load_clips, random_play, wrong_order_play
from .data import Demo, load_demos
from .exploit_suite import (
    SUITE_DIR,
    SuiteEpisode,
    SuitePart,
    claims,
    load_part,
    pay,
    suite_file,
    summarise_claims,
    summarise_pay,
)
from .task_stages import demo_stages, true_stages

REPORT_FILE = "report.json"
NEGATIVE_SEEDS = {"random": 41_000_000, "wrong_order": 41_500_000}  # layouts no other episode uses
DEFAULT_NEGATIVE_EPISODES = 40
MIN_WITHIN_FRAMES = 3  # fewer frames of a subtask: no within-subtask correlation for that demonstration


NOT_EARLY_AFTER = 5  # a false completion the true one follows within this many frames was only early
SETTLE_FRAMES = 10  # copies of a demonstration's last frame the tracker replay goes on over


def min_max(values: np.ndarray) -> np.ndarray:
    values = np.asarray(values, dtype=np.float64)
    span = values.max() - values.min()
    if np.isnan(span):  # no environment reward (a robot's recording): undefined, not flat
        return values
    return (values - values.min()) / span if span > 0 else np.zeros_like(values)


def cosine_similarity(embeddings: np.ndarray, goal: np.ndarray) -> np.ndarray:
    norms = np.linalg.norm(embeddings, axis=1) * np.linalg.norm(goal)
    return embeddings @ goal / np.maximum(norms, 1e-12)


def ground_truth_gaussian(length: int, start: int, end: int) -> np.ndarray:
    sigma = max((end - start + 1) / 2.0, 1.0)
    return np.exp(-0.5 * ((np.arange(length) - end) / sigma) ** 2)


def rank_correlation(a: np.ndarray, b: np.ndarray) -> float:
    if np.ptp(a) == 0 or np.ptp(b) == 0:
        return 0.0
    return float(spearmanr(a, b).statistic)


def subtask_name(scheme: int, subtask: int) -> str:
    """Short name for tables: 'all' (1 subtask), the block's colour (3), 'grasp red' / 'push red' (6)."""
    if scheme == 1:
        return "all"
    if scheme == 3:
        return BLOCK_COLOURS[subtask]
    return f"{'grasp' if subtask % 2 == 0 else 'push'} {BLOCK_COLOURS[subtask // 2]}"


# --- per-subtask metrics of one trace ------------------------------------------------------
def within_subtask_spearman(values: np.ndarray, labels: np.ndarray, num_subtasks: int) -> np.ndarray:
    """(subtasks,) Spearman of `values` against the frame index over the frames labelled k.

    `values`: (N,), or (N, subtasks) to correlate column k for subtask k. NaN where fewer than
    MIN_WITHIN_FRAMES frames carry label k; 0 where the values are constant on them."""
    values = np.asarray(values, dtype=np.float64)
    labels = np.asarray(labels)
    frames = np.arange(len(labels))
    result = np.full(num_subtasks, np.nan)
    for k in range(num_subtasks):
        mask = labels == k
        if mask.sum() >= MIN_WITHIN_FRAMES:
            column = values[:, k] if values.ndim == 2 else values
            result[k] = rank_correlation(column[mask], frames[mask])
    return result


def switch_dips(total: np.ndarray, completion_frames: Sequence[int], num_subtasks: int) -> np.ndarray:
    """(subtasks,) total[s + 1] - total[s - 1] around the frame s on which the tracker completed k
    (negative = a dip); NaN where k never completed or a neighbouring frame does not exist."""
    dips = np.full(num_subtasks, np.nan)
    for k, frame in enumerate(list(completion_frames)[:num_subtasks]):
        if frame >= 1 and frame + 1 < len(total):
            dips[k] = float(total[frame + 1] - total[frame - 1])
    return dips


def completion_lags(completion_frames: Sequence[int], ends: np.ndarray) -> np.ndarray:
    """(subtasks,) tracker completion frame minus true end frame (negative = early); NaN if missed."""
    lags = np.full(len(ends), np.nan)
    for k, (frame, end) in enumerate(zip(completion_frames, ends, strict=False)):
        lags[k] = frame - int(end)
    return lags


def false_completions(events: Sequence[Sequence[int]], episode: Clip, scheme: int, early_frames: int = 0) -> np.ndarray:
    """(subtasks,) bool: the tracker marked k done (on the frames `events[k]`, see
    Replay.completion_events) at least once on a frame where k was not really complete
    (`Clip.not_yet_completed`: the ordered progress, mapped through the scheme's labels) and
    did not really complete within the next `early_frames` frames either (0: any false frame
    counts; NOT_EARLY_AFTER tells an early completion from one the episode never earns)."""
    flags = np.zeros(len(events), dtype=bool)
    for k, frames in enumerate(events):
        not_done = episode.not_yet_completed(scheme, k)
        flags[k] = any(bool(not_done[frame : frame + early_frames + 1].all()) for frame in frames)
    return flags


# --- negative episodes -----------------------------------------------------------------------
def record_negatives(
    view: str, image_size: int, episodes: int, clip_files: Sequence[str] = (), seed_offset: int = 0
) -> dict[str, list[Clip]]:
    """`episodes` random-policy (clips.random_play) and `episodes` wrong-order expert episodes, on
    the layout seeds NEGATIVE_SEEDS[kind] + seed_offset + i, frames after every step; and, if given, every
    clip of `clip_files` (kind "clips", e.g. a trained policy's own rollouts)."""
    negatives = {
        "random": random_play(view, image_size, episodes, seed=NEGATIVE_SEEDS["random"] + seed_offset),
        "wrong_order": wrong_order_play(
            view, image_size, episodes, NEGATIVE_SEEDS["wrong_order"] + seed_offset, (WRONG_ORDER,)
        ),
    }
    if clip_files:
        negatives["clips"] = [clip for path in clip_files for clip in load_clips(path, view, image_size)]
    return negatives


def describe_negatives(
    negatives: dict[str, list[Clip]], clip_files: Sequence[str] = (), seed_offset: int = 0
) -> dict[str, Any]:
    """What the negatives were, per kind, with the true ordered progress they reached."""
    policies = {
        "random": "uniform random actions",
        "wrong_order": f"scripted expert, block order {list(WRONG_ORDER)} (blue, red, yellow)",
        "clips": f"labelled clip files {list(clip_files)}",
    }
    described = {}
    for kind, episodes in negatives.items():
        described[kind] = {
            "episodes": len(episodes),
            "first_seed": NEGATIVE_SEEDS[kind] + seed_offset if kind in NEGATIVE_SEEDS else None,
            "policy": policies[kind],
            "true_final_progress_mean": float(np.mean([e.progress[-1] for e in episodes])) if episodes else None,
            "true_progress_max": int(max(e.progress.max() for e in episodes)) if episodes else None,
        }
    return described


def negative_events(
    model: RewardModel,
    episodes: list[Clip],
    embeddings: list[np.ndarray],
    scheme: int,
    variant: str,
    scorer_options: dict[str, Any] | None = None,
    stage_episodes: list[Clip] | None = None,
) -> list[list[list[int]]]:
    """Per negative episode, a fresh scorer's completion frames of every subtask
    (Replay.completion_events). `stage_episodes`: the same episodes through the stage head's
    camera, when it is another."""
    events = []
    seen = stage_episodes or episodes
    for episode, embedded, viewed in zip(episodes, embeddings, seen, strict=True):
        stages = true_stages(episode.progress, episode.held, scheme)
        played = replay(model, embedded, scheme, variant, scorer_options, viewed.frames, stages)
        events.append(played.claims())
    return events


def event_flags(events: list[list[list[int]]], episodes: list[Clip], scheme: int, early_frames: int = 0) -> np.ndarray:
    """(episodes, subtasks) bool: false_completions of each episode's `events` (negative_events)."""
    rows = [false_completions(row, clip, scheme, early_frames) for row, clip in zip(events, episodes, strict=True)]
    return np.stack(rows) if rows else np.zeros((0, 0), dtype=bool)


@dataclass
class Negatives:
    """Negative episodes per kind through the encoder's camera (`clips`) and the stage head's
    (`seen`, the same episodes when it is the encoder's), with their embeddings."""

    clips: dict[str, list[Clip]]
    seen: dict[str, list[Clip]]
    embeddings: dict[str, list[np.ndarray]]

    def events(
        self, model: RewardModel, scheme: int, variant: str, scorer_options: dict[str, Any] | None
    ) -> dict[str, list[list[list[int]]]]:
        """Per kind, negative_events of every episode."""
        return {
            kind: negative_events(model, clips, self.embeddings[kind], scheme, variant, scorer_options, self.seen[kind])
            for kind, clips in self.clips.items()
        }


def play_negatives(
    model: RewardModel,
    camera: str | None,
    episodes: int,
    clip_files: Sequence[str] = (),
    seed_offset: int = 0,
) -> Negatives:
    """record_negatives through the model's camera and, when the stage head reads `camera`, through it too."""
    clips = record_negatives(model.view, model.image_size, episodes, clip_files, seed_offset)
    seen = clips if camera is None else record_negatives(camera, model.image_size, episodes, seed_offset=seed_offset)
    embeddings = {kind: [model.embed(clip.frames) for clip in kind_clips] for kind, kind_clips in clips.items()}
    return Negatives(clips, seen, embeddings)


def suite_events(
    model: RewardModel,
    part: SuitePart,
    schemes: list[int],
    scorer_options: dict[str, Any] | None = None,
    progress_bar: bool = True,
) -> Iterator[tuple[SuiteEpisode, Clip, dict[int, Replay]]]:
    """Per episode of the exploit suite `part`, one at a time: the episode, its clip through the
    model's camera (then SETTLE_FRAMES copies of its last frame, as demonstrations are replayed)
    and, per scheme, the scheme's default reward replayed over it (Replay.completion_events: the
    claims; Replay.completed: the pay)."""
    camera = stage_camera(model, schemes, scorer_options)
    for episode in track(part.episodes, desc="exploit suite", disable=not progress_bar):
        clip = part.clip(episode, model.view, model.image_size, SETTLE_FRAMES)
        seen = clip if camera is None else part.clip(episode, camera, model.image_size, SETTLE_FRAMES)
        embeddings = model.embed(clip.frames)
        replays = {
            scheme: replay(
                model,
                embeddings,
                scheme,
                default_variant(model, scheme),
                scorer_options,
                seen.frames,
                true_stages(clip.progress, clip.held, scheme),
            )
            for scheme in schemes
        }
        yield episode, clip, replays


def suite_report(
    model: RewardModel,
    part: SuitePart,
    schemes: list[int],
    scorer_options: dict[str, Any] | None = None,
    progress_bar: bool = True,
) -> dict[str, Any]:
    """Per scheme, the claims (exploit_suite.summarise_claims) and the pay (summarise_pay) of the
    scheme's default reward on the exploit suite `part`, over suite_events."""
    rows: dict[int, list[dict[str, np.ndarray]]] = {scheme: [] for scheme in schemes}
    paid: dict[int, list[dict[str, int]]] = {scheme: [] for scheme in schemes}
    for _, clip, replays in suite_events(model, part, schemes, scorer_options, progress_bar):
        for scheme, played in replays.items():
            rows[scheme].append(claims(played.claims(), clip, scheme))
            paid[scheme].append(pay(played.completed, clip, scheme))
    policies = [episode.policy for episode in part.episodes]
    schemes_report = {
        str(scheme): summarise_claims(rows[scheme], policies) | summarise_pay(paid[scheme]) for scheme in schemes
    }
    return {**part.describe(), "schemes": schemes_report}


def format_suite(suite: dict[str, Any]) -> list[str]:
    """The suite's rates per scheme and subtask, one line each."""
    lines = [
        f"exploit suite, {suite['part']} part ({suite['episodes']} episodes of {suite['policies']} policies): "
        "unplaced claims / early claims / misses"
    ]
    for scheme, row in suite["schemes"].items():
        lines.append(
            f"  {scheme} subtasks: unplaced claim of any subtask in {row['unplaced_claim_any']:.1%} of episodes"
        )
        if "overpaid_frame_share" in row:  # scores made before the pay was measured lack it
            lines.append(
                f"  paid for a block not in the goal on {row['overpaid_frame_share']:.1%} of frames, short on "
                f"{row['underpaid_frame_share']:.1%}; episodes ending overclaimed {row['ends_overclaimed_rate']:.1%}"
            )
        for sub in row["per_subtask"]:
            cells = [_number(sub[key], ".1%", 8) for key in ("unplaced_claim_rate", "early_claim_rate", "miss_rate")]
            name = subtask_name(int(scheme), sub["subtask"])
            lines.append(
                f"  {sub['subtask'] + 1} {name:<13}{''.join(cells)}   ({sub['episodes_completing']} completing)"
            )
    return lines


# --- one demonstration ---------------------------------------------------------------------
@dataclass
class DemoQuality:
    """One demonstration's numbers under one scheme."""

    reward: np.ndarray  # learned reward per frame
    env: np.ndarray  # environment reward per frame (frame 0 repeats frame 1's)
    cosine: np.ndarray  # (frames, subtasks)
    gaussians: np.ndarray  # (frames, subtasks)
    replay: Replay
    ends: np.ndarray
    stages: np.ndarray  # (frames,) the true stage of every frame: subtasks really done
    metrics: dict[str, float]
    within_shaping: np.ndarray  # (subtasks,) within_subtask_spearman of the shaping term
    within_embedding: np.ndarray  # (subtasks,) the same of -raw embedding distance to goal k
    dips: np.ndarray  # (subtasks,) switch_dips
    lags: np.ndarray  # (subtasks,) completion_lags


def demo_quality(
    model: RewardModel,
    demo: Demo,
    embeddings: np.ndarray,
    scheme: int,
    variant: str,
    scorer_options: dict[str, Any] | None = None,
    stage_frames: np.ndarray | None = None,
) -> DemoQuality:
    """`stage_frames`: the demonstration through the stage head's camera, when it is another."""
    # a demonstration ends on the frame where its last block counts, while an episode goes on:
    # the tracker may confirm the last subtask on the frames after, so it is replayed over
    # SETTLE_FRAMES more copies of the last frame (per-frame metrics use the demonstration's own)
    seen = demo.frames if stage_frames is None else stage_frames
    stages = demo_stages(demo.progress, demo.labels[scheme], scheme)
    settled = replay(
        model,
        np.concatenate([embeddings, np.repeat(embeddings[-1:], SETTLE_FRAMES, 0)]),
        scheme,
        variant,
        scorer_options,
        np.concatenate([seen, np.repeat(seen[-1:], SETTLE_FRAMES, 0)]),
        np.concatenate([stages, np.repeat(stages[-1:], SETTLE_FRAMES)]),
    )
    played = Replay(settled.parts.select(slice(0, len(embeddings))), settled.num_subtasks)  # the scorer is causal
    # a robot's recording has no environment reward: the metrics against it are undefined (null)
    rewards = demo.rewards if demo.rewards is not None else np.full(len(demo) - 1, np.nan)
    env = np.concatenate([rewards[:1], rewards]).astype(np.float64)
    goals = model.goals(scheme).goals
    ends = demo.ends[scheme]
    starts = subtask_starts(ends)
    cosine = np.stack([cosine_similarity(embeddings, goal) for goal in goals], axis=1)
    gaussians = np.stack([ground_truth_gaussian(len(demo), s, e) for s, e in zip(starts, ends, strict=True)], axis=1)
    learned, oracle = min_max(played.rewards), min_max(env)
    progress = np.arange(len(demo)) / max(len(demo) - 1, 1)
    completions = settled.completion_frames
    offsets = [frame - int(end) for frame, end in zip(completions, ends, strict=False)]
    metrics = {
        "mse": float(np.mean((learned - oracle) ** 2)),
        "mae": float(np.mean(np.abs(learned - oracle))),
        "bias": float(np.mean(learned - oracle)),
        "cosine_gaussian_mse": float(
            np.mean([np.mean((min_max(cosine[:, i]) - gaussians[:, i]) ** 2) for i in range(len(goals))])
        ),
        "spearman_progress": rank_correlation(played.rewards, progress),
        "spearman_env": rank_correlation(played.rewards, env),
        "tracker_all_completed": float(settled.all_completed),
        "completion_offset_frames": float(np.mean(offsets)) if offsets else float("nan"),
    }
    distances = np.linalg.norm(embeddings[:, None, :] - goals[None], axis=-1)
    return DemoQuality(
        reward=played.rewards,
        env=env,
        cosine=cosine,
        gaussians=gaussians,
        replay=played,
        ends=ends,
        stages=stages,
        metrics=metrics,
        within_shaping=within_subtask_spearman(played.shaping, stages, len(goals)),
        within_embedding=within_subtask_spearman(-distances, stages, len(goals)),
        dips=switch_dips(settled.rewards, completions, len(goals)),
        lags=completion_lags(completions, ends),
    )


# --- summaries ---------------------------------------------------------------------------
def finite_or_none(value: float) -> float | None:
    """JSON has no NaN: undefined statistics are written as null."""
    value = float(value)
    return value if math.isfinite(value) else None


def finite_stats(values: np.ndarray, **statistics: Callable[[np.ndarray], float]) -> dict[str, float | None]:
    """Each named statistic over the finite values (None when there are none)."""
    finite = np.asarray(values, dtype=np.float64)
    finite = finite[np.isfinite(finite)]
    return {name: finite_or_none(function(finite)) if len(finite) else None for name, function in statistics.items()}


def per_subtask_summary(
    results: list[DemoQuality],
    scheme: int,
    negatives: dict[str, np.ndarray],
    not_early: dict[str, np.ndarray] | None = None,
) -> list[dict[str, Any]]:
    """One entry per subtask (see the module doc); `negatives[kind]`: (episodes, subtasks) false
    completions, `not_early[kind]` those of them no true completion followed within NOT_EARLY_AFTER frames."""
    within_shaping = np.stack([r.within_shaping for r in results])
    within_embedding = np.stack([r.within_embedding for r in results])
    dips = np.stack([r.dips for r in results])
    lags = np.stack([r.lags for r in results])
    rows = []
    for k in range(within_shaping.shape[1]):
        rows.append(
            {
                "subtask": k,
                "name": subtask_name(scheme, k),
                "spearman_shaping_within": {
                    **finite_stats(within_shaping[:, k], median=np.median, mean=np.mean),
                    "demos": int(np.isfinite(within_shaping[:, k]).sum()),
                },
                "spearman_embedding_within": {
                    **finite_stats(within_embedding[:, k], median=np.median, mean=np.mean),
                    "demos": int(np.isfinite(within_embedding[:, k]).sum()),
                },
                "switch_dip": {
                    **finite_stats(dips[:, k], median=np.median, min=np.min),
                    "switches": int(np.isfinite(dips[:, k]).sum()),
                },
                "completion_lag_frames": {
                    **finite_stats(lags[:, k], median=np.median, mean=np.mean),
                    "completed": int(np.isfinite(lags[:, k]).sum()),
                },
                "miss_rate": float(np.mean(~np.isfinite(lags[:, k]))),
                "false_completion_rate": {
                    kind: float(flags[:, k].mean()) if len(flags) else None for kind, flags in negatives.items()
                },
                "false_not_early_rate": {
                    kind: float(flags[:, k].mean()) if len(flags) else None for kind, flags in (not_early or {}).items()
                },
            }
        )
    return rows


def summarise(results: list[DemoQuality]) -> dict[str, Any]:
    table = {key: np.array([r.metrics[key] for r in results]) for key in results[0].metrics}
    spearman_total = {
        "median": float(np.median(table["spearman_progress"])),
        "mean": float(table["spearman_progress"].mean()),
    }
    return {
        "demos": len(results),
        "reward_vs_env": {key: float(table[key].mean()) for key in ("mse", "mae", "bias")},
        "cosine_gaussian_mse": float(table["cosine_gaussian_mse"].mean()),
        "spearman_progress_total_incl_bonus": spearman_total,
        "spearman_progress": dict(spearman_total),  # the same numbers, under the key older reports use
        "spearman_env": {
            "median": float(np.median(table["spearman_env"])),
            "mean": float(table["spearman_env"].mean()),
        },
        "tracker_pass_rate": float(table["tracker_all_completed"].mean()),
        "completion_offset_frames_mean": float(np.nanmean(table["completion_offset_frames"]))
        if np.isfinite(table["completion_offset_frames"]).any()
        else None,
    }


SUMMARY_NOTES = {
    "spearman_progress_total_incl_bonus": "Spearman of the TOTAL reward (subtask-bonus staircase included, monotone "
    "by construction) with time; median/mean over demonstrations. `spearman_progress` holds the same numbers.",
    "per_subtask": "per subtask k: within-subtask Spearman vs time of the shaping term (reward without bonus and "
    "intrinsic) and of -embedding distance to goal k, over the frames whose true subtask is k; switch dip "
    "total[s+1] - total[s-1] at the tracker's completion frame s (negative = dip); completion lag (tracker minus "
    "true end, frames) and miss rate; false-completion rate on random and wrong-order negatives, and of those "
    "false completions the share no true completion followed within a few frames (false_not_early_rate). Details: "
    "the module doc in `normalisation`.",
    "false_completion_any": "share of negative episodes with a false completion of any subtask",
    "scorer": "the scorer each scheme was scored with: reward variant and RewardConfig after the scorer options",
}


# --- plots -----------------------------------------------------------------------------------
def plot_scheme(results: list[DemoQuality], title: str, path: Path, examples: int = 3) -> None:
    """Top row: learned vs environment reward (normalised); middle row: cosine curves vs ground truth;
    bottom row: the shaping term (reward without bonus) on each true subtask's frames, tracker
    completions as grey lines, true subtask ends dotted."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = results[:examples]
    figure, axes = plt.subplots(3, len(shown), figsize=(4.2 * len(shown), 9), squeeze=False)
    colours = plt.get_cmap("tab10")
    for column, result in enumerate(shown):
        top, middle, bottom = axes[0, column], axes[1, column], axes[2, column]
        completions = result.replay.completion_frames
        top.plot(min_max(result.reward), label="learned (normalised)")
        top.plot(min_max(result.env), "--", label="environment (normalised)")
        for frame in completions:
            top.axvline(frame, color="grey", alpha=0.4, linewidth=0.8)
        top.set(title=f"demo {column}: reward", xlabel="frame")
        for i in range(result.cosine.shape[1]):
            middle.plot(min_max(result.cosine[:, i]), color=colours(i), label=f"subtask {i + 1}")
            middle.plot(result.gaussians[:, i], "--", color=colours(i), alpha=0.6)
        middle.set(title="cosine to each goal (dashed: ideal)", xlabel="frame")
        frames = np.arange(len(result.stages))
        shaping = result.replay.shaping
        for i in range(result.cosine.shape[1]):
            mask = result.stages == i
            label = f"true stage {i + 1}"
            bottom.plot(frames[mask], shaping[mask], ".-", color=colours(i), markersize=3, label=label)
            bottom.axvline(int(result.ends[i]), color=colours(i), linestyle=":", linewidth=1.0)
        for frame in completions:
            bottom.axvline(frame, color="grey", alpha=0.6, linewidth=1.0)
        rhos = ", ".join("-" if not np.isfinite(rho) else f"{rho:.2f}" for rho in result.within_shaping)
        bottom.set_title(f"shaping by true stage, rho {rhos}", fontsize=9)
        bottom.set(xlabel="frame (grey: tracker completions)", ylabel="reward without bonus")
    axes[0, 0].legend(fontsize=8)
    axes[1, 0].legend(fontsize=8)
    axes[2, 0].legend(fontsize=7)
    figure.suptitle(title)
    figure.tight_layout()
    figure.savefig(path, dpi=90)
    plt.close(figure)


# --- scorer options ----------------------------------------------------------------------------
class ScorerOptionError(ValueError):
    """RewardScorer refuses the scorer options given."""


def described_model(model: RewardModel) -> dict[str, Any]:
    """The model's description for a report: its metadata with each scheme's thresholds, not the
    goals and stage classifiers fitted with them (model.json holds those; a report stays small)."""
    described = model.metadata.to_dict()
    subtasks = described["subtasks"]
    described["subtasks"] = {scheme: {"thresholds": goals["thresholds"]} for scheme, goals in subtasks.items()}
    return described


def reward_config(settings: dict[str, Any]) -> RewardConfig:
    """The scorers' RewardConfig from the command line's reward settings, refused in one line."""
    try:
        return build_settings(RewardConfig, settings, "reward setting(s)")
    except ValueError as error:
        raise ScorerOptionError(f"bad reward settings: {error}") from None


def json_ready(options: dict[str, Any] | None) -> dict[str, Any]:
    """Scorer options for report.json: config dataclasses as dicts."""
    return {
        key: dataclasses.asdict(value) if dataclasses.is_dataclass(value) else value
        for key, value in (options or {}).items()
    }


def figure_title(scorer: dict[str, Any], scheme: int, view: str) -> str:
    """A quality figure's title for people, from the scorer's description (describe_scorer)."""
    title = f"{scorer['variant'].upper()} reward, {scheme} subtask{'s' * (scheme > 1)}, {view} camera"
    config = scorer["config"]
    if config is None:
        return title
    evidence = {"pixels": "the pixel stage head", "embedding": "the embedding's stage classifier"}
    stage = f"{config['tracker']} tracker" + (
        f" reading {evidence.get(scorer['stage_evidence'], scorer['stage_evidence'])}"
        if config["tracker"] == "confirmed"
        else ""
    )
    if config["stage_source"] != "tracker":
        stage = f"{config['stage_source']} stage"
    return f"{title}\n{config['shaping']} shaping, {stage}"


def format_options(options: dict[str, Any] | None) -> str:
    return " ".join(f"{key}={json.dumps(value)}" for key, value in json_ready(options).items())


def describe_scorer(
    model: RewardModel, scheme: int, variant: str, scorer_options: dict[str, Any] | None
) -> dict[str, Any]:
    """The scorer the options make (what report.json records per scheme); ScorerOptionError when
    RewardScorer refuses them, so that a bad option fails before any work."""
    try:
        scorer = RewardScorer(model, scheme, variant, **(scorer_options or {}))
    except (TypeError, ValueError, AttributeError) as error:
        raise ScorerOptionError(
            f"RewardScorer does not accept the scorer options {format_options(scorer_options)}: {error}"
        ) from error
    config = getattr(scorer, "config", None)
    return {
        "variant": scorer.variant,
        "config": dataclasses.asdict(config) if dataclasses.is_dataclass(config) else None,
        "stage_evidence": getattr(scorer, "evidence", None),  # "auto" resolved for this model
    }


def check_scorer_options(model: RewardModel, schemes: list[int], scorer_options: dict[str, Any] | None) -> None:
    for scheme in schemes:
        describe_scorer(model, scheme, default_variant(model, scheme), scorer_options)


def stage_camera(model: RewardModel, schemes: list[int], scorer_options: dict[str, Any] | None) -> str | None:
    """The camera these scorers' pixel stage head reads when it is not the encoder's (every
    episode must then be seen through both), else None."""
    cameras = [
        RewardScorer(model, scheme, default_variant(model, scheme), **(scorer_options or {})).stage_camera
        for scheme in schemes
    ]
    return next((camera for camera in cameras if camera), None)


def load_stage_frames(
    model: RewardModel,
    schemes: list[int],
    scorer_options: dict[str, Any] | None,
    dataset: str | Path,
    split: str,
    limit: int | None = None,
    progress_bar: bool = True,
) -> list[np.ndarray] | None:
    """The demonstrations' frames through the stage head's camera (`stage_camera`); None when it
    reads the encoder's."""
    camera = stage_camera(model, schemes, scorer_options)
    if camera is None:
        return None
    return [demo.frames for demo in load_demos(dataset, split, camera, model.image_size, limit, progress_bar)]


# --- the report --------------------------------------------------------------------------------
def evaluate(
    model: RewardModel,
    demos: list[Demo],
    schemes: list[int],
    out: Path,
    progress_bar: bool = True,
    scorer_options: dict[str, Any] | None = None,
    negative_episodes: int = DEFAULT_NEGATIVE_EPISODES,
    clip_files: Sequence[str] = (),
    stage_frames: list[np.ndarray] | None = None,
    negative_seed_offset: int = 0,
    suite: SuitePart | None = None,
) -> dict[str, Any]:
    """The report over `demos` for every scheme, with `negative_episodes` negatives of each kind
    (layout seeds moved by `negative_seed_offset`), the clips of `clip_files` and the exploit suite part `suite`;
    every reward is scored by `RewardScorer(model, scheme, variant, **scorer_options)`. A stage
    head that reads another camera than the encoder needs the demonstrations through it
    (`stage_frames`, load_stage_frames); the negatives are played through both."""
    camera = stage_camera(model, schemes, scorer_options)
    if camera is not None and (stage_frames is None or len(stage_frames) != len(demos)):
        raise ValueError(f"the stage head reads the {camera!r} camera: pass the demonstrations' frames of it")
    if camera is not None and clip_files:
        raise ClipError(
            f"clip files record one camera, and the stage head reads the {camera!r} camera beside the encoder's"
        )
    out.mkdir(parents=True, exist_ok=True)
    embeddings = [
        model.embed(demo.frames) for demo in track(demos, desc="embedding", disable=not progress_bar, leave=False)
    ]
    with track(total=1, desc="negative episodes", disable=not progress_bar, leave=False) as bar:
        played = play_negatives(model, camera, negative_episodes, clip_files, negative_seed_offset)
        bar.update(1)
    negatives = played.clips
    report: dict[str, Any] = {
        "model": described_model(model),
        "supervision": recorded_supervision(model.metadata),
        "normalisation": __doc__,
        "scorer_options": json_ready(scorer_options),
        "negatives": describe_negatives(negatives, clip_files, negative_seed_offset),
        "notes": SUMMARY_NOTES,
        "schemes": {},
    }
    for scheme in schemes:
        variant = default_variant(model, scheme)
        scorer = describe_scorer(model, scheme, variant, scorer_options)
        results = [
            demo_quality(model, demo, emb, scheme, variant, scorer_options, frames)
            for demo, emb, frames in zip(demos, embeddings, stage_frames or [None] * len(demos), strict=True)
        ]
        events = played.events(model, scheme, variant, scorer_options)
        flags = {kind: event_flags(events[kind], negatives[kind], scheme) for kind in negatives}
        not_early = {kind: event_flags(events[kind], negatives[kind], scheme, NOT_EARLY_AFTER) for kind in negatives}
        summary = {"variant": variant, "scorer": scorer, **summarise(results)}
        summary["per_subtask"] = per_subtask_summary(results, scheme, flags, not_early)
        summary["false_completion_any"] = {
            kind: float(rows.any(axis=1).mean()) if len(rows) else None for kind, rows in flags.items()
        }
        plot_path = out / f"quality_{variant}_{scheme}.png"
        plot_scheme(results, figure_title(scorer, scheme, model.view), plot_path)
        summary["plot"] = plot_path.name
        report["schemes"][str(scheme)] = summary
    if suite is not None:
        report["exploit_suite"] = suite_report(model, suite, schemes, scorer_options, progress_bar)
    (out / REPORT_FILE).write_text(json.dumps(report, indent=2) + "\n")
    return report


SUBTASK_COLUMNS = (  # the summary table's per-subtask columns: title, width
    ("shaping rho", 12),
    ("embed rho", 10),
    ("dip med", 9),
    ("dip min", 9),
    ("lag med", 9),
    ("lag mean", 9),
    ("miss", 7),
    ("false rand", 11),
    ("false wrong", 12),
    ("false clips", 12),
    ("not early r/w", 14),
)


def _number(value: float | str | None, spec: str, width: int) -> str:
    return f"{'-' if value is None else format(value, spec):>{width}}"


def _rate_pair(rates: dict[str, float | None]) -> str:
    """Random / wrong-order rates as one cell, e.g. 0.0/2.5%."""
    return "/".join("-" if rates.get(kind) is None else f"{100 * rates[kind]:.1f}" for kind in NEGATIVE_SEEDS) + "%"


def format_summary(report: dict[str, Any]) -> str:
    lines = [f"model: {describe_supervision(report['supervision'])}"] if "supervision" in report else []
    if report.get("scorer_options"):
        lines.append(f"scorer options: {format_options(report['scorer_options'])}")
    header = "variant  subtasks  spearman(progress, total incl. bonus)  tracker pass  MSE    MAE    bias    cosine-MSE"
    for scheme, row in report["schemes"].items():
        env = row["reward_vs_env"]
        lines.append(header)
        lines.append(
            f"{row['variant']:<8} {scheme:>8}  {row['spearman_progress_total_incl_bonus']['median']:>37.3f}  "
            f"{row['tracker_pass_rate']:>12.1%}  {env['mse']:.3f}  {env['mae']:.3f}  {env['bias']:+.3f}  "
            f"{row['cosine_gaussian_mse']:.3f}"
        )
        lines.append("  subtask".ljust(17) + "".join(f"{title:>{width}}" for title, width in SUBTASK_COLUMNS))
        for sub in row["per_subtask"]:
            false = sub["false_completion_rate"]
            values = (
                (sub["spearman_shaping_within"]["median"], ".3f"),
                (sub["spearman_embedding_within"]["median"], ".3f"),
                (sub["switch_dip"]["median"], "+.3f"),
                (sub["switch_dip"]["min"], "+.3f"),
                (sub["completion_lag_frames"]["median"], "+.1f"),
                (sub["completion_lag_frames"]["mean"], "+.1f"),
                (sub["miss_rate"], ".1%"),
                (false.get("random"), ".1%"),
                (false.get("wrong_order"), ".1%"),
                (false.get("clips"), ".1%"),
                (_rate_pair(sub.get("false_not_early_rate", {})), ""),
            )
            cells = "".join(
                _number(value, spec, width) for (value, spec), (_, width) in zip(values, SUBTASK_COLUMNS, strict=True)
            )
            lines.append(f"  {sub['subtask'] + 1} {sub['name']:<13}{cells}")
    negatives = report.get("negatives", {})
    if negatives:
        counts = ", ".join(f"{entry['episodes']} {kind}" for kind, entry in negatives.items())
        lines.append(
            f"rho: median within-subtask Spearman vs time; dip: total after - before each completion; "
            f"false: share of negative episodes ({counts}); not early: false completions no true completion "
            f"followed within {NOT_EARLY_AFTER} frames"
        )
    if "exploit_suite" in report:
        lines += format_suite(report["exploit_suite"])
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("model", help="model folder (a pretraining run's model/)")
    parser.add_argument("dataset", help="demonstration dataset; its validation split is used")
    parser.add_argument("--out", required=True, help="folder for report.json and the plots")
    parser.add_argument("--schemes", type=int, nargs="*", help="subtask schemes (default: all the model has)")
    parser.add_argument("--split", default="valid", choices=("train", "valid"))
    parser.add_argument("--limit", type=int, help="use only the first N demonstrations")
    parser.add_argument(
        "--negative-episodes",
        type=int,
        default=DEFAULT_NEGATIVE_EPISODES,
        help="random-policy and wrong-order episodes, each, for the false-completion rates (0 skips them)",
    )
    parser.add_argument(
        "--negative-seed-offset",
        type=int,
        default=0,
        help="moves the negatives' layout seeds, for a selection set the reported figures never see",
    )
    parser.add_argument("--clips", nargs="+", default=[], metavar="FILE", help="labelled clip files, negatives too")
    parser.add_argument(
        "--exploit-suite",
        metavar="FILE",
        help=f"an exploit suite part to count claims on (the committed one: {suite_file(SUITE_DIR, 'development')})",
    )
    reward_flags = add_setting_flags(
        parser.add_argument_group("how the reward scores (RewardConfig; the same flags as inest-train's)"),
        RewardConfig,
    )
    args = parser.parse_args(argv)
    if min(args.negative_episodes, args.negative_seed_offset) < 0:
        parser.error("--negative-episodes and --negative-seed-offset must be >= 0")
    try:
        reward_settings = reward_flags.overrides(args)
        scorer_options = {"config": reward_config(reward_settings)} if reward_settings else {}
        model = load_model(args.model)
        schemes = args.schemes or sorted(model.subtasks)
        for scheme in schemes:
            model.goals(scheme)
        check_scorer_options(model, schemes, scorer_options)
        suite = None if args.exploit_suite is None else load_part(args.exploit_suite)
        demos = load_demos(args.dataset, args.split, model.view, model.image_size, args.limit)
        if not demos:
            raise DatasetError(f"{args.dataset} has no {args.split} demonstrations")
        report = evaluate(
            model,
            demos,
            schemes,
            Path(args.out),
            scorer_options=scorer_options,
            negative_episodes=args.negative_episodes,
            clip_files=args.clips,
            stage_frames=load_stage_frames(model, schemes, scorer_options, args.dataset, args.split, args.limit),
            negative_seed_offset=args.negative_seed_offset,
            suite=suite,
        )
    except (ModelError, DatasetError, ScorerOptionError, ClipError) as error:
        print(f"inest-reward-quality: {error}", file=sys.stderr)
        return 2
    print(format_summary(report))
    print(f"wrote {Path(args.out) / REPORT_FILE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
