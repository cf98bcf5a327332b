"""Stop long work cleanly on SIGINT or SIGTERM: the first signal asks it to stop (training
ends its iteration and writes a checkpoint), a second stops at once (KeyboardInterrupt).

Ray's driver installs its own SIGTERM handlers when it starts (one of them dumps native
stacks and aborts), so :meth:`SignalStop.install` is called again once Ray is up.
"""

from __future__ import annotations

import logging
import signal
from collections.abc import Callable
from types import FrameType, TracebackType
from typing import Any

logger = logging.getLogger(__name__)
SIGNALS = (signal.SIGINT, signal.SIGTERM)


class SignalStop:
    """A context that handles SIGINT and SIGTERM in the main thread, restoring the handlers
    found at the first :meth:`install` when it exits.

    Attributes:
        received: the signals received, in order.
    """

    def __init__(self, what: str = "stopping with a checkpoint of the last update") -> None:
        self.what = what
        self.received: list[signal.Signals] = []
        self._stop: Callable[[], None] | None = None
        self._previous: dict[signal.Signals, Any] = {}

    @property
    def first(self) -> signal.Signals | None:
        return self.received[0] if self.received else None

    def install(self) -> None:
        """Take SIGINT and SIGTERM (again: after Ray has put in its own handlers)."""
        for sig in SIGNALS:
            previous = signal.signal(sig, self._handle)
            self._previous.setdefault(sig, previous)

    def restore(self) -> None:
        """Give SIGINT and SIGTERM back to the handlers found at the first install."""
        for sig, previous in self._previous.items():
            signal.signal(sig, previous)
        self._previous.clear()

    def on_stop(self, stop: Callable[[], None]) -> None:
        """Call ``stop`` on the first signal (at once if one came already)."""
        self._stop = stop
        if self.received:
            stop()

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        sig = signal.Signals(signum)
        self.received.append(sig)
        if len(self.received) > 1:
            self.restore()
            raise KeyboardInterrupt(sig.name)
        logger.warning("%s: %s (%s again to stop at once)", sig.name, self.what, sig.name)
        if self._stop is not None:
            self._stop()

    def __enter__(self) -> SignalStop:
        self.install()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.restore()
