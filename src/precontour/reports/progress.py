"""Progress of long runs: a step counter and a one-line display on stderr.

Computations take an optional ``progress(done, total, message)`` callable; the command line
passes a :class:`ProgressLine`.
"""

from __future__ import annotations

import sys
import time
import weakref
from typing import Callable, TextIO

from .. import kernels
from ..files import check_signals

#: ``progress(done, total, message)``: called before each step (done = steps finished).
Progress = Callable[[int, int, str], None]


class StepCounter:
    """``step(message)`` reports the next of ``total`` steps to ``progress`` (if any)."""

    def __init__(self, progress: Progress | None, total: int):
        self.progress = progress
        self.total = total
        self.done = 0

    def __call__(self, message: str) -> None:
        if self.progress is not None:
            self.progress(self.done, self.total, message)
        self.done += 1


class ReportSteps:
    """The progress of a computation followed by ``after`` steps of the reporting layer (the
    report's writing): passed as the computation's ``progress``, it reports the
    computation's steps with a total that counts the later ones too; :meth:`step` then
    reports each later step, :meth:`finish` the end. The computation returns its result
    only; the count of steps lives here."""

    def __init__(self, progress: Progress | None, after: int = 1):
        self.progress = progress
        self.after = after
        self.done = 0
        self.total = after

    def __call__(self, done: int, total: int, message: str) -> None:
        self.done, self.total = done + 1, total + self.after
        if self.progress is not None:
            self.progress(done, self.total, message)

    def step(self, message: str) -> None:
        if self.progress is not None:
            self.progress(self.done, self.total, message)
        self.done += 1

    def finish(self, message: str) -> None:
        if self.progress is not None:
            self.progress(self.done, self.total, message)


class ProgressLine:
    """Progress display on a stream: one updating line on a terminal, else a line per step.

    Each line reads ``[  12.3 s]  7/41  paper pid-high: simulate ...``; :meth:`close` ends the
    updating line.
    """

    def __init__(self, stream: TextIO | None = None):
        self.stream = sys.stderr if stream is None else stream
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.start = time.perf_counter()
        self._width = 0
        if self.tty:
            # the note before the first compile goes on a line of its own, not after ours
            kernels.before_note.append(weakref.WeakMethod(self.close))

    def __call__(self, done: int, total: int, message: str) -> None:
        check_signals()  # a step begins: where a SIGTERM or Ctrl-C stops the command
        text = f"[{time.perf_counter() - self.start:7.1f} s] {done:3d}/{total} {message}"
        if self.tty:
            pad = max(0, self._width - len(text))
            self.stream.write("\r" + text + " " * pad)
            self._width = len(text)
        else:
            self.stream.write(text + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self.tty and self._width:
            self.stream.write("\n")
            self.stream.flush()
            self._width = 0
