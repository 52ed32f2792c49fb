"""Serving the learned reward to live camera streams, without ROS: the reward node's logic.

Frames arrive one at a time from one or more streams (a simulator or camera each), already
fitted to the encoder's input (the node fits each once, as it decodes it: images.decode_image);
whatever has arrived when the node gets to it is scored in one encoder forward pass.

Stamps. A stream's frames are keyed by their stamp and expected in stamp order:
- a repeat of the newest stamp with the same pixels is a re-publish (a lockstep simulator
  answering a re-sent action): it gets the cached reward instead of moving the tracker twice;
- a zero stamp (a camera that leaves it unset), or a repeated stamp with new pixels, is a new
  frame and scored as one; the stream is warned about once;
- an older stamp (a clock that jumped back, a restarted camera or bag) follows `backward`:
  `reset` starts a new episode on that stream (tracker reset, like `reset_reward`), `reject`
  drops the frame as stale until the clock passes the newest stamp; either is counted and logged.
Every frame that gets no reward of its own is counted by reason in `ServingStats`.

A stage head that reads a second camera (a scene camera beside the egocentric one,
`RewardScorer.stage_camera`) gets that camera's frame of the same stamp (`submit_stage`), so a
frame is never scored with another moment's stage evidence: a frame waits for its partner (a
zero-stamped frame takes the stream's newest one) until the second camera sends a newer stamp.
Each camera's frames come in stamp order, so its partner is then lost: the frame is dropped,
counted as `unpaired` and logged, and never holds back the stream's later frames. Second-camera
frames older than the frame just paired have no partner either and are dropped, counted as
`stage_unpaired` (as are the oldest kept ones when too many wait).

Clock jumps. Only the second camera's frames that came since the stream's episode began (a
backward stamp or a reset) can show a frame's partner lost: one kept from before the clock went
back (a scene frame whose ego frame was lost) says nothing about the new clock's stamps. When the
second camera's own stamp goes back, its kept frames are the old clock's: the frames still
waiting for them get theirs, the rest are dropped (`stage_unpaired`, logged as a clock jump).
"""

from __future__ import annotations

import time
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from .rewards import RewardFunction, RewardScorer, Steps

BACKWARD_POLICIES = ("reset", "reject")
READY, WAITING, LOST = "ready", "waiting", "lost"  # a frame's pairing with its stage camera's frame


@dataclass
class ScoredFrame:
    """One served frame's reward: where and when the frame came from, and its published parts
    under their RewardParts names (reward_parts.PARTS, which names their Reward fields too)."""

    stream: int
    stamp: int  # nanoseconds, the image's own stamp
    received: float  # time.perf_counter() when the frame arrived
    frame_id: str  # the image's frame, handed back for the reward's header
    episode_frame: int  # frames the stream's tracker has scored since its episode began (1 for the first)
    model_generation: int  # which model scored it: 0 the first, +1 per replace_scorer
    total: float
    shaping: float
    bonus: float
    intrinsic: float
    completed: int  # the stage: == num_subtasks once all are done
    switched: bool
    confidence: float
    repeated: bool = False  # the cached reward of an already scored stamp


@dataclass
class Pending:
    stamp: int
    frame: np.ndarray  # already fitted to the encoder input
    received: float
    frame_id: str
    republished: bool  # same stamp and pixels as the stream's previous frame: answered from the cache
    stage_frame: np.ndarray | None = None  # the stage head's camera at the same stamp, once it has come


@dataclass
class StageFrame:
    frame: np.ndarray  # already fitted to the encoder's input size, like its partner
    received: float  # time.perf_counter() when it arrived
    arrival: int  # StreamScorer.arrivals when it arrived: whether it came before an episode began


