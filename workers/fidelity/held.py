"""The contact-free, pelvis-held variant of a scene, and seeded excitation rollouts on it.

Integration error is measured where trajectories do not diverge for physical reasons:
contact switches amplify any difference, so the variant holds the pelvis 1 m above its
standing height (the feet never reach the ground) and drives the muscles with a fixed,
seeded excitation sequence. What differs between two profiles is then the integration.

How the pelvis is held, per backend (no change to the simulators is needed):

- MuJoCo: contacts are disabled (``mjDSBL_CONTACT``) and the root dofs get an armature of
  ``HOLD_ARMATURE`` (kg or kg m^2): the legs' reactions move them by less than 1e-5 m or
  rad over 2 s (measured and returned as ``root_drift``), identically for every profile.
- OpenSim: the root coordinates are locked in the state (``Coordinate.setLocked``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from gaitforge.workers.bodies.topology import topology_for
from gaitforge.workers.scenes import Scene
from gaitforge.workers.scenes.profiles import FidelityProfile
from gaitforge.workers.sim import Simulator, make_simulator

HOLD_HEIGHT = 1.0
"""m the pelvis is raised above its standing height in the held variant."""
HOLD_ARMATURE = 1e9
"""kg (slides) or kg m^2 (hinges): MuJoCo armature that holds the root dofs still."""
EXCITATION_HOLD_S = 0.05
"""s each random excitation level of the seeded sequence is held (then a new draw)."""


def with_profile(scene: Scene, backend: str, profile: FidelityProfile, **update: object) -> Scene:
    """``scene`` on ``backend`` only, integrated with ``profile``, validated again.

    Raises:
        SpecError: the profile does not fit the scene (e.g. a MuJoCo step that does not
            divide the control period).
    """
    from gaitforge.workers.spec_io import validate_model

    raw = scene.model_dump(mode="python")
    raw.update(backends=[backend], fidelity={backend: profile.model_dump()}, **update)
    return validate_model(raw, Scene, f"scene {scene.name!r} with {describe(profile)}")


def describe(profile: FidelityProfile) -> str:
    """A short label, e.g. ``rk4 0.25ms`` or ``rk-merson acc 1e-03`` or ``rk2 fixed 1ms``."""
    step = f"{profile.timestep * 1e3:g}ms"
    if profile.fixed_step or profile.accuracy is None:
        return f"{profile.integrator} {'fixed ' if profile.fixed_step else ''}{step}"
    return f"{profile.integrator} acc {profile.accuracy:.0e}"


def excitation_sequence(n_muscles: int, steps: int, dt: float, seed: int) -> np.ndarray:
    """[steps, n_muscles] excitations in [0, 1]: uniform draws held ``EXCITATION_HOLD_S``."""
    rng = np.random.default_rng(seed)
    hold = max(1, round(EXCITATION_HOLD_S / dt))
    draws = rng.uniform(0.0, 1.0, (-(-steps // hold), n_muscles))
    return np.repeat(draws, hold, axis=0)[:steps]


def body_excitations(body: str, muscles: list[str], steps: int, dt: float, seed: int) -> np.ndarray:
    """[steps, len(muscles)]: the seeded sequence drawn over all of ``body``'s muscles in
    name order, so that a muscle gets the same excitation whichever backend or pruning
    (which muscles are kept, in which order) runs it."""
    every = sorted(topology_for(body).muscles)
    u = excitation_sequence(len(every), steps, dt, seed)
    return u[:, [every.index(m) for m in muscles]]


def hold(sim: Simulator, backend: str) -> None:
    """Make a freshly reset simulator the held variant (pelvis raised, held, no contact)."""
    if backend == "mujoco":
        _hold_mujoco(sim)
    else:
        _hold_opensim(sim)


def root_dofs_mujoco(sim: Simulator) -> tuple[np.ndarray, int]:
    """(root dof addresses, qpos address of the vertical root coordinate) of a MuJoCo sim:
    the root dofs are those of the joints between the world and its child bodies, less any
    dof the scene keeps (a fixed-base body such as the elbow has none to hold)."""
    import mujoco

    m = sim.model  # type: ignore[attr-defined]
    dofs: list[int] = []
    lift = -1
    kept = set(sim.dof_names)
    for j in range(m.njnt):
        if m.body_parentid[m.jnt_bodyid[j]] != 0 or m.joint(j).name in kept:
            continue
        n = {0: 6, 1: 3, 2: 1, 3: 1}[int(m.jnt_type[j])]  # free, ball, slide, hinge
        dofs += range(m.jnt_dofadr[j], m.jnt_dofadr[j] + n)
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            lift = int(m.jnt_qposadr[j]) + sim.up_axis
        elif (
            m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE and abs(m.jnt_axis[j][sim.up_axis]) > 0.999
        ):
            lift = int(m.jnt_qposadr[j])
    return np.array(dofs, dtype=int), lift


def _hold_mujoco(sim: Simulator) -> None:
    import mujoco

    m, d = sim.model, sim.data  # type: ignore[attr-defined]
    dofs, lift = root_dofs_mujoco(sim)
    m.dof_armature[dofs] = HOLD_ARMATURE
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    if lift >= 0:
        d.qpos[lift] += HOLD_HEIGHT
    mujoco.mj_forward(m, d)


def _hold_opensim(sim: Simulator) -> None:
    from gaitforge.workers.bodies import load_body

    model, state = sim.model, sim.osim_state  # type: ignore[attr-defined]
    coords = model.getCoordinateSet()
    root = load_body(sim.scene.body).ordered_joints()[0]  # type: ignore[attr-defined]
    for dof in root.dofs:
        coord = coords.get(dof.name)
        if dof.type == "slide" and abs(dof.axis[sim.up_axis]) > 0.999:
            coord.setValue(state, coord.getValue(state) + HOLD_HEIGHT, False)
        coord.setSpeedValue(state, 0.0)
    model.assemble(state)
    for dof in root.dofs:
        coords.get(dof.name).setLocked(state, True)
    model.realizeVelocity(state)
    model.equilibrateMuscles(state)


@dataclass
class Rollout:
    """One held rollout.

    Attributes:
        dofs: names of the columns of ``q``.
        q: [steps + 1, n_dofs] kept dof positions (rad or m), the reset pose first.
        health: cause of the first failure, ``"ok"`` if none.
        wall_s: wall-clock time of the steps, s.
        steps: control steps completed.
        root_drift: largest change of the pelvis position over the rollout, m.
    """

    dofs: list[str]
    q: np.ndarray
    health: str
    wall_s: float
    steps: int
    root_drift: float


def held_rollout(
    scene: Scene, backend: str, profile: FidelityProfile, seconds: float, seed: int = 0
) -> Rollout:
    """Run the held variant of ``scene`` (no reset noise) under ``profile`` for ``seconds``
    of simulated time with the excitation sequence of ``seed``; stops at the first health
    failure."""
    sim = make_simulator(with_profile(scene, backend, profile, init_noise=0.0), backend)
    sim.reset(seed)
    hold(sim, backend)
    dt = 1.0 / scene.control_hz
    steps = round(seconds / dt)
    u = body_excitations(scene.body, sim.muscle_names, steps, dt, seed)
    root0 = sim.state().pelvis_pos
    q = [sim.state().dof_pos]
    health = "ok"
    start = time.perf_counter()
    for k in range(steps):
        h = sim.step(u[k], dt)
        if not h.ok:
            health = h.cause
            break
        q.append(sim.state().dof_pos)
    wall = time.perf_counter() - start
    drift = float(np.abs(sim.state().pelvis_pos - root0).max(initial=0.0))
    return Rollout(list(sim.dof_names), np.array(q), health, wall, len(q) - 1, drift)


def rms_error(a: Rollout, b: Rollout, seconds: float, dt: float) -> float:
    """RMS over time and shared dofs of ``a.q - b.q`` over the first ``seconds`` (rad or m);
    ``inf`` if either rollout failed before then."""
    n = round(seconds / dt) + 1
    if len(a.q) < n or len(b.q) < n:
        return float("inf")
    shared = [d for d in a.dofs if d in b.dofs]
    qa = a.q[:n, [a.dofs.index(d) for d in shared]]
    qb = b.q[:n, [b.dofs.index(d) for d in shared]]
    return float(np.sqrt(np.mean((qa - qb) ** 2)))
