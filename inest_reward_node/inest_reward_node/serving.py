"""Serving the learned reward to live camera streams, without ROS: the reward node's logic.

Frames arrive one at a time from one or more streams (a simulator or camera each); whatever
has arrived when the node gets to it is scored in one encoder forward pass. Frames are keyed
by their stamp: a stream's frames must come in stamp order; a repeat of the last scored
stamp (a simulator re-publishing after a restart of this node or of the agent) gets the
cached reward again instead of moving the tracker twice; an older stamp is rejected as stale.
"""

from __future__ import annotations

import dataclasses
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from .encoders import resize_frames
from .rewards import RewardScorer


@dataclass
class ScoredFrame:
    stream: int
    stamp: int  # nanoseconds, the image's own stamp
    total: float
    distance: float
    bonus: float
    intrinsic: float
    subtask: int
    completed_subtask: bool
    received: float  # time.perf_counter() when the frame arrived
    frame_id: str = ""  # the image's frame, handed back for the reward's header
    repeated: bool = False  # the cached reward of an already scored stamp


@dataclass
class ServingStats:
    """Counters and latencies since the last report (diagnostics)."""

    scored: int = 0
    repeated: int = 0
    rejected: int = 0
    dropped: int = 0
    last_rejection: str = ""
    latencies: list[float] = field(default_factory=list)  # seconds, arrival -> scored
    batches: int = 0
    since: float = field(default_factory=time.perf_counter)

    def summary(self) -> dict[str, float | int | str]:
        elapsed = max(time.perf_counter() - self.since, 1e-9)
        latencies = np.array(self.latencies) * 1e3 if self.latencies else np.zeros(1)
        return {
            "rate_hz": self.scored / elapsed,
            "latency_p50_ms": float(np.percentile(latencies, 50)),
            "latency_p99_ms": float(np.percentile(latencies, 99)),
            "mean_batch": self.scored / max(self.batches, 1),
            "scored": self.scored,
            "repeated": self.repeated,
            "rejected": self.rejected,
            "dropped": self.dropped,
            "last_rejection": self.last_rejection,
        }


class StreamScorer:
    """Batches frames from several streams into one scorer, one tracker per stream. The scorer's
    RewardConfig (the node's `reward.*` parameters) decides shaping and tracker; a tracker may now
    reopen a subtask, so a stream's `subtask` can go down."""

    def __init__(self, scorer: RewardScorer, max_pending: int = 4) -> None:
        if scorer.config.stage_source == "privileged":
            raise ValueError("a privileged stage (a diagnostic) needs state vectors; served streams carry images only")
        self.scorer = scorer
        self.max_pending = max_pending  # per stream: older waiting frames are dropped (counted)
        self.pending: list[deque[tuple[int, np.ndarray, float, str]]] = [deque() for _ in range(scorer.num_envs)]
        self.last: list[ScoredFrame | None] = [None] * scorer.num_envs
        self.stats = ServingStats()

    @property
    def num_pending(self) -> int:
        return sum(len(queue) for queue in self.pending)

    def reject(self, reason: str) -> None:
        self.stats.rejected += 1
        self.stats.last_rejection = reason

    def submit(
        self, stream: int, stamp: int, frame: np.ndarray, received: float | None = None, frame_id: str = ""
    ) -> None:
        queue = self.pending[stream]
        newest = queue[-1][0] if queue else (self.last[stream].stamp if self.last[stream] else None)
        if newest is not None and stamp < newest:
            self.reject(f"stale frame on stream {stream}: stamp {stamp} is older than {newest}")
            return
        if queue and stamp == newest:
            return  # the same frame twice before it was scored
        frame = resize_frames(frame[None], self.scorer.model.image_size)[0]
        queue.append((stamp, frame, time.perf_counter() if received is None else received, frame_id))
        while len(queue) > self.max_pending:
            queue.popleft()
            self.stats.dropped += 1

    def flush(self) -> list[ScoredFrame]:
        """Score everything pending in one forward pass. Trackers and novelty memories then advance
        in rounds: round r holds each stream's r-th frame, so frames of different streams count as
        simultaneous (like N environments stepped together) and a stream's own frames stay in order."""
        results: list[ScoredFrame] = []
        waiting: list[tuple[int, int, int, np.ndarray, float, str]] = []  # (round, stream, stamp, frame, ...)
        for stream, queue in enumerate(self.pending):
            position = 0
            while queue:
                stamp, frame, arrived, frame_id = queue.popleft()
                last = self.last[stream]
                if last is not None and stamp == last.stamp:
                    results.append(dataclasses.replace(last, received=arrived, repeated=True))
                    self.stats.repeated += 1
                    continue
                waiting.append((position, stream, stamp, frame, arrived, frame_id))
                position += 1
        if not waiting:
            return results
        waiting.sort(key=lambda item: item[0])  # stable: round by round, streams in order within one
        parts = self.scorer.score_frames(
            np.stack([item[3] for item in waiting]),
            envs=np.array([item[1] for item in waiting]),
            rounds=np.array([item[0] for item in waiting]),
        )
        now = time.perf_counter()
        for index, (_, stream, stamp, _, arrived, frame_id) in enumerate(waiting):
            scored = ScoredFrame(
                stream,
                stamp,
                float(parts.total[index]),
                float(parts.distance[index]),
                float(parts.bonus[index]),
                float(parts.intrinsic[index]),
                int(parts.completed[index]),  # the stage: == num_subtasks once all are done
                bool(parts.switched[index]),
                arrived,
                frame_id,
            )
            self.last[stream] = scored
            results.append(scored)
            self.stats.latencies.append(now - arrived)
        self.stats.scored += len(waiting)
        self.stats.batches += 1
        return results

    def reset(self, stream: int) -> None:
        """A new episode on one stream: its tracker restarts and any stamp may follow (a restarted
        simulator's clock starts over); the exploration memories are kept. Flush first."""
        self.scorer.reset(stream)
        self.last[stream] = None

    def take_stats(self) -> dict[str, float | int | str]:
        summary = self.stats.summary()
        self.stats = ServingStats()
        return summary
