"""Progress output: a bar on a terminal, whole lines in a log."""

from __future__ import annotations

import io

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
