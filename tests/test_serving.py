"""Serving live streams: batched scoring across streams equals scoring each stream alone, in order;
repeats, stale frames, overload and resets behave as the reward node promises."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from inest_reward_node.intrinsic import IntrinsicConfig
from inest_reward_node.rewards import RewardScorer
from inest_reward_node.serving import StreamScorer
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
    streams = StreamScorer(scorer(1), max_pending=2)
    streams.submit(0, 5, FRAMES[0])
    streams.flush()
    streams.submit(0, 4, FRAMES[1])
    assert streams.stats.rejected == 1 and "stamp 4 is older than 5" in streams.stats.last_rejection
    for stamp in (6, 7, 8):
        streams.submit(0, stamp, FRAMES[stamp])
    assert streams.stats.dropped == 1
    assert [r.stamp for r in streams.flush()] == [7, 8]


def test_reset_restarts_the_tracker_and_accepts_a_restarted_clock():
    streams = StreamScorer(scorer(1))
    streams.scorer.trackers[0].completed = 2
    streams.submit(0, 50, FRAMES[0])
    assert streams.flush()[0].subtask == 2
    streams.reset(0)
    streams.submit(0, 1, FRAMES[0])  # a simulator that restarted: its clock starts over
    result = streams.flush()[0]
    assert result.subtask == 0 and streams.stats.rejected == 0


def test_frames_of_any_size_are_resized_to_the_encoder_input():
    streams = StreamScorer(scorer(1))
    big = np.repeat(np.repeat(FRAMES[0], 2, axis=0), 2, axis=1)  # 64 px
    streams.submit(0, 1, big)
    assert streams.pending[0][0][1].shape == (32, 32, 3)
