"""Keeping the graph's node processes alive (no ROS imports): the launcher's respawn logic, and
the priority and CPUs the environment side runs on while the agent trains.

Like `respawn`/`respawn_delay` of ROS launch, with a bound: a node that exits is started again
after `delay` seconds, doubled for each further restart in a row; one that stays up for
`healthy_after` seconds starts its count over. The graph stops, with one message, when a node
keeps dying (more than `max_respawns` restarts in a row), when one refuses its configuration
(exit code 2: a restart would only repeat it), when one ran out of disk space (NO_SPACE_EXIT:
so would a restart), or when the agent finishes (exit 0).
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from inest_common.files import NO_SPACE_EXIT
from inest_common.processes import dies_with_parent

CONFIG_ERROR = 2  # the nodes' exit code for a bad parameter or run file
FINISHES = "agent"  # the node whose exit 0 means the run is over
# While the agent trains, the simulators and the reward node run this much nicer than it: the
# agent's update, which sets the pace of training over the graph, then does not wait behind them
# for a core (measured in docs/reports/performance.md). Niceness only matters when every core is busy.
TRAINING_NICENESS = 10
# ... and on every CPU this process may use but the first (AUTO_CPUS): the update then runs on a
# CPU no simulator is scheduled on, so none preempts it or moves through its cache
# (docs/reports/performance.md).
AUTO_CPUS, ALL_CPUS = "auto", "all"
CPU_LIST = re.compile(r"[0-9]+(-[0-9]+)?(,[0-9]+(-[0-9]+)?)*")  # taskset's list form, without strides


def parse_cpus(text: str, usable: set[int]) -> set[int]:
    """A CPU list in taskset's syntax ("1", "0,2-3") as a set of CPU numbers, each one of `usable`
    (checked range by range, so "0-1000000000" is refused before it is built)."""
    if not CPU_LIST.fullmatch(text):
        raise ValueError(f"{text!r} is not a CPU list such as 1 or 0,2-3 (nor {AUTO_CPUS} or {ALL_CPUS})")
    cpus: set[int] = set()
    for part in text.split(","):
        first, _, last = part.partition("-")
        low, high = int(first), int(last or first)
        if high < low:
            raise ValueError(f"{text!r} is not a CPU list: the range {part} runs backwards")
        if high > max(usable) or not set(range(low, high + 1)) <= usable:
            raise ValueError(
                f"CPU list {text!r} names CPUs this process may not run on (it may use {format_cpus(usable)})"
            )
        cpus.update(range(low, high + 1))
    return cpus


def parse_niceness(text: str) -> int:
    """How much nicer simulators and reward node run while the agent trains: 0 (off) to 19, the
    range nice(1) grants an unprivileged user above the default priority."""
    if not (text.isdigit() and int(text) <= 19):
        raise ValueError(f"must be an integer between 0 and 19, got {text}")
    return int(text)


def training_cpus(setting: str) -> set[int] | None:
    """The CPUs simulators and reward node are confined to while the agent trains, None for no
    confinement: AUTO_CPUS every CPU this process may use but the lowest (None with one CPU or
    without util-linux's taskset), ALL_CPUS None, else a CPU list of CPUs this process may use."""
    usable = os.sched_getaffinity(0)
    if setting == ALL_CPUS:
        return None
    if setting == AUTO_CPUS:
        return usable - {min(usable)} if len(usable) > 1 and shutil.which("taskset") else None
    cpus = parse_cpus(setting, usable)
    if shutil.which("taskset") is None:
        raise ValueError(f"CPU list {setting!r} needs taskset (util-linux), which is not installed")
    return cpus


def format_cpus(cpus: set[int]) -> str:
    return ",".join(str(cpu) for cpu in sorted(cpus))


def environment_prefix(niceness: int, cpus: set[int] | None) -> list[str]:
    """The command prefix of simulators and reward node while the agent trains, like a ROS launch
    prefix: util-linux `taskset -c CPUS` and coreutils `nice -n NICENESS`, each only when set."""
    pinned = ["taskset", "-c", format_cpus(cpus)] if cpus else []
    return [*pinned, *(["nice", "-n", str(niceness)] if niceness else [])]


@dataclass(frozen=True)
class RespawnPolicy:
    max_respawns: int = 3  # restarts in a row before the graph is stopped
    delay: float = 1.0  # seconds before the first restart, doubled for each further one
    healthy_after: float = 60.0  # seconds up after which a node's restarts count from zero again

    def __post_init__(self) -> None:
        if self.max_respawns < 0 or self.delay < 0 or self.healthy_after <= 0:
            raise ValueError(f"respawn: max_respawns and delay must be >= 0, healthy_after positive, got {self}")


@dataclass
class Child:
    name: str
    command: list[str]
    log: Path
    process: subprocess.Popen | None = None
    started: float = 0.0
    restarts: int = 0  # in a row
    due: float | None = None  # when the scheduled restart starts it


@dataclass(frozen=True)
class Outcome:
    status: int  # the launcher's exit code
    message: str  # why the graph stops ("" when the agent finished)


class Supervisor:
    """The node processes of one graph. `check()` handles exits and due restarts, and says when
    the graph must stop (`outcome`). `respawn_command(name, command)` gives the argv of a restart."""

    def __init__(
        self,
        commands: list[tuple[str, list[str]]],
        log_dir: Path,
        env: dict[str, str],
        policy: RespawnPolicy,
        respawn_command: Callable[[str, list[str]], list[str]] = lambda name, command: command,
    ) -> None:
        self.children = {name: Child(name, command, log_dir / f"{name}.log") for name, command in commands}
        self.env, self.policy, self.respawn_command = env, policy, respawn_command
        self.outcome: Outcome | None = None

    def start_all(self) -> None:
        """Start every node; a log an earlier launch left (a killed run being resumed, say) is
        continued after a separator line, never truncated."""
        for child in self.children.values():
            if child.log.is_file() and child.log.stat().st_size:
                with open(child.log, "a") as log:
                    log.write(f"\n--- inest-launch: started again {time.strftime('%Y-%m-%d %H:%M:%S')} ---\n")
            self.start(child)

    def start(self, child: Child, restart: bool = False) -> None:
        with open(child.log, "a") as log:  # the child keeps its own copy of the descriptor
            # SIGTERM when the launcher dies, even by SIGKILL: no node outlives it (the agent saves
            # its checkpoint on SIGTERM, so a rerun with --resume goes on from there)
            child.process = subprocess.Popen(
                child.command, stdout=log, stderr=subprocess.STDOUT, env=self.env, start_new_session=True,
                preexec_fn=dies_with_parent(signal.SIGTERM),
            )  # fmt: skip
        child.started, child.due = time.monotonic(), None
        verb = "restarted" if restart else "started"
        print(f"inest-launch: {verb} {child.name} (pid {child.process.pid}), log {child.log}", flush=True)

    @property
    def processes(self) -> dict[str, subprocess.Popen]:
        return {name: child.process for name, child in self.children.items() if child.process is not None}

    def check(self) -> bool:
        """Restart what is due, schedule restarts of what exited; True once the graph must stop."""
        now = time.monotonic()
        for child in self.children.values():
            if child.due is not None:
                if now >= child.due:
                    child.command = self.respawn_command(child.name, child.command)
                    with open(child.log, "a") as log:
                        log.write(f"\n--- inest-launch: restart {child.restarts} ---\n")
                    self.start(child, restart=True)
                continue
            code = child.process.poll() if child.process is not None else None
            if code is not None:
                self.outcome = self.exited(child, code, now)
                if self.outcome is not None:
                    return True
        return False

    def exited(self, child: Child, code: int, now: float) -> Outcome | None:
        if child.name == FINISHES and code == 0:
            return Outcome(0, "")
        if code == CONFIG_ERROR:
            return Outcome(CONFIG_ERROR, f"{child.name} refused its configuration: {last_line(child.log)}")
        if code == NO_SPACE_EXIT:
            return Outcome(NO_SPACE_EXIT, f"{child.name} ran out of disk space: {last_line(child.log)}")
        if now - child.started >= self.policy.healthy_after:
            child.restarts = 0
        if child.restarts >= self.policy.max_respawns:
            return Outcome(
                1,
                f"{child.name} keeps dying (exit status {code} after {child.restarts} restarts); "
                f"stopping the graph, see {child.log}",
            )
        delay = self.policy.delay * 2**child.restarts
        child.restarts += 1
        child.due = now + delay
        print(
            f"inest-launch: {child.name} exited with status {code}; restarting it in {delay:.0f} s "
            f"(restart {child.restarts} of {self.policy.max_respawns})",
            file=sys.stderr,
            flush=True,
        )
        return None


def last_line(path: Path) -> str:
    lines = [line for line in path.read_text(errors="replace").splitlines() if line.strip()]
    return lines[-1] if lines else "(its log is empty)"
