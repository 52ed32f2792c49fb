"""Child processes that do not outlive the process that started them (Linux): started with
`preexec_fn=dies_with_parent(signal)`, a child gets that signal when its parent dies, even by
SIGKILL, which the parent cannot pass on itself. Elsewhere it is None: no such arrangement."""

from __future__ import annotations

import ctypes
import sys
from collections.abc import Callable

PR_SET_PDEATHSIG = 1  # prctl(2)
LIBC = ctypes.CDLL(None) if sys.platform == "linux" else None  # loaded here: the child only calls it


def dies_with_parent(signal_number: int) -> Callable[[], None] | None:
    """A `preexec_fn` for subprocess.Popen: the child gets `signal_number` when its parent dies."""
    if LIBC is None:
        return None

    def arrange() -> None:
        LIBC.prctl(PR_SET_PDEATHSIG, signal_number)

    return arrange