@dataclass
class ServingStats:
    """Counters and latencies since the last report (diagnostics)."""

    scored: int = 0
    repeated: int = 0
    rejected: Counter[str] = field(default_factory=Counter)  # reason -> frames refused (malformed, stale)
    dropped: Counter[str] = field(default_factory=Counter)  # reason -> valid frames never scored
    # stream -> its camera's frames that got no reward of their own: dropped or refused as stale
    # (not the second camera's frames, nor malformed ones, which name no stamp to answer)
    unanswered: Counter[int] = field(default_factory=Counter)
    zero_stamps: int = 0  # frames stamped 0, scored as new ones
    repeated_stamps: int = 0  # a stamp again with new pixels, scored as a new frame
    stamp_resets: int = 0  # backward stamps that started a new episode
    last_rejection: str = ""
    latencies: list[float] = field(default_factory=list)  # seconds, arrival -> scored
    pair_waits: list[float] = field(default_factory=list)  # seconds a frame waited for its stage frame
    batches: int = 0
    since: float = field(default_factory=time.perf_counter)

    def summary(self) -> dict[str, float | int | str]:
        elapsed = max(time.perf_counter() - self.since, 1e-9)
        latencies = np.array(self.latencies) * 1e3 if self.latencies else np.zeros(1)
        pair_waits = np.array(self.pair_waits) * 1e3 if self.pair_waits else np.zeros(1)
        return {
            "rate_hz": self.scored / elapsed,
            "latency_p50_ms": float(np.percentile(latencies, 50)),
            "latency_p99_ms": float(np.percentile(latencies, 99)),
            "waited_for_stage_frame": len(self.pair_waits),  # frames that came before their partner
            "stage_wait_p99_ms": float(np.percentile(pair_waits, 99)),
            "mean_batch": self.scored / max(self.batches, 1),
            "scored": self.scored,
            "repeated": self.repeated,
            "rejected": self.rejected.total(),
            **{f"rejected_{reason}": count for reason, count in sorted(self.rejected.items())},
            "dropped": self.dropped.total(),
            **{f"dropped_{reason}": count for reason, count in sorted(self.dropped.items())},
            **{f"stream{stream}_unanswered": count for stream, count in sorted(self.unanswered.items())},
            "zero_stamps": self.zero_stamps,
            "repeated_stamps": self.repeated_stamps,
            "stamp_resets": self.stamp_resets,
            "last_rejection": self.last_rejection,
        }


@dataclass
class _Throttled:
    count: int
    summary: str  # the latest line, with {count} and {seconds} still to fill in
    since: float


class ThrottledLog:
    """Lines for the node's log that may come thousands of times a second: the first of each key
    at once, the rest as one line per `period` with their count ("rejected 812 frames in the last
    5 s: ..."), whatever else happened in between; `once` lines only the first time."""

    def __init__(self, period: float = 5.0, clock: Callable[[], float] = time.monotonic) -> None:
        self.period, self.clock = period, clock
        self.lines: list[tuple[str, str]] = []  # (level, line) not yet taken
        self.throttled: dict[str, _Throttled] = {}
        self.said: set[str] = set()

    def add(self, key: str, first: str, summary: str, level: str = "warning") -> None:
        now = self.clock()
        entry = self.throttled.get(key)
        if entry is None:
            self.lines.append((level, first))
            self.throttled[key] = _Throttled(0, summary, now)
            return
        entry.count, entry.summary = entry.count + 1, summary
        if now - entry.since >= self.period:
            self._report(key, entry, now, level)

    def once(self, key: str, line: str, level: str = "warning") -> None:
        if key not in self.said:
            self.said.add(key)
            self.lines.append((level, line))

    def take(self) -> list[tuple[str, str]]:
        """The lines to log now, including the counts of every key whose period is over."""
        now = self.clock()
        for key, entry in list(self.throttled.items()):
            if now - entry.since >= self.period:
                self._report(key, entry, now, "warning")
        lines, self.lines = self.lines, []
        return lines

    def _report(self, key: str, entry: _Throttled, now: float, level: str) -> None:
        if entry.count == 0:  # quiet for a whole period: the next one is logged at once again
            del self.throttled[key]
            return
        seconds = f"{now - entry.since:.0f}"
        self.lines.append((level, entry.summary.replace("{count}", str(entry.count)).replace("{seconds}", seconds)))
        entry.count, entry.since = 0, now


