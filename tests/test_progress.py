"""Progress output: a bar on a terminal, whole lines in a log."""

from __future__ import annotations

import io
import re
import subprocess
import sys
import time

from inest_common.progress import track


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_log_gets_whole_lines_and_a_terminal_gets_the_bar():
    log = io.StringIO()
    for _ in track(range(1000), desc="work", file=log):
        pass
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue() and 1 <= len(lines) <= 3  # first and last line, no redraws
    assert lines[-1].startswith("work: 100%") and "1000/1000" in lines[-1]
    # never redrawn by tqdm's monitor thread, which would repeat the last line with a stale count
    assert track(range(3), file=io.StringIO()).maxinterval == float("inf")
    log = io.StringIO()
    for _ in track(range(10), desc="nested", file=log, leave=False):  # a bar a terminal would clear
        pass
    assert log.getvalue().splitlines()[-1].startswith("nested: 100%")
    terminal = Terminal()
    for _ in track(range(10), desc="bar", file=terminal, mininterval=0):
        pass
    assert "\r" in terminal.getvalue()


# a loop that runs fast for a second (an agent's random steps before its updates begin), then at
# 100 steps/s; it says on stdout where the slow part began
SLOWING_LOOP = """
import time
from inest_common import progress
progress.LINE_INTERVAL = 0.2  # seconds between log lines (30 in use)
bar = progress.track(total=10**9, desc="steps")
start = time.monotonic()
while time.monotonic() < start + 1.0:
    bar.update(1)
print(bar.n, flush=True)
while True:
    time.sleep(0.01)
    bar.update(1)
"""


def test_a_killed_process_log_shows_how_far_it_got_after_it_slowed_down(tmp_path):
    """tqdm's default spaced a log's lines by the count of the first interval: once the loop slowed
    down, no line came for minutes, and a killed agent's log ended at its fast start."""
    log = tmp_path / "loop.log"
    with open(log, "w") as stderr:
        loop = [sys.executable, "-c", SLOWING_LOOP]
        process = subprocess.Popen(loop, stdout=subprocess.PIPE, stderr=stderr, text=True)
    slowed_at = int(process.stdout.readline())
    time.sleep(2.0)  # some 200 slow steps, ten line intervals
    process.kill()
    process.communicate()
    counts = [int(count) for count in re.findall(r"\| (\d+)/1000000000 \[", log.read_text())]
    assert counts and counts[-1] >= slowed_at + 20, log.read_text()  # a line came while it was slow
