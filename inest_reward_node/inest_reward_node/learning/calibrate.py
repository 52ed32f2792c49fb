"""Calibration of a pretrained encoder: goal embeddings, XIRL distance scale, subtask-completion
thresholds, per-subtask start distances and embeddings, the stage classifier (fitted by
stage_fitting.py) and the pixel stage head (runtime/stage_head.py), from the training demonstrations and
random, wrong-order and clip-file play.

`calibrate()` computes all of them for every subtask scheme (TCC: 1, 3 and 6 subtasks; HOLD-R: 1;
REDS: the one it was trained on, whose "goals" are its learned subtask embeddings, what its
subtask inference and the cosine-similarity report compare frames with); the functions above
it are its parts.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from inest_common.progress import track
from inest_sim_node.dataset import DatasetError

from ..runtime.methods import subtask_rewards
from ..runtime.model import ModelMetadata, RewardModel, SubtaskGoals, model_kind
from ..runtime.stage_window import StageWindow, window_features
from .clips import Clip, clip_file_labels, load_clips, random_play, wrong_order_play
from .config import CalibrationConfig, PretrainConfig
from .data import Demo, load_demos
from .demo_negatives import demo_negatives
from .stage_fitting import fit_stage_classifier, fit_stage_head, fit_stage_support
from .task_stages import demo_stages, true_stages


def goal_embeddings(embeddings: Sequence[np.ndarray], ends: Sequence[np.ndarray]) -> np.ndarray:
    """Goal of subtask i = mean embedding of the frames where subtask i ends. -> (subtasks, D)."""
    return np.mean([emb[end] for emb, end in zip(embeddings, ends, strict=True)], axis=0)


def xirl_distance_scale(embeddings: Sequence[np.ndarray], final_goal: np.ndarray) -> float:
    """XIRL's normaliser: 1 / mean distance from each demonstration's first frame to the goal."""
    first = np.stack([emb[0] for emb in embeddings])
    return float(1.0 / max(np.linalg.norm(first - final_goal, axis=1).mean(), 1e-8))


def subtask_starts(ends: np.ndarray) -> np.ndarray:
    """First frame of each subtask: frame 0, then the frame after the previous subtask ended."""
    return np.concatenate([[0], np.asarray(ends[:-1]) + 1])


def start_frames(embeddings: Sequence[np.ndarray], ends: Sequence[np.ndarray], subtask: int) -> np.ndarray:
    """(demos, D): each demonstration's embedding on the frame where `subtask` starts (its last frame
    if the start lies past it)."""
    return np.stack(
        [emb[min(int(subtask_starts(end)[subtask]), len(emb) - 1)] for emb, end in zip(embeddings, ends, strict=True)]
    )


def start_embeddings(embeddings: Sequence[np.ndarray], ends: Sequence[np.ndarray]) -> np.ndarray:
    """(subtasks, D): the mean embedding of the frames where each subtask starts (segment shaping's 0)."""
    return np.stack([start_frames(embeddings, ends, k).mean(axis=0) for k in range(len(ends[0]))])


def start_distances(embeddings: Sequence[np.ndarray], ends: Sequence[np.ndarray], goals: np.ndarray) -> list[float]:
    """d_k_start: per subtask k, the mean raw distance to goal k on the frame where subtask k starts
    (progress shaping's zero point). A start past a demonstration's last frame uses its last frame."""
    return [
        float(max(np.linalg.norm(start_frames(embeddings, ends, subtask) - goal, axis=1).mean(), 1e-8))
        for subtask, goal in enumerate(goals)
    ]


def subtask_windows(ends: np.ndarray, hold_steps: int) -> list[slice]:
    """The last `hold_steps` frames of each subtask, never reaching back into the previous one
    (a subtask that ends on the same frame as the one before it keeps just that frame)."""
    starts = subtask_starts(ends)
    return [
        slice(min(max(int(start), int(end) - hold_steps + 1), int(end)), int(end) + 1)
        for start, end in zip(starts, ends, strict=True)
    ]


def highest_held(rewards: np.ndarray, hold_steps: int) -> float:
    """The highest value that `rewards` stays above for `hold_steps` consecutive frames: a tracker
    with a lower threshold would complete on this sequence."""
    if len(rewards) < hold_steps:
        return -np.inf
    windows = np.lib.stride_tricks.sliding_window_view(rewards, hold_steps)
    return float(windows.min(axis=1).max())


def calibrate_thresholds(
    rewards_per_subtask: Callable[[int], Sequence[np.ndarray]],
    ends: Sequence[np.ndarray],
    num_subtasks: int,
    hold_steps: int,
    config: CalibrationConfig,
    negatives_per_subtask: Callable[[int], Sequence[np.ndarray]] | None = None,
) -> list[float]:
    """`rewards_per_subtask(i)` gives, per demonstration, subtask i's reward on every frame;
    `negatives_per_subtask(i)` the same for random-policy episodes (see CalibrationConfig)."""
    thresholds = []
    for subtask in range(num_subtasks):
        demos = list(zip(rewards_per_subtask(subtask), ends, strict=True))
        lows = [float(np.min(rewards[subtask_windows(end, hold_steps)[subtask]])) for rewards, end in demos]
        threshold = float(np.percentile(lows, config.percentile))
        negatives = [] if negatives_per_subtask is None else negatives_per_subtask(subtask)
        thresholds.append(raised_threshold(threshold, subtask, demos, negatives, hold_steps, config))
    return thresholds


def raised_threshold(
    threshold: float,
    subtask: int,
    demos: Sequence[tuple[np.ndarray, np.ndarray]],
    negatives: Sequence[np.ndarray],
    hold_steps: int,
    config: CalibrationConfig,
) -> float:
    """`threshold` raised until at most `false_fire_rate` of the `negatives` (per episode, the
    subtask's reward on every frame, -inf where it was really complete) would complete it, but
    never so far that fewer than `demo_pass_rate` of the `demos` ((subtask reward, subtask ends)
    per demonstration) complete it by `late_frames` after its end."""
    if not len(negatives):
        return threshold
    held_negatives = [highest_held(r, hold_steps) for r in negatives]
    negative_level = float(np.quantile(held_negatives, 1 - config.false_fire_rate, method="higher"))
    spans = [slice(int(subtask_starts(end)[subtask]), int(end[subtask]) + 1 + config.late_frames) for _, end in demos]
    demo_held = [highest_held(rewards[span], hold_steps) for (rewards, _), span in zip(demos, spans, strict=True)]
    ceiling = float(np.quantile(demo_held, 1 - config.demo_pass_rate, method="lower"))
    return max(threshold, min(negative_level, ceiling))


def calibrate(
    model: RewardModel, demos: list[Demo], config: PretrainConfig, progress_bar: bool = True
) -> dict[int, SubtaskGoals]:
    """Goal embeddings, XIRL scale, thresholds, start distances and embeddings and the stage classifier
    per subtask scheme, from the training demonstrations (and random, wrong-order and clip-file
    play, see CalibrationConfig)."""
    embeddings = [
        model.embed(demo.frames) for demo in track(demos, desc="embedding demos", leave=False, disable=not progress_bar)
    ]
    size = config.encoder.image_size
    calibration = config.calibration
    plays = random_play(config.view, size, calibration.random_episodes)
    negatives = [model.embed(play.frames) for play in plays]
    wrong_order = wrong_order_play(config.view, size, calibration.wrong_order_episodes)  # classifier only
    clips = [clip for path in calibration.clips for clip in load_clips(path, config.view, size)]
    clip_embeddings = [model.embed(clip.frames) for clip in clips]
    others = wrong_order + clips
    other_embeddings = [model.embed(clip.frames) for clip in wrong_order] + clip_embeddings
    # the labelled episodes the thresholds are raised against, and their embeddings
    raising, raising_embeddings = (
        (plays + clips, negatives + clip_embeddings) if calibration.clips_raise_thresholds else (plays, negatives)
    )
    head_episodes = (
        stage_head_episodes(config, demos, plays + others) if calibration.stage_head.iterations else ([], [])
    )
    schemes = (config.reds.subtasks,) if config.method == "reds" else model_kind(config.method).schemes
    labelled = set.intersection(*(set(demo.ends) for demo in demos))  # a person's file cuts 3 or 6 subtasks
    if not labelled.intersection(schemes):
        raise DatasetError(f"the demonstrations are cut into {sorted(labelled)} subtasks; this model needs {schemes}")
    schemes = tuple(scheme for scheme in schemes if scheme in labelled)
    result = {}
    for scheme in schemes:
        ends = [demo.ends[scheme] for demo in demos]
        goals = model.reds_subtask_embeddings() if config.method == "reds" else goal_embeddings(embeddings, ends)
        partial = SubtaskGoals(goals, [], xirl_distance_scale(embeddings, goals[-1]))
        rewards = [subtask_rewards(model, emb, partial) for emb in embeddings]
        negative_rewards = [subtask_rewards(model, emb, partial) for emb in raising_embeddings]

        def false_completions(subtask: int, scheme=scheme, negative_rewards=negative_rewards) -> list[np.ndarray]:
            """The negatives' reward for `subtask`, -inf where the subtask was really completed."""
            return [
                np.where(play.not_yet_completed(scheme, subtask), rewards[:, subtask], -np.inf)
                for play, rewards in zip(raising, negative_rewards, strict=True)
            ]

        partial.thresholds = calibrate_thresholds(
            lambda i, rewards=rewards: [r[:, i] for r in rewards],
            ends,
            scheme,
            config.shaping.hold_steps,
            calibration,
            false_completions,
        )
        partial.start_distances = start_distances(embeddings, ends, goals)
        partial.start_embeddings = start_embeddings(embeddings, ends)
        stages = [demo_stages(demo.progress, demo.labels[scheme], scheme) for demo in demos]
        negative_stages = [true_stages(clip.progress, clip.held, scheme) for clip in plays + others]
        partial.stage_classifier = fit_stage_classifier(
            embeddings, stages, scheme + 1, negatives + other_embeddings, negative_stages, calibration.classifier
        )
        if calibration.stage_support_quantile:
            partial.stage_support = fit_stage_support(
                embeddings,
                stages,
                scheme + 1,
                calibration.stage_support_quantile,
                calibration.stage_support_references,
            )
        if calibration.window_offsets:
            partial.stage_window = fit_stage_window(
                embeddings, stages, scheme + 1, negatives + other_embeddings, negative_stages, calibration
            )
        head = calibration.stage_head
        if head.iterations and scheme in calibration.stage_head_subtasks:
            labelled, played = head_episodes
            partial.stage_head = fit_stage_head(
                [demo.frames for demo in labelled] + [clip.frames for clip in played],
                [demo_stages(demo.progress, demo.labels[scheme], scheme) for demo in labelled]
                + [true_stages(clip.progress, clip.held, scheme) for clip in played],
                scheme + 1,
                head,
                progress_bar,
            )
        result[scheme] = partial
    return result


def fit_stage_window(
    embeddings: list[np.ndarray],
    stages: list[np.ndarray],
    num_stages: int,
    negatives: list[np.ndarray],
    negative_stages: list[np.ndarray],
    calibration: CalibrationConfig,
) -> StageWindow:
    """The window stage classifier on every episode's windows: the demonstrations', the labelled
    negatives' and the demonstrations rewound and reordered (demo_negatives.py)."""
    offsets = calibration.window_offsets
    rebuilt = demo_negatives(stages, calibration.demo_negatives, calibration.classifier.seed)
    negatives = negatives + [embeddings[demo][order] for demo, order in rebuilt]
    negative_stages = negative_stages + [stages[demo][order] for demo, order in rebuilt]
    classifier = fit_stage_classifier(
        [window_features(episode, offsets) for episode in embeddings],
        stages,
        num_stages,
        [window_features(episode, offsets) for episode in negatives],
        negative_stages,
        calibration.classifier,
    )
    return StageWindow(offsets, classifier)


def stage_head_episodes(config: PretrainConfig, demos: list[Demo], plays: list[Clip]) -> tuple[list[Demo], list[Clip]]:
    """The labelled demonstrations and play the pixel stage head is fitted on, in the camera it
    reads. `plays`: the calibration's random, wrong-order and clip-file play in the encoder's
    camera. A head of another camera sees the same demonstrations and the same random and
    wrong-order episodes (their seeds fix them) through its own; clip files record one camera,
    so it is fitted without the encoder's and with `stage_head_clips`, recorded through its own."""
    head = config.calibration.stage_head
    view = head.view or config.view
    size = config.encoder.image_size
    calibration = config.calibration
    own = [clip for path in calibration.stage_head_clips for clip in load_clips(path, view, size)]
    if view == config.view:
        return demos[: head.max_demos], plays + own
    labelled = load_demos(config.dataset, "train", view, size, min(head.max_demos, len(demos)), progress_bar=False)
    return labelled, random_play(view, size, calibration.random_episodes) + wrong_order_play(
        view, size, calibration.wrong_order_episodes
    ) + own


def supervision(
    config: PretrainConfig,
    demonstrations: int,
    schemes: Sequence[int] = (1, 3, 6),
    segmented_by: str = "dataset (the simulator's subtask ends)",
) -> dict[str, object]:
    """What a model's calibration was fitted on, the labelling budget a robot user has to pay
    to fit the same (model.json `supervision`): the demonstrations and who segmented them into
    subtasks, every kind of labelled negative episode with its count and its labeller, and the
    cameras the reward then needs."""
    calibration = config.calibration
    negatives: dict[str, dict[str, object]] = {
        "random_play": {"episodes": calibration.random_episodes, "labelled_by": "simulator"},
        "wrong_order": {"episodes": calibration.wrong_order_episodes, "labelled_by": "simulator"},
    }
    head = calibration.stage_head
    heads = [scheme for scheme in calibration.stage_head_subtasks if scheme in schemes] if head.iterations else []
    files = [("clips", path) for path in calibration.clips]
    files += [("stage-head-clips", path) for path in calibration.stage_head_clips] if heads else []
    for kind, path in files:
        episodes, labelled_by = clip_file_labels(path)
        negatives[f"{kind}:{path}"] = {"episodes": episodes, "labelled_by": labelled_by}
    cameras = [config.view] + ([head.view] if heads and head.view not in (None, config.view) else [])
    return {
        "demonstrations": {"episodes": demonstrations, "segmented_by": segmented_by},
        "negatives": negatives,
        "labelled_episodes": sum(int(entry["episodes"]) for entry in negatives.values()),
        "simulator_labelled_episodes": sum(
            int(entry["episodes"]) for entry in negatives.values() if entry["labelled_by"] == "simulator"
        ),
        "stage_heads": {"subtask_schemes": list(heads), "camera": head.view or config.view} if heads else None,
        "cameras": cameras,
    }


def recorded_supervision(metadata: ModelMetadata) -> dict[str, object]:
    """The model's `supervision`; for a model calibrated before it was recorded, its labelled
    negative episodes and cameras as its calibration record gives them (`derived`: True; None
    episodes when a clip file it was fitted on is no longer there to count)."""
    if metadata.supervision:
        return metadata.supervision
    calibration = metadata.calibration
    episodes: int | None = calibration.get("random_episodes", 0) + calibration.get("wrong_order_episodes", 0)
    for path in calibration.get("clips", []):
        episodes = episodes + clip_file_labels(path)[0] if episodes is not None and Path(path).is_file() else None
    heads = {goals.stage_head.config.view for goals in metadata.subtasks.values() if goals.stage_head is not None}
    return {
        "labelled_episodes": episodes,
        "simulator_labelled_episodes": episodes,
        "cameras": [metadata.view, *sorted(view for view in heads if view not in (None, metadata.view))],
        "derived": True,
    }


def describe_supervision(record: dict[str, object]) -> str:
    """model.json `supervision` in one line: `fitted on 800 demonstrations and 10 labelled negative
    episodes (5 random_play, 5 wrong_order; 10 by the simulator); cameras: ego`."""
    cameras = "+".join(record["cameras"])
    if record.get("derived"):
        return (
            f"{record['labelled_episodes']} labelled negative episodes by the simulator (its calibration "
            f"record; calibrated before supervision was recorded); cameras: {cameras}"
        )
    negatives = record["negatives"]
    kinds = ", ".join(
        f"{entry['episodes']} {kind}" if "episodes" in entry else f"{entry['frames']} unlabelled {kind} frames"
        for kind, entry in negatives.items()
        if entry.get("episodes", entry.get("frames"))
    )
    return (
        f"fitted on {record['demonstrations']['episodes']} demonstrations and {record['labelled_episodes']} labelled "
        f"negative episodes ({kinds or 'none'}; {record['simulator_labelled_episodes']} by the simulator); "
        f"cameras: {cameras}"
    )
