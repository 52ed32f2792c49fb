"""A person's labels spent on the agent's own episodes, in the loop: the few labelled episodes a
robot user can pay for, placed where the policy is rather than on random play.

At each labelling step (`label_at`) a round opens: the agent's next `label_episodes` training
episodes in which the reward claimed a stage (those a person watching `inest-monitor` would check)
are labelled with their true stage on every frame; the completion thresholds are raised against
them and the stage classifier refitted with them (stage_refit.py), kept for every later refit.
The simulator stands in for the person, who would mark the frame where each block enters the
goal in a clip label file (`inest-record-clips`, then `inest-reward-quality --clips`); the labels
are the same, since a stage holds from one marked frame to the next. Only episodes that start
once a round is open are recorded, so each is whole. The labelled episodes are kept in
RUN/labelled-rollouts.npz: a resumed run keeps them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..runtime.rewards import RewardParts, Steps
from .task_stages import privileged_stages

LABELLED_FILE = "labelled-rollouts.npz"


class RolloutLabelling:
    """Records whole training episodes while labels are owed, keeps those the reward claimed a stage in."""

    def __init__(self, scheme: int, num_envs: int, label_at: tuple[int, ...], per_round: int) -> None:
        self.scheme, self.label_at, self.per_round = scheme, label_at, per_round
        self.recording: list[list[tuple[np.ndarray, int, int]] | None] = [None] * num_envs
        self.episodes: list[tuple[np.ndarray, np.ndarray]] = []  # (embeddings, true stages) per episode
        self.owed = 0  # episodes the rounds opened so far ask for
        self.refitted_with = 0  # labelled episodes the last refit read

    def open_rounds(self, steps: int) -> None:
        """The rounds due by training step `steps` are open."""
        self.owed = self.per_round * sum(at <= steps for at in self.label_at)

    @property
    def wanted(self) -> int:
        return self.owed - len(self.episodes)

    def round_complete(self) -> bool:
        """Every episode owed is labelled and the classifier has not been refitted on them yet."""
        return self.wanted <= 0 and len(self.episodes) > self.refitted_with

    def observe(self, steps: Steps, parts: RewardParts) -> None:
        """One scored batch (rows in environment order within each round); nothing to do, on the
        training's hot path, while no round is open and no episode is being recorded."""
        if self.wanted <= 0 and not any(record is not None for record in self.recording):
            return
        truth = privileged_stages(steps.states, self.scheme)
        for row, env in enumerate(steps.envs):
            record = self.recording[env]
            if record is not None:
                record.append((parts.embeddings[row], int(truth[row]), int(parts.completed[row])))
            if steps.episode_ends[row]:
                if record and self.wanted > 0 and any(claimed for _, _, claimed in record):
                    self.episodes.append(
                        (np.stack([frame for frame, _, _ in record]), np.array([stage for _, stage, _ in record]))
                    )
                self.recording[env] = [] if self.wanted > 0 else None

    def save(self, run_dir: Path) -> None:
        embeddings, stages = zip(*self.episodes, strict=True)
        np.savez(
            run_dir / LABELLED_FILE,
            embeddings=np.concatenate(embeddings),
            stages=np.concatenate(stages),
            lengths=np.array([len(episode) for episode in stages]),
        )

    def restore(self, run_dir: Path) -> None:
        """The episodes a run labelled before it was stopped, all of them refitted on already."""
        if not (run_dir / LABELLED_FILE).exists():
            return
        with np.load(run_dir / LABELLED_FILE) as data:
            ends = np.cumsum(data["lengths"])[:-1]
            self.episodes = list(zip(np.split(data["embeddings"], ends), np.split(data["stages"], ends), strict=True))
        self.refitted_with = len(self.episodes)
