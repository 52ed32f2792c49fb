"""Lockstep steps are assembled by stamp, whatever order (or how often) their messages arrive."""

from __future__ import annotations

from inest_agent_node.pairing import REWARD, STATUS, StepMailbox


def test_a_step_completes_only_when_status_and_reward_both_arrived_in_any_order():
    box = StepMailbox()
    box.put(REWARD, 20, "reward@20")
    assert box.take(10) is None and box.missing(10) == [STATUS]
    box.put_status(10, 20, "status 10->20")
    assert box.take(10) == (20, {STATUS: "status 10->20", REWARD: "reward@20"})
    box = StepMailbox()
    box.put_status(10, 20, "status 10->20")
    assert box.take(10) is None and box.missing(10) == [REWARD]
    box.put(REWARD, 20, "reward@20")
    assert box.take(10) == (20, {STATUS: "status 10->20", REWARD: "reward@20"})


def test_messages_for_other_stamps_never_complete_a_step():
    box = StepMailbox()
    box.put_status(10, 20, "status 10->20")
    box.put(REWARD, 10, "reward of the previous frame")  # a late reward: wrong stamp
    box.put(REWARD, 30, "reward of a later frame")
    assert box.take(10) is None and box.missing(10) == [REWARD]


def test_completed_steps_forget_older_messages_so_a_late_repeat_cannot_be_taken_again():
    box = StepMailbox()
    box.put_status(10, 20, "s")
    box.put(REWARD, 20, "r")
    box.put(REWARD, 15, "stale")
    assert box.take(10)[0] == 20
    assert box.boxes[REWARD] == {20: "r"}  # 15 dropped, the current frame's reward kept
    box.put_status(10, 20, "repeat")  # the simulator re-published an old step
    box.forget_before(20)
    assert box.take(10) is None


def test_without_a_reward_node_the_status_is_enough():
    box = StepMailbox(needs_reward=False)
    box.put_status(0, 5, "s")
    assert box.take(0) == (5, {STATUS: "s"})
