"""`inest-monitor`: watch a running INEST graph's reward and subtask topics from a terminal.

Prints one line per interval: steps/s from the simulators' episode status, the latest learned
reward and subtask per stream with how sure the reward has been of that subtask since it was
reached (the mean stage confidence of its frames), finished episodes and their mean score, and
the reward node's health from /diagnostics. `--episode-lines` adds a line per finished episode:
its score and the steps at which the learned reward's subtask went up (`sim0: episode 3: 3 of 3
blocks placed in order (score 1.00); the learned reward's subtask 1 at step 14, 2 at 40, done at
63`). A line that would only repeat the last one's step count (a graph waiting to start, a final
evaluation) is left out, but one comes at least every QUIET_LINE_S. `--plot` writes a
reward-trace PNG on exit (Ctrl-C).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from inest_common.rosutil import namespaced
from inest_common.settings import OneLineParser
from inest_interfaces.msg import EpisodeStatus, Reward
from inest_sim_node.scoring import NUM_BLOCKS
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

TRACE_STEPS = 500  # steps per stream kept for the reward-trace plot
QUIET_LINE_S = 30.0  # seconds between lines while no step is taken


@dataclass
class StreamView:
    steps: int = 0
    episodes: int = 0
    scores: deque = field(default_factory=lambda: deque(maxlen=20))
    reward: float = float("nan")
    subtask: str = "-"
    stage: int = -1  # Reward.subtask of the latest frame
    # Reward.stage_confidence summed over the frames since `stage` was reached: one frame's is noisy
    # (the stage head may doubt, for a few frames, a block the tracker has seen placed, and a latched
    # "done" read "sure 0.00"); their mean says how well the evidence has backed the stage
    confidence_sum: float = 0.0
    confidence_frames: int = 0
    num_subtasks: int = 0
    trace: deque = field(default_factory=lambda: deque(maxlen=TRACE_STEPS))  # (reward, subtask)
    climbs: list[tuple[int, int]] = field(default_factory=list)  # (step, subtask) each time a new high was reached
    highest: int = 0  # this episode's highest subtask so far
    finished: EpisodeStatus | None = None  # the end of an episode whose last reward may still come

    @property
    def confidence(self) -> float:
        """The stage's mean confidence since it was reached (NaN: none read, or no frame yet)."""
        return self.confidence_sum / self.confidence_frames if self.confidence_frames else float("nan")


def climb_text(climbs: list[tuple[int, int]], num_subtasks: int) -> str:
    """`subtask 1 at step 14, 2 at 40, done at 63`: when the learned subtask went up (what the
    reward believed, which the score beside it confirms or not)."""
    if not climbs:
        return "subtask stayed at 0"
    parts = [f"{'done' if subtask >= num_subtasks else subtask} at {'step ' * (i == 0)}{step}"
             for i, (step, subtask) in enumerate(climbs)]  # fmt: skip
    return "subtask " + ", ".join(parts)


def confidence_text(confidence: float) -> str:
    """` (sure 0.93)`: the stage's mean confidence, when the reward reads stage evidence."""
    return "" if math.isnan(confidence) else f" (sure {confidence:.2f})"


