"""Fault injection (test-only scene setting): a real simulator made to crash, hang or NaN.

``abort`` kills the process with ``os.abort`` (SIGABRT, as a segfaulting simulator would);
``hang`` sleeps inside ``step`` (as a stuck integrator would); ``nan`` writes NaN into the
simulator's own state and steps it, so the backend's health checks see a real failure.
"""

from __future__ import annotations

import logging
import os
import time

import numpy as np
from gaitforge.workers.scenes.spec import FaultInjection
from gaitforge.workers.sim.base import Health, Reflex, Simulator

logger = logging.getLogger(__name__)


class FaultySimulator:
    """Wraps a simulator; everything but ``step`` and ``step_reflex`` passes through."""

    def __init__(self, sim: Simulator, fault: FaultInjection) -> None:
        self._sim = sim
        self._fault = fault
        self._rng = np.random.default_rng(0)

    def __getattr__(self, name: str) -> object:
        return getattr(self._sim, name)

    def reset(self, seed: int) -> None:
        """Reset the simulator; the faults of the episode follow from ``seed`` too."""
        self._rng = np.random.default_rng([seed, 0xFA17])
        self._sim.reset(seed)

    def step(self, excitations: np.ndarray, duration: float) -> Health:
        self._inject()
        return self._sim.step(excitations, duration)

    def step_reflex(
        self, reflex: Reflex, duration: float, updates: int
    ) -> tuple[np.ndarray, Health]:
        self._inject()
        return self._sim.step_reflex(reflex, duration, updates)

    def _inject(self) -> None:
        """This control step's faults, drawn from the episode's generator."""
        draw = self._rng.uniform(size=3)
        if draw[0] < self._fault.abort_prob:
            logger.warning("fault injection: aborting process %d", os.getpid())
            os.abort()
        if draw[1] < self._fault.hang_prob:
            logger.warning("fault injection: hanging for %.0f s", self._fault.hang_s)
            time.sleep(self._fault.hang_s)
        if draw[2] < self._fault.nan_prob:
            self._sim.poison()

    def __getstate__(self) -> dict:
        return {"sim": self._sim, "fault": self._fault}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["sim"], state["fault"])  # type: ignore[misc]
