"""Serving live streams: batched scoring across streams equals scoring each stream alone, in order;
repeats, zero and backward stamps, stale frames, overload, resets, cropping and the throttled log
behave as the reward node promises."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from inest_reward_node.runtime.images import decode_image, encode_rgb
from inest_reward_node.runtime.intrinsic import IntrinsicConfig
from inest_reward_node.runtime.rewards import RewardScorer
from inest_reward_node.runtime.serving import StreamScorer, ThrottledLog
from test_scorer import line_model

FRAMES = np.random.default_rng(3).integers(0, 256, (12, 32, 32, 3), dtype=np.uint8)


def scorer(streams: int) -> RewardScorer:
    torch.manual_seed(0)  # the same random encoder every time
    model = line_model()
    model.network.eval()
    return RewardScorer(model, 3, intrinsic=IntrinsicConfig(mode="embedding", k=2), num_envs=streams)


def alone(frames: np.ndarray) -> list[float]:
    """The reference: one stream, one frame at a time."""
    reference = scorer(1)
    return [float(reference.score(frame[None]).total[0]) for frame in frames]


def test_one_batch_of_two_streams_scores_like_two_environments_stepped_together():
    streams = StreamScorer(scorer(2), max_pending=10)
    for index in range(3):
        streams.submit(0, 100 + index, FRAMES[index])
        streams.submit(1, 7 + index, FRAMES[6 + index])
    results = streams.flush()
    assert streams.stats.batches == 1 and len(results) == 6
    reference = scorer(2)  # in-process: both environments' frames scored together, step by step
    expected = {}
    for index in range(3):
        parts = reference.score(FRAMES[[index, 6 + index]])
        expected[(0, 100 + index)], expected[(1, 7 + index)] = parts.total
    for result in results:
        assert result.total == pytest.approx(expected[(result.stream, result.stamp)], rel=1e-5, abs=1e-7)


def test_a_round_is_complete_once_every_stream_has_a_frame_waiting():
    streams = StreamScorer(scorer(2), max_pending=10)
    assert not streams.round_complete
    streams.submit(0, 100, FRAMES[0])
    assert not streams.round_complete  # the reward node waits up to round_wait_ms for stream 1
    streams.submit(1, 7, FRAMES[1])
    assert streams.round_complete
    streams.flush()
    assert not streams.round_complete and streams.stats.batches == 1


def test_a_flush_takes_every_streams_frames_round_by_round_up_to_max_batch():
    """Cameras of several arms share one forward pass; a backlog longer than `max_batch` is
    scored in several, each stream's frames in order, none twice, and every drop is its stream's."""
    streams = StreamScorer(scorer(3), max_pending=3, max_batch=4)
    for index in range(3):
        for stream in range(3):
            streams.submit(stream, 100 + index, FRAMES[3 * stream + index])
    streams.submit(2, 103, FRAMES[11])  # a fourth frame on stream 2: its oldest is dropped
    first = streams.flush()
    assert [(r.stream, r.stamp) for r in first] == [(0, 100), (1, 100), (2, 101), (0, 101)]
    assert streams.ready and streams.stats.batches == 1
    second = streams.flush()
    assert [(r.stream, r.stamp) for r in second] == [(0, 102), (1, 101), (2, 102), (1, 102)]
    assert [(r.stream, r.stamp, r.episode_frame) for r in streams.flush()] == [(2, 103, 3)]
    assert not streams.ready and streams.num_pending == 0 and streams.stats.batches == 3
    stats = streams.take_stats()
    assert stats["dropped_overflow"] == 1 and stats["stream2_unanswered"] == 1 and "stream0_unanswered" not in stats


def test_a_stream_alone_scores_frame_by_frame_even_when_its_frames_arrive_together():
    streams = StreamScorer(scorer(1), max_pending=10)
    for index in range(6):
        streams.submit(0, 100 + index, FRAMES[index])
    np.testing.assert_allclose([r.total for r in streams.flush()], alone(FRAMES[:6]), rtol=1e-5)


def test_a_repeated_stamp_gets_the_cached_reward_and_does_not_move_the_tracker():
    streams = StreamScorer(scorer(1))
    streams.submit(0, 1, FRAMES[0])
    first = streams.flush()[0]
    streams.submit(0, 1, FRAMES[0])
    again = streams.flush()[0]
    assert again.repeated and again.total == first.total and streams.stats.repeated == 1
    streams.submit(0, 2, FRAMES[1])
    assert streams.flush()[0].total == pytest.approx(alone(FRAMES[:2])[1], rel=1e-5)


def test_stale_frames_are_rejected_and_overload_drops_the_oldest():
    streams = StreamScorer(scorer(1), max_pending=2, backward="reject")
    streams.submit(0, 5, FRAMES[0])
    streams.flush()
    streams.submit(0, 4, FRAMES[1])
    assert streams.stats.rejected == {"stale": 1} and "stamp 4 is older than 5" in streams.stats.last_rejection
    for stamp in (6, 7, 8):
        streams.submit(0, stamp, FRAMES[stamp])
    assert streams.stats.dropped == {"overflow": 1}
    assert [r.stamp for r in streams.flush()] == [7, 8]
    first = streams.take_stats()  # a report's counts, and their running totals
    assert (first["rejected"], first["dropped"], first["scored"]) == (1, 1, 3)
    assert first["stream0_unanswered"] == 2  # the stream's frames that got no reward: stale and overflow
    assert (first["total_rejected"], first["total_dropped_overflow"], first["total_scored"]) == (1, 1, 3)
    streams.submit(0, 9, FRAMES[9])
    streams.flush()
    second = streams.take_stats()  # a reader that missed the first report still has every count
    assert (second["scored"], second["rejected"], second["total_scored"], second["total_rejected"]) == (1, 0, 4, 1)


def test_reset_restarts_the_tracker_and_accepts_a_restarted_clock():
    streams = StreamScorer(scorer(1))
    streams.scorer.trackers[0].completed = 2
    streams.submit(0, 50, FRAMES[0])
    first = streams.flush()[0]
    assert (first.completed, first.episode_frame) == (2, 1)
    for _ in range(2):  # a frame and its re-publish: the cached reward, the same count
        streams.submit(0, 51, FRAMES[1])
        assert streams.flush()[0].episode_frame == 2
    streams.reset(0)
    streams.submit(0, 1, FRAMES[0])  # a simulator that restarted: its clock starts over
    result = streams.flush()[0]
    assert result.completed == 0 and not streams.stats.rejected
    assert result.episode_frame == 1  # counted from the episode's start again: what tells the agent


def test_a_frame_is_fitted_once_on_arrival_and_never_again():
    """decode_image fits a frame to the encoder input; the streams and the encoder take it as it is."""
    streams = StreamScorer(scorer(1))
    big = np.repeat(np.repeat(FRAMES[0], 2, axis=0), 2, axis=1)  # 64 px
    with pytest.raises(ValueError, match="fit it to the encoder's 32x32 input first"):
        streams.submit(0, 1, big)
    data, step = encode_rgb(big)
    fitted = decode_image("rgb8", 64, 64, step, data, 32)
    streams.submit(0, 1, fitted)
    assert streams.pending[0][0].frame is fitted
    np.testing.assert_allclose(streams.flush()[0].total, alone(big[None])[0], rtol=1e-5)  # as the encoder fits it


def test_zero_stamps_are_scored_as_new_frames_with_one_warning():
    """A camera that leaves header.stamp at 0: every frame is a new one, not a copy of the first reward."""
    streams = StreamScorer(scorer(1), max_pending=10)
    results = []
    for frame in FRAMES[:6]:
        streams.submit(0, 0, frame)
        results += streams.flush()
    assert not any(r.repeated for r in results) and streams.stats.scored == 6 and streams.stats.zero_stamps == 6
    np.testing.assert_allclose([r.total for r in results], alone(FRAMES[:6]), rtol=1e-5)
    assert streams.log.take() == [("warning", "stream 0 sends zero stamps: every frame is scored as a new one")]


def test_a_repeated_stamp_with_new_pixels_is_a_new_frame():
    streams = StreamScorer(scorer(1))
    for frame in FRAMES[:3]:
        streams.submit(0, 7, frame)
        streams.flush()
    assert streams.stats.scored == 3 and streams.stats.repeated_stamps == 2 and streams.stats.repeated == 0
    assert len(streams.log.take()) == 1


def test_a_backward_jump_starts_a_new_episode_on_that_stream():
    streams = StreamScorer(scorer(2), max_pending=10)
    streams.scorer.trackers[0].completed = streams.scorer.trackers[1].completed = 2
    streams.submit(0, 2_000_000_000, FRAMES[0])
    streams.submit(1, 2_000_000_000, FRAMES[1])
    before = streams.submit(0, 1_000_000_000, FRAMES[2])  # the clock went back 1 s
    assert sorted((r.stream, r.completed) for r in before) == [(0, 2), (1, 2)]  # the old episode's frames first
    assert [tracker.completed for tracker in streams.scorer.trackers] == [0, 2]  # only the jumping stream's reset
    assert [(r.stamp, r.completed) for r in streams.flush()] == [(1_000_000_000, 0)]
    assert streams.stats.stamp_resets == 1 and not streams.stats.rejected and not streams.stats.dropped
    assert streams.log.take() == [("warning", "stream 0: stamp went back 1.000 s: a new episode (tracker reset)")]


def test_backward_stamps_can_be_rejected_instead_counted_and_logged_with_a_count():
    clock = [0.0]
    streams = StreamScorer(scorer(1), backward="reject", log=ThrottledLog(5.0, clock=lambda: clock[0]))
    streams.submit(0, 2_000_000_000, FRAMES[0])
    streams.flush()
    for index in range(30):  # 1 s of 30 Hz frames from a clock that jumped back 1 s
        clock[0] = index / 30
        streams.submit(0, 1_000_000_000 + index * 33_000_000, FRAMES[1])
    assert streams.stats.rejected == {"stale": 30} and streams.num_pending == 0
    clock[0] = 5.0
    lines = [line for _, line in streams.log.take()]
    assert len(lines) == 2 and lines[0].startswith("rejected a frame: stale frame on stream 0: stamp 1000000000")
    assert lines[1].startswith("rejected 29 frames in the last 5 s: stale frame on stream 0")


def test_the_log_counts_each_reason_once_per_period_however_they_interleave():
    clock = [0.0]
    log = ThrottledLog(5.0, clock=lambda: clock[0])
    for index in range(1000):  # 1 kHz for 1 s, two reasons alternating
        clock[0] = index / 1000
        reason = ("encoding", "step")[index % 2]
        log.add(reason, f"first {reason}", f"{{count}} more {reason} in {{seconds}} s")
    assert log.take() == [("warning", "first encoding"), ("warning", "first step")]
    clock[0] = 5.2
    assert log.take() == [("warning", "499 more encoding in 5 s"), ("warning", "499 more step in 5 s")]
    clock[0] = 10.4
    assert log.take() == []  # a quiet period: the next one is logged at once again
    log.add("step", "first step", "")
    assert log.take() == [("warning", "first step")]


def test_a_640x480_frame_scores_like_its_centre_480x480_crop():
    """A 4:3 camera whose centre holds the training view: the default crop keeps its aspect."""
    rng = np.random.default_rng(5)
    wide = np.kron(FRAMES[:4], np.ones((15, 20, 1), np.uint8))  # 480x640, stretched to 4:3 ...
    wide[:, :, 80:560] = np.kron(FRAMES[:4], np.ones((15, 15, 1), np.uint8))  # ... with the square view in its centre
    wide[:, :, :80] = rng.integers(0, 256, (4, 480, 80, 3), dtype=np.uint8)  # and clutter at the sides
    results = {}
    for name, frames, resize in (
        ("wide", wide, "crop"),
        ("centre", wide[:, :, 80:560], "crop"),
        ("squash", wide, "squash"),
    ):
        streams = StreamScorer(scorer(1), max_pending=10)
        for index, frame in enumerate(frames):
            data, step = encode_rgb(frame, "bgr8")
            streams.submit(0, index + 1, decode_image("bgr8", *frame.shape[:2], step, data, 32, resize))
        results[name] = [r.total for r in streams.flush()]
    assert results["wide"] == results["centre"]
    assert results["squash"] != results["centre"]  # squashing shows the encoder other pixels
