"""Pairing a lockstep step's messages by stamp, never by arrival order (no ROS imports).

After the agent acts on the observation stamped S, the simulator's episode status that
answers it carries `action_stamp == S`, the new observation's stamp S' and the new state; the
reward for that step carries S'. Messages for other stamps (late repeats, the reward of a
reset frame) never satisfy a step, and are dropped once a newer step has completed.
"""

from __future__ import annotations

from typing import Any

STATUS, REWARD = "episode_status", "reward"


class StepMailbox:
    """One environment's messages, by stamp, until the step that needs them takes them."""

    def __init__(self, needs_reward: bool = True) -> None:
        self.stamped = (REWARD,) if needs_reward else ()
        self.statuses: dict[int, tuple[int, Any]] = {}  # action stamp -> (new stamp, status)
        self.boxes: dict[str, dict[int, Any]] = {topic: {} for topic in self.stamped}

    def put_status(self, action_stamp: int, new_stamp: int, message: Any) -> None:
        self.statuses[action_stamp] = (new_stamp, message)

    def put(self, topic: str, stamp: int, message: Any) -> None:
        if topic in self.boxes:
            self.boxes[topic][stamp] = message

    def take(self, acted_on: int) -> tuple[int, dict[str, Any]] | None:
        """(new stamp, {topic: message}) once everything answering the action on `acted_on` is here."""
        if self.missing(acted_on):
            return None
        new_stamp, status = self.statuses[acted_on]
        messages = {STATUS: status, **{topic: self.boxes[topic][new_stamp] for topic in self.stamped}}
        self.forget_before(new_stamp)
        return new_stamp, messages

    def missing(self, acted_on: int) -> list[str]:
        """The topics the step that acted on `acted_on` still waits for (for the timeout log)."""
        if acted_on not in self.statuses:
            return [STATUS]
        new_stamp = self.statuses[acted_on][0]
        return [topic for topic in self.stamped if new_stamp not in self.boxes[topic]]

    def forget_before(self, stamp: int) -> None:
        """Drop everything older than the observation stamped `stamp` (it is now the current one)."""
        self.statuses = {key: value for key, value in self.statuses.items() if key >= stamp}
        for topic in self.stamped:
            self.boxes[topic] = {key: value for key, value in self.boxes[topic].items() if key >= stamp}