class GraphMonitor(Node):
    def __init__(self, namespaces: list[str], episode_lines: bool = False) -> None:
        super().__init__("inest_monitor")
        self.namespaces = namespaces
        self.views = [StreamView() for _ in namespaces]
        self.health = ""
        self.episode_lines = episode_lines
        self.events: list[str] = []  # episode lines not printed yet
        for index, namespace in enumerate(namespaces):
            self.create_subscription(
                Reward, namespaced(namespace, "reward"), lambda m, i=index: self.on_reward(i, m), 100
            )
            self.create_subscription(
                EpisodeStatus, namespaced(namespace, "episode_status"), lambda m, i=index: self.on_status(i, m), 100
            )
        self.create_subscription(DiagnosticArray, "/diagnostics", self.on_diagnostics, 10)
        self.last_steps, self.last_time = 0, time.monotonic()

    def on_reward(self, index: int, msg: Reward) -> None:
        view = self.views[index]
        if msg.episode_frame <= 1:  # a new episode's first frame
            self.end_episode(index)
            view.climbs, view.highest, view.stage = [], 0, -1
        if msg.subtask != view.stage:
            view.stage, view.confidence_sum, view.confidence_frames = msg.subtask, 0.0, 0
        if msg.subtask > view.highest:
            view.climbs.append((msg.episode_frame, msg.subtask))
            view.highest = msg.subtask
        done = " done" if msg.subtask >= msg.num_subtasks else ""  # Reward.subtask == num_subtasks: all done
        view.reward, view.subtask = msg.total, f"{msg.subtask}/{msg.num_subtasks}{done}"
        view.confidence_sum += msg.stage_confidence
        view.confidence_frames += 1
        view.num_subtasks = msg.num_subtasks
        view.trace.append((msg.total, msg.subtask))

    def on_status(self, index: int, msg: EpisodeStatus) -> None:
        view = self.views[index]
        if msg.step > 0:
            view.steps += 1
        if msg.truncated:
            view.episodes += 1
            view.scores.append(msg.score)
            view.finished = msg  # its line waits for the reward of its last frame

    def end_episode(self, index: int) -> None:
        """Queue the episode line of stream `index`'s finished episode, if there is one."""
        view = self.views[index]
        if view.finished is None:
            return
        if self.episode_lines:
            blocks, score = view.finished.blocks_in_order, view.finished.score
            self.events.append(
                f"{self.namespaces[index] or '/'}: episode {view.episodes}: {blocks} of {NUM_BLOCKS} blocks placed "
                "in order "
                f"(score {score:.2f}); the learned reward's {climb_text(view.climbs, view.num_subtasks)}"
            )
        view.finished = None

    def take_events(self, final: bool = False) -> list[str]:
        """The episode lines to print now; `final`: also those whose next episode never came."""
        if final:
            for index in range(len(self.views)):
                self.end_episode(index)
        events, self.events = self.events, []
        return events

    def on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name.startswith("inest_reward_node"):
                values = {item.key: item.value for item in status.values}
                self.health = (
                    f"reward node {float(values['rate_hz']):.0f} Hz, p99 {float(values['latency_p99_ms']):.1f} ms, "
                    f"rejected {values['rejected']}, dropped {values['dropped']}"
                )

    def total_steps(self) -> int:
        return sum(view.steps for view in self.views)

    def line(self) -> str:
        now = time.monotonic()
        steps = self.total_steps()
        rate = (steps - self.last_steps) / max(now - self.last_time, 1e-9)
        self.last_steps, self.last_time = steps, now
        scores = [score for view in self.views for score in view.scores]
        streams = "  ".join(
            f"{namespace or '/'}: r {view.reward:+.3f} subtask {view.subtask}{confidence_text(view.confidence)}"
            for namespace, view in zip(self.namespaces, self.views, strict=True)
        )
        mean_score = f"{sum(scores) / len(scores):.2f}" if scores else "-"
        episodes = sum(view.episodes for view in self.views)
        return f"steps {steps}  {rate:6.1f} steps/s  {streams}  episodes {episodes} (score {mean_score})  {self.health}"

    def plot(self, path: str | Path) -> None:
        """Reward and subtask over the last steps of each stream."""
        import matplotlib.pyplot as plt

        figure = self.trace_figure()
        figure.savefig(path, dpi=100, format="png")
        plt.close(figure)

    def trace_figure(self):
        """The reward-trace figure: the subtask axis runs 0 .. num_subtasks, its top labelled "done"."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        figure, (top, bottom) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
        for namespace, view in zip(self.namespaces, self.views, strict=True):
            if view.trace:
                rewards, subtasks = zip(*view.trace, strict=True)
                top.plot(rewards, label=namespace or "/")
                bottom.step(range(len(subtasks)), subtasks, where="post", label=namespace or "/")
        top.set(
            ylabel="learned reward",
            title=f"The learned reward and its subtask, last {TRACE_STEPS} frames per simulator",
        )
        bottom.set(xlabel="frame", ylabel="subtask")
        subtasks = max((view.num_subtasks for view in self.views), default=0)
        if subtasks:
            bottom.set_yticks(range(subtasks + 1), [*map(str, range(subtasks)), "done"])
            bottom.set_ylim(-0.2, subtasks + 0.2)
        if any(view.trace for view in self.views):  # an empty legend only warns
            top.legend(loc="upper left")
        figure.tight_layout()
        return figure


def watch(monitor: GraphMonitor, interval: float, until=lambda: False, duration: float | None = None) -> None:
    """Spin the monitor, printing a line every `interval` s, until `until()` or `duration` is over."""
    end = None if duration is None else time.monotonic() + duration
    next_print = time.monotonic() + interval
    live = sys.stdout.isatty()

    def print_events(final: bool = False) -> None:
        for event in monitor.take_events(final):
            print(("\r\x1b[K" if live else "") + event, flush=True)  # above the live line

    printed_steps, printed_at = -1, 0.0
    while rclpy.ok() and not until() and (end is None or time.monotonic() < end):
        rclpy.spin_once(monitor, timeout_sec=0.1)
        print_events()
        if (now := time.monotonic()) >= next_print:
            line, steps = monitor.line(), monitor.total_steps()
            if steps != printed_steps or now - printed_at >= QUIET_LINE_S:
                print(("\r" if live else "") + line, end="" if live else "\n", flush=True)
                printed_steps, printed_at = steps, now
            next_print += interval
    print_events(final=True)
    if live:
        print()


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--namespaces", nargs="+", default=["sim0"], help="simulator namespaces ('' for none)")
    parser.add_argument("--interval", type=float, default=1.0, help="seconds between lines")
    parser.add_argument("--duration", type=float, help="stop after this many seconds (default: Ctrl-C)")
    parser.add_argument("--plot", help="write a reward-trace PNG here on exit")
    parser.add_argument("--episode-lines", action="store_true", help="a line per finished episode")
    args = parser.parse_args(argv)
    rclpy.init()
    monitor = GraphMonitor(args.namespaces, args.episode_lines)
    try:
        watch(monitor, args.interval, duration=args.duration)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if args.plot:
            monitor.plot(args.plot)
        monitor.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0
