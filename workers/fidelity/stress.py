"""Numerical stability at the extremes: every profile under hostile inputs, and bisection
for the largest stable timestep (MuJoCo) or loosest stable accuracy (OpenSim).

A scenario fails when the simulator reports any health cause (NaN, a MuJoCo warning
counter such as BADQACC, which MuJoCo raises while silently resetting the state, an
OpenSim integrator failure, a joint speed above ``MAX_SPEED``). Falling is not a failure.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from gaitforge.workers.bodies import load_body
from gaitforge.workers.fidelity.grid import (
    MUJOCO_INTEGRATORS,
    OPENSIM_INTEGRATORS,
    OPENSIM_MAX_STEP,
)
from gaitforge.workers.fidelity.held import describe, root_dofs_mujoco, with_profile
from gaitforge.workers.scenes import Scene
from gaitforge.workers.scenes.profiles import FidelityProfile
from gaitforge.workers.sim import Simulator, make_simulator

logger = logging.getLogger(__name__)

SCENARIOS = ("zeros", "ones", "bang-bang", "random", "spin", "drop")
"""zeros / ones: all excitations 0 / 1; bang-bang: all 0 and all 1 alternating every
control step; random: uniform in [0, 1] each step; spin: every kept dof starts at
``SPIN_SPEED`` (alternating sign) under random excitations; drop: the body starts
``DROP_HEIGHT`` above the ground under random excitations."""
SPIN_SPEED = 20.0
"""rad/s (or m/s) initial speed of every kept dof in the ``spin`` scenario."""
DROP_HEIGHT = 0.5
"""m the body is raised before the ``drop`` scenario."""
LOOSEST_ACCURACY = 0.5
TIGHTEST_ACCURACY = 1e-6
MIN_STEP = 0.00025
"""s: the smallest MuJoCo step bisection considers."""


def scenario_excitations(name: str, n_muscles: int, steps: int, seed: int) -> np.ndarray:
    """[steps, n_muscles] excitations of a scenario."""
    rng = np.random.default_rng(seed)
    if name == "zeros":
        return np.zeros((steps, n_muscles))
    if name == "ones":
        return np.ones((steps, n_muscles))
    if name == "bang-bang":
        return np.repeat((np.arange(steps) % 2)[:, None], n_muscles, axis=1).astype(float)
    return rng.uniform(0.0, 1.0, (steps, n_muscles))


def _perturb(sim: Simulator, backend: str, name: str) -> None:
    """Apply the initial-state part of a scenario to a freshly reset simulator."""
    if name not in ("spin", "drop"):
        return
    if backend == "mujoco":
        import mujoco  # lazy: the OpenSim path needs no MuJoCo

        m, d = sim.model, sim.data  # type: ignore[attr-defined]
        if name == "spin":
            for k, dof in enumerate(sim.dof_names):
                jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, dof)
                d.qvel[m.jnt_dofadr[jid]] = SPIN_SPEED * (-1) ** k
        else:
            _, lift = root_dofs_mujoco(sim)
            if lift >= 0:
                d.qpos[lift] += DROP_HEIGHT
        mujoco.mj_forward(m, d)
        return
    model, state = sim.model, sim.osim_state  # type: ignore[attr-defined]
    coords = model.getCoordinateSet()
    if name == "spin":
        for k, dof in enumerate(sim.dof_names):
            coords.get(dof).setSpeedValue(state, SPIN_SPEED * (-1) ** k)
    else:
        root = load_body(sim.scene.body).ordered_joints()[0]  # type: ignore[attr-defined]
        for dof in root.dofs:
            if dof.type == "slide" and abs(dof.axis[sim.up_axis]) > 0.999:
                coord = coords.get(dof.name)
                coord.setValue(state, coord.getValue(state) + DROP_HEIGHT, False)
    model.realizeVelocity(state)


def run_scenario(
    scene: Scene, backend: str, profile: FidelityProfile, name: str, seconds: float, seed: int = 0
) -> str:
    """Health cause of the first failing step of scenario ``name`` (``"ok"`` if none)."""
    sim = make_simulator(with_profile(scene, backend, profile), backend)
    sim.reset(seed)
    _perturb(sim, backend, name)
    dt = 1.0 / scene.control_hz
    steps = max(1, round(seconds / dt))
    for u in scenario_excitations(name, len(sim.muscle_names), steps, seed):
        health = sim.step(u, dt)
        if not health.ok:
            return health.cause
        if not sim.state().is_finite():
            return "nan_state"
    return "ok"


def stability_map(
    scene: Scene,
    backend: str,
    profiles: list[FidelityProfile],
    seconds: float,
    scenarios: tuple[str, ...] = SCENARIOS,
    on_done: Callable[[str], None] | None = None,
) -> list[dict[str, str]]:
    """One row per profile: ``{"profile": label, scenario: cause, ...}``."""
    rows = []
    for profile in profiles:
        row = {"profile": describe(profile)}
        for name in scenarios:
            row[name] = run_scenario(scene, backend, profile, name, seconds)
            if on_done is not None:
                on_done(f"{row['profile']}: {name}")
        rows.append(row)
    return rows


def _stable(
    scene: Scene, backend: str, profile: FidelityProfile, seconds: float, scenarios: tuple[str, ...]
) -> bool:
    return all(run_scenario(scene, backend, profile, s, seconds) == "ok" for s in scenarios)


@dataclass
class Limit:
    """Bisection result for one integrator.

    Attributes:
        integrator: its name.
        largest_stable: largest stable MuJoCo step (s) or loosest stable OpenSim accuracy;
            ``None`` if even the finest setting tried failed.
        smallest_unstable: the neighbouring failing setting (``None`` if none failed).
        checks: settings tried.
    """

    integrator: str
    largest_stable: float | None
    smallest_unstable: float | None
    checks: int


def bisect_limits(
    scene: Scene,
    backend: str,
    seconds: float,
    integrators: tuple[str, ...] | None = None,
    scenarios: tuple[str, ...] = SCENARIOS,
    on_done: Callable[[str], None] | None = None,
) -> list[Limit]:
    """Per integrator, the largest stable step (MuJoCo: among divisors of the control
    period down to ``MIN_STEP``) or loosest stable accuracy (OpenSim: quarter decades from
    ``LOOSEST_ACCURACY`` to ``TIGHTEST_ACCURACY``), by bisection, assuming stability is
    monotone in the setting. Stable means every scenario healthy for ``seconds``."""
    period = 1.0 / scene.control_hz
    if backend == "mujoco":
        names = integrators or MUJOCO_INTEGRATORS
        # candidate k: step = period / n_k, n from 1 (coarsest) up
        n_max = max(1, math.floor(period / MIN_STEP + 1e-9))
        settings = [period / n for n in range(1, n_max + 1)]

        def make(i: str, v: float) -> FidelityProfile:
            return FidelityProfile(integrator=i, timestep=v)
    else:
        names = integrators or OPENSIM_INTEGRATORS
        lo, hi = math.log10(LOOSEST_ACCURACY), math.log10(TIGHTEST_ACCURACY)
        settings = [
            10 ** (lo + (hi - lo) * k / round((lo - hi) * 4))
            for k in range(round((lo - hi) * 4) + 1)
        ]

        def make(i: str, v: float) -> FidelityProfile:
            return FidelityProfile(integrator=i, timestep=OPENSIM_MAX_STEP, accuracy=v)

    limits = []
    for integrator in names:
        checks = 0

        def ok(k: int, integrator: str = integrator) -> bool:
            nonlocal checks
            checks += 1
            stable = _stable(scene, backend, make(integrator, settings[k]), seconds, scenarios)
            if on_done is not None:
                on_done(f"{integrator} {settings[k]:.3g}: {'stable' if stable else 'unstable'}")
            return stable

        # settings run from loosest (index 0) to finest; find the first stable index
        if ok(0):
            limits.append(Limit(integrator, settings[0], None, checks))
            continue
        last = len(settings) - 1
        if not ok(last):
            limits.append(Limit(integrator, None, settings[last], checks))
            continue
        bad, good = 0, last
        while good - bad > 1:
            mid = (bad + good) // 2
            if ok(mid):
                good = mid
            else:
                bad = mid
        limits.append(Limit(integrator, settings[good], settings[bad], checks))
        logger.info("%s: largest stable %.3g", integrator, settings[good])
    return limits
