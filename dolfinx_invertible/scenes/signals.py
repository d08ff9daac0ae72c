"""SIGINT and SIGTERM during a scene run: held while a step is written, then an interruption."""

from __future__ import annotations

import contextlib
import signal

__all__ = ["RunInterrupted", "Signals"]


class RunInterrupted(BaseException):  # noqa: N818 (an interruption, not an error)
    """Raised inside a run by SIGINT or SIGTERM, so that the summary still gets written.

    A :class:`BaseException`, like :class:`KeyboardInterrupt`: handlers of ``Exception`` (e.g.
    around a file rewrite) must not turn it into an error.
    """


class Signals:
    """Turn SIGINT and SIGTERM into :class:`RunInterrupted` while a run is stepping.

    Inside :meth:`deferred` (writing a step) a signal is held until the block ends, so every
    step in the output is complete.
    """

    def __enter__(self):
        self._previous = {}
        self._held: int | None = None
        self._deferring = False
        for number in (signal.SIGINT, signal.SIGTERM):
            try:
                self._previous[number] = signal.signal(number, self._received)
            except ValueError:  # not the main thread
                pass
        return self

    def _received(self, number, frame):
        if self._deferring:
            self._held = number
        else:
            self._raise(number)

    @staticmethod
    def _raise(number):
        raise RunInterrupted(f"interrupted by {signal.Signals(number).name}")

    @contextlib.contextmanager
    def deferred(self):
        """Hold a signal until the block ends."""
        self._deferring = True
        try:
            yield
        finally:
            self._deferring = False
        if self._held is not None:
            self._raise(self._held)

    def __exit__(self, *exception):
        for number, handler in self._previous.items():
            signal.signal(number, handler)
