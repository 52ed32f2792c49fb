"""Progress bars for long work: tqdm's bar on a terminal, plain lines when the output is a log
file or a pipe (a line at most every LINE_INTERVAL seconds and one at the end), so that a log
holds readable lines instead of hundreds of carriage-return redraws."""

from __future__ import annotations

import sys
from collections.abc import Iterable
from typing import Any, TextIO

from tqdm import tqdm

LINE_INTERVAL = 30.0  # seconds between progress lines in a log


class LineStream:
    """Turns tqdm's carriage-return redraws into whole lines on `stream`."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream

    def write(self, text: str) -> None:
        line = text.replace("\r", "").strip()
        if line:
            self.stream.write(line + "\n")

    def flush(self) -> None:
        self.stream.flush()


def track(iterable: Iterable[Any] | None = None, **kwargs: Any) -> tqdm:
    """tqdm(iterable, **kwargs), line-based when its output (`file`, default stderr) is not a terminal."""
    stream = kwargs.pop("file", None) or sys.stderr
    if kwargs.get("disable") or stream.isatty():
        return tqdm(iterable, file=stream, **kwargs)
    kwargs.setdefault("mininterval", LINE_INTERVAL)
    # a line every `mininterval` whatever the speed: tqdm's default adapts the count between lines to
    # the first interval's rate, so after a fast start (an agent's random steps before its updates
    # begin) a slower loop wrote no line for minutes, and a killed run's log did not show how far it got
    kwargs.setdefault("miniters", 1)
    # tqdm's monitor thread redraws a bar quiet for `maxinterval` (10 s) with the count of its last
    # draw (a loop over an iterable keeps its count to itself between draws): in a log, each line again
    kwargs.setdefault("maxinterval", float("inf"))
    kwargs["leave"] = True  # a log keeps the final line: leave=False would end it on the first one, at 0 %
    return tqdm(iterable, file=LineStream(stream), ascii=True, ncols=100, **kwargs)
