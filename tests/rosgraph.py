"""Helpers for the integration tests: real node processes on a private ROS domain, on loopback."""

from __future__ import annotations

import itertools
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import rclpy
from inest_bringup.launcher import graph_environment

BIN = Path(sys.executable).parent
_domains = itertools.count()


def fresh_domain() -> int:
    """A ROS_DOMAIN_ID no other test of this run uses, and unlikely to meet a parallel run's."""
    return 1 + (os.getpid() * 13 + next(_domains)) % 200


class Processes:
    """Started node processes, each logging to its own file; all stopped at the end of the test."""

    def __init__(self, domain: int, log_dir: Path) -> None:
        self.env = {**graph_environment(domain, log_dir / "ros"), "PYTHONUNBUFFERED": "1"}
        self.log_dir = log_dir
        self.running: dict[str, subprocess.Popen] = {}

    def start(self, name: str, *argv: str) -> subprocess.Popen:
        log = open(self.log_dir / f"{name}.log", "w")  # noqa: SIM115 (closed with the process)
        command = [str(BIN / argv[0]) if (BIN / argv[0]).exists() else argv[0], *argv[1:]]
        process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, env=self.env, cwd=self.log_dir)
        self.running[name] = process
        return process

    def watch(self, msg_type: type, topic: str, enough: Callable[[list], bool], timeout: float = 90) -> list:
        """The messages of `topic` on this graph's domain, until `enough(messages)` or `timeout` s."""
        rclpy.init(domain_id=int(self.env["ROS_DOMAIN_ID"]))
        messages: list = []
        try:
            node = rclpy.create_node("watcher")
            node.create_subscription(msg_type, topic, messages.append, 50)
            deadline = time.monotonic() + timeout
            while not enough(messages) and time.monotonic() < deadline:
                rclpy.spin_once(node, timeout_sec=0.05)
        finally:
            rclpy.shutdown()
        return messages

    def log(self, name: str) -> str:
        return (self.log_dir / f"{name}.log").read_text()

    def stop_all(self) -> None:
        for process in self.running.values():
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
        deadline = time.monotonic() + 10
        for process in self.running.values():
            try:
                process.wait(max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