class StreamScorer:
    """Batches frames from several streams into one scorer, one tracker per stream: a flush scores
    every stream's ready frames in one forward pass of at most `max_batch`. The scorer's
    RewardConfig (the node's `reward.*` parameters) decides shaping and tracker; a tracker may now
    reopen a subtask, so a stream's `subtask` can go down."""

    def __init__(
        self,
        scorer: RewardFunction,
        max_pending: int = 4,
        backward: str = "reset",
        log: ThrottledLog | None = None,
        max_batch: int = 32,
    ) -> None:
        if scorer.needs_known_stages:
            raise ValueError("a privileged stage (a diagnostic) needs the true stage; served streams carry images only")
        if backward not in BACKWARD_POLICIES:
            raise ValueError(f"backward_stamps must be one of {BACKWARD_POLICIES}, got {backward!r}")
        self.scorer = scorer
        self.max_pending = max_pending  # per stream: older waiting frames are dropped (counted)
        self.max_batch = max_batch  # frames per forward pass: the rest wait for the next flush
        self.backward = backward
        self.log = log or ThrottledLog()
        self.pending: list[deque[Pending]] = [deque() for _ in range(scorer.num_envs)]
        self.last: list[ScoredFrame | None] = [None] * scorer.num_envs
        self.episode_frames = [0] * scorer.num_envs  # scored since each stream's tracker was reset
        self.newest: list[tuple[int, np.ndarray] | None] = [None] * scorer.num_envs  # (stamp, frame) accepted last
        # the stage head's second camera: its frames by stamp, waiting for their partners
        self.stage_frames: list[dict[int, StageFrame]] = [{} for _ in range(scorer.num_envs)]
        self.stage_newest: list[int] = [0] * scorer.num_envs  # the second camera's latest stamp (0: none yet)
        self.episode_began = [0] * scorer.num_envs  # `arrivals` when each stream's episode began
        self.stats = ServingStats()
        self.totals: Counter[str] = Counter()  # every count since the start, for a reader that missed a report
        self.arrivals = 0  # frames submitted so far, of either camera: what a callback brought
        self.model_generation = 0

    def replace_scorer(self, scorer: RewardScorer, keep_memories: bool) -> None:
        """Score from now on with `scorer` (a refitted model), its streams carrying on their
        episodes (RewardScorer.continue_episodes). It must read the same cameras at the same size:
        the subscriptions and the frames waiting are made for them. Flush before, so that the
        frames that arrived under the old model are scored by it."""
        old = self.scorer
        if (scorer.camera, scorer.stage_camera, scorer.image_size) != (old.camera, old.stage_camera, old.image_size):
            raise ValueError(
                f"the new model reads {scorer.camera} (stage: {scorer.stage_camera}) at {scorer.image_size} px, "
                f"the node serves {old.camera} (stage: {old.stage_camera}) at {old.image_size} px: restart the node"
            )
        scorer.continue_episodes(old, keep_memories)
        self.scorer = scorer
        self.model_generation += 1

    @property
    def stage_camera(self) -> str | None:
        """The second camera the scorer's stage head reads (submit_stage), or None."""
        return self.scorer.stage_camera

    def submit_stage(self, stream: int, stamp: int, frame: np.ndarray, received: float | None = None) -> None:
        """The stage head's camera frame of `stamp` on `stream`, fitted to the encoder's input like
        its partner (`fitted`); kept until its partner is scored. Only the newest few are kept: a
        partner that never comes must not grow the store."""
        self.arrivals += 1
        kept = self.stage_frames[stream]
        arrived = time.perf_counter() if received is None else received
        frame = self.fitted(frame)
        if 0 < stamp < self.stage_newest[stream]:
            self.stage_clock_went_back(stream, stamp)
        if stamp:
            self.stage_newest[stream] = stamp
        kept[stamp] = StageFrame(frame, arrived, self.arrivals)
        while len(kept) > 4 * self.max_pending:
            del kept[next(iter(kept))]
            self.stats.dropped["stage_unpaired"] += 1

    def stage_clock_went_back(self, stream: int, stamp: int) -> None:
        """The second camera's stamp went back: what it kept is the old clock's, no partner of the
        new one's frames. Frames of this episode still waiting for theirs take them; the rest go."""
        kept, began = self.stage_frames[stream], self.episode_began[stream]
        for item in self.pending[stream]:
            partner = kept.get(item.stamp)
            if item.stage_frame is None and partner is not None and partner.arrival > began:
                self.pair(item, kept.pop(item.stamp))
        if not kept:
            return
        self.stats.dropped["stage_unpaired"] += len(kept)
        detail = (
            f"stream {stream}: the {self.stage_camera} camera's clock jumped back "
            f"{(self.stage_newest[stream] - stamp) / 1e9:.3f} s"
        )
        self.log.add(
            f"stage-backward:{stream}",
            f"{detail}: dropped {len(kept)} {self.stage_camera} frame(s) of the old clock, no partners of the new one",
            f"{{count}} {self.stage_camera} clock jumps in the last {{seconds}} s; latest: {detail}",
        )
        kept.clear()

    def pair(self, item: Pending, partner: StageFrame) -> None:
        item.stage_frame = partner.frame
        if partner.received > item.received:  # the frame waited for it: the pairing's own cost
            self.stats.pair_waits.append(partner.received - item.received)

    def partner(self, stream: int, item: Pending) -> str:
        """Give `item` its stage frame if it needs one and it has come: READY; WAITING while it may
        still come; LOST once the stage camera has sent a newer stamp in this episode (one from
        before it may be the old clock's, whose stamps the new one repeats)."""
        if self.stage_camera is None or item.stage_frame is not None:
            return READY
        kept, began = self.stage_frames[stream], self.episode_began[stream]
        if item.stamp == 0 and kept:  # zero stamps cannot pair: the newest scene frame
            partner = kept.pop(next(reversed(kept)))
        elif item.stamp in kept:
            partner = kept.pop(item.stamp)
        elif any(stamp > item.stamp and frame.arrival > began for stamp, frame in kept.items()):
            return LOST
        else:
            return WAITING
        self.pair(item, partner)
        for orphan in [stamp for stamp in kept if stamp < item.stamp]:  # their partners are past
            del kept[orphan]
            self.stats.dropped["stage_unpaired"] += 1
        return READY

    @property
    def num_pending(self) -> int:
        return sum(len(queue) for queue in self.pending)

    def has_ready(self, stream: int) -> bool:
        """The stream's next frame can be taken now: scored, answered from the cache or dropped."""
        queue = self.pending[stream]
        return bool(queue) and self.partner(stream, queue[0]) != WAITING

    @property
    def round_complete(self) -> bool:
        """Every stream has a frame ready to score (with its stage frame, when the stage head reads
        a second camera): a flush now scores a whole lockstep round at once."""
        return all(self.has_ready(stream) for stream in range(len(self.pending)))

    @property
    def ready(self) -> bool:
        """Some stream has a frame a flush would take: one left over by `max_batch`, say."""
        return any(self.has_ready(stream) for stream in range(len(self.pending)))

    def reject(self, reason: str, detail: str) -> None:
        """Count and log a frame that will get no reward; `reason` is its short name."""
        self.stats.rejected[reason] += 1
        self.stats.last_rejection = detail
        self.log.add(
            f"rejected:{reason}",
            f"rejected a frame: {detail}",
            f"rejected {{count}} frames in the last {{seconds}} s: {detail}",
        )

    def fitted(self, frame: np.ndarray) -> np.ndarray:
        """`frame`, checked to be fitted to the encoder's input already (images.decode_image with
        its size, or images.fit_square): a frame is cropped and resized once, where it arrives,
        so that the encoder sees it as it was fitted there."""
        size = self.scorer.image_size
        if frame.shape[:2] != (size, size):
            raise ValueError(
                f"a {frame.shape[1]}x{frame.shape[0]} frame: fit it to the encoder's {size}x{size} input first"
            )
        return frame

    def submit(
        self, stream: int, stamp: int, frame: np.ndarray, received: float | None = None, frame_id: str = ""
    ) -> list[ScoredFrame]:
        """Queue one frame, fitted to the encoder's input (`fitted`). Returns what had to be scored
        before it could be taken (the old episode's frames when a backward stamp starts a new
        one), usually nothing."""
        self.arrivals += 1
        arrived = time.perf_counter() if received is None else received
        frame = self.fitted(frame)
        newest = self.newest[stream]
        republished, scored = False, []
        if stamp == 0:
            self.stats.zero_stamps += 1
            self.log.once(f"zero:{stream}", f"stream {stream} sends zero stamps: every frame is scored as a new one")
        elif newest is not None and stamp < newest[0]:
            if self.backward == "reject":
                self.reject("stale", f"stale frame on stream {stream}: stamp {stamp} is older than {newest[0]}")
                self.stats.unanswered[stream] += 1
                return []
            scored = self.flush()  # the old episode's frames belong to it
            self.reset(stream)
            self.stats.stamp_resets += 1
            jump = f"stream {stream}: stamp went back {(newest[0] - stamp) / 1e9:.3f} s"
            self.log.add(
                f"backward:{stream}",
                f"{jump}: a new episode (tracker reset)",
                f"{{count}} backward stamps in the last {{seconds}} s, each a new episode; latest: {jump}",
            )
        elif newest is not None and stamp == newest[0]:
            republished = np.array_equal(frame, newest[1])
            if not republished:
                self.stats.repeated_stamps += 1
                self.log.once(
                    f"repeated:{stream}",
                    f"stream {stream} repeats stamps with new pixels: each is scored as a new frame",
                )
        queue = self.pending[stream]
        if republished and queue:
            self.stats.repeated += 1  # the same frame twice before it was scored: its twin's reward answers both
            return scored
        self.newest[stream] = (stamp, frame)
        queue.append(Pending(stamp, frame, arrived, frame_id, republished))
        while len(queue) > self.max_pending:
            queue.popleft()
            self.drop(stream, "overflow")
        return scored

    def drop(self, stream: int, reason: str, count: int = 1) -> None:
        """Count `count` of the stream's camera frames dropped unscored for `reason`."""
        self.stats.dropped[reason] += count
        self.stats.unanswered[stream] += count

    def flush(self) -> list[ScoredFrame]:
        """Score every stream's ready frames in one forward pass, at most `max_batch` (the rest wait:
        `ready`). Trackers and novelty memories then advance in rounds: round r holds each stream's
        r-th frame, so frames of different streams count as simultaneous (like N environments
        stepped together) and a stream's own frames stay in order."""
        results: list[ScoredFrame] = []
        waiting: list[tuple[int, int, Pending]] = []  # (round, stream, frame), round by round
        streams, position = list(range(len(self.pending))), 0
        while streams and len(waiting) < self.max_batch:
            taken = []
            for stream in streams:
                if len(waiting) < self.max_batch and (item := self.take(stream, results)) is not None:
                    waiting.append((position, stream, item))
                    taken.append(stream)
            streams, position = taken, position + 1
        if not waiting:
            return results
        parts = self.scorer.score(
            np.stack([item.frame for _, _, item in waiting]),
            None if self.stage_camera is None else np.stack([item.stage_frame for _, _, item in waiting]),
            Steps(envs=np.array([entry[1] for entry in waiting]), rounds=np.array([entry[0] for entry in waiting])),
        )
        now = time.perf_counter()
        for index, (_, stream, item) in enumerate(waiting):
            self.episode_frames[stream] += 1
            scored = ScoredFrame(
                stream,
                item.stamp,
                item.received,
                item.frame_id,
                self.episode_frames[stream],
                self.model_generation,
                **parts.row(index),
            )
            self.last[stream] = scored
            results.append(scored)
            self.stats.latencies.append(now - item.received)
        self.stats.scored += len(waiting)
        self.stats.batches += 1
        return results

    def take(self, stream: int, results: list[ScoredFrame]) -> Pending | None:
        """The stream's next frame to score, answering re-publishes (into `results`) and dropping
        frames whose partner is lost on the way; None once it has none ready."""
        queue = self.pending[stream]
        while queue:
            item, last = queue[0], self.last[stream]
            if item.republished and last is not None:
                queue.popleft()
                results.append(replace(last, received=item.received, frame_id=item.frame_id, repeated=True))
                self.stats.repeated += 1
                continue
            pairing = self.partner(stream, item)
            if pairing == WAITING:
                return None  # it and the stream's later frames wait for its stage frame
            queue.popleft()
            if pairing == READY:
                return item
            self.drop_unpaired(stream, item.stamp)
        return None

    def drop_unpaired(self, stream: int, stamp: int) -> None:
        self.drop(stream, "unpaired")
        detail = f"stream {stream}: no {self.stage_camera} camera frame of stamp {stamp} (a newer one came)"
        self.log.add(
            f"unpaired:{stream}",
            f"{detail}: the frame is dropped unscored",
            f"dropped {{count}} unpaired frames in the last {{seconds}} s; latest: {detail}",
        )

    def reset(self, stream: int) -> None:
        """A new episode on one stream: its tracker restarts and any stamp may follow (a restarted
        simulator's clock starts over); the exploration memories are kept. Flush first: what is
        still pending then waits for a stage frame that did not come, and is dropped (counted)."""
        if self.pending[stream]:
            self.drop(stream, "unpaired", len(self.pending[stream]))
            self.pending[stream].clear()
        self.scorer.reset(stream)
        self.last[stream] = None
        self.episode_frames[stream] = 0
        self.newest[stream] = None
        self.episode_began[stream] = self.arrivals

    def take_stats(self) -> dict[str, float | int | str]:
        """The counts and latencies since the last call, and every count's running total (`total_*`)."""
        summary = self.stats.summary()
        self.stats = ServingStats()
        self.totals.update({key: value for key, value in summary.items() if type(value) is int})
        return summary | {f"total_{key}": count for key, count in sorted(self.totals.items())}
