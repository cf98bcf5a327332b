"""Fault injection, a test hook: a real simulator made to crash, hang or NaN.

    GAITFORGE_TEST_FAULTS='{"nan_prob": 0.1}' pytest ...     # every simulator of the process

``abort`` kills the process with ``os.abort`` (SIGABRT, as a segfaulting simulator would);
``hang`` sleeps inside ``step`` (as a stuck integrator would); ``nan`` writes NaN into the
simulator's own state and steps it, so the backend's health checks see a real failure. The
environment variable is read when a simulator is made; the rollout pool passes it on to its
Ray actors. It is no part of a scene or a job: nothing a user submits can set it.
"""

from __future__ import annotations

import logging
import os
import time
from typing import Annotated

import numpy as np
from gaitforge.workers.sim.base import Health, Reflex, Simulator
from pydantic import BaseModel, ConfigDict, Field

logger = logging.getLogger(__name__)

FAULTS_ENV = "GAITFORGE_TEST_FAULTS"
"""the environment variable holding the faults to inject, as JSON"""
Probability = Annotated[float, Field(ge=0, le=1)]


class FaultInjection(BaseModel):
    """Per control step, the chance of each fault."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    abort_prob: Probability = 0.0
    hang_prob: Probability = 0.0
    hang_s: Annotated[float, Field(gt=0)] = 3600.0
    nan_prob: Probability = 0.0

    def as_environment(self) -> dict[str, str]:
        """``{FAULTS_ENV: json}``: set it (``monkeypatch.setenv``) to inject these faults."""
        return {FAULTS_ENV: self.model_dump_json()}


def injected_faults() -> FaultInjection | None:
    """The faults :data:`FAULTS_ENV` asks for in this process (None: none).

    Raises:
        ValueError: the variable is set but not a valid :class:`FaultInjection` (a test's
            mistake, named).
    """
    text = os.environ.get(FAULTS_ENV)
    if not text:
        return None
    return FaultInjection.model_validate_json(text)


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
