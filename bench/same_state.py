"""MuJoCo put in OpenSim's state, and where their dynamics part: OpenSim let go relaxed
(every excitation 0), or driven by a policy (``--policy``, deterministic, through the scene's
own actions and reflex layer); at each of ``--at-s`` MuJoCo is given OpenSim's joint angles,
speeds, pelvis placement and muscle activations; then, at that instant, each simulator's
contact forces on each body (body weights, forward and up), its kept-joint accelerations
(rad/s²), MuJoCo's again with its contacts replaced by OpenSim's contact forces and torques
on the same bodies, both muscle moment sets (N m), and the generalized force OpenSim's
accelerations need beyond what MuJoCo applies (MuJoCo's inverse dynamics; "force left",
N m). The mass matrices are compared first. What is left once the contact forces are the
same is the muscles' and joints' own modelling; the contact rows are the contact models'
own difference in the same state (MuJoCo's built from ``--mujoco-scene``, e.g. a scene with
MuJoCo's contact options).

Usage: python bench/same_state.py [--scene walk-2d+clock] [--at-s 0.03 ...]
           [--policy CHECKPOINT --seed 0] [--mujoco-scene SCENE]
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import opensim
from gaitforge.learner.checkpoint import load_policy
from gaitforge.learner.evaluation.episodes import make_runner, policy_act
from gaitforge.learner.evaluation.evaluate import resolve_checkpoint
from gaitforge.workers.env import GRAVITY
from gaitforge.workers.episode import Observer
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.sim import make_simulator
from gaitforge.workers.sim.base import Pose
from relaxed_drop import lift  # bench/relaxed_drop.py (this script's folder is on sys.path)
from rich.console import Console
from rich.table import Table

console = Console(width=200)
STEP_S = 0.005
ROOT = ("pelvis_tx", "pelvis_ty", "pelvis_tilt")
Visit = Callable[[Any, float], None]
"""called with OpenSim's simulator and its time from the reset (s) at each time asked for"""


def opensim_muscle_moments(sim) -> np.ndarray:
    """[kept joints]: the muscles' moments (N m) on OpenSim at its present state, tendon
    forces times ``sim.moment_arms()``."""
    sim.model.realizeDynamics(sim.osim_state)
    forces = np.array([mu.getActuation(sim.osim_state) for mu in sim._muscles])
    return forces @ sim.moment_arms()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default="walk-2d+clock", help="a catalogue name or a file")
    parser.add_argument(
        "--at-s",
        type=float,
        nargs="+",
        default=[0.03],
        help="OpenSim's times compared, s from the reset",
    )
    parser.add_argument(
        "--policy", type=Path, default=None, help="a checkpoint driving OpenSim (else relaxed)"
    )
    parser.add_argument("--seed", type=int, default=0, help="the episode's reset seed")
    parser.add_argument("--mujoco-scene", default=None, help="MuJoCo's scene (else --scene)")
    args = parser.parse_args()
    if min(args.at_s) < STEP_S:
        raise SystemExit(f"--at-s: {min(args.at_s)} s is under one {STEP_S} s step")
    scene = load_scene(args.scene).resolved()
    mujoco_scene = load_scene(args.mujoco_scene).resolved() if args.mujoco_scene else scene
    how = f"driven by {args.policy} (seed {args.seed})" if args.policy else "relaxed"

    def visit(op: Any, t: float) -> None:
        for table in compare(op, mujoco_scene, f"{scene.name} on OpenSim, {how}, {t:.3g} s"):
            console.print(table)

    if args.policy is None:
        relaxed(scene, sorted(args.at_s), visit)
    else:
        seen = under_policy(args.policy, scene, args.seed, sorted(args.at_s), visit)
        if missed := [t for t in args.at_s if t not in seen]:
            console.print(f"the episode ended before {missed} s")


def relaxed(scene: Scene, times: list[float], visit: Visit) -> None:
    """OpenSim from the reset (seed 0) with every excitation 0, ``visit`` at each time."""
    op = make_simulator(scene, "opensim")  # the simulators' own objects: a bench probe
    op.reset(0)
    done = 0
    for t in times:
        while done < round(t / STEP_S):
            op.step(np.zeros(len(op.muscle_names)), STEP_S)
            done += 1
        visit(op, t)


def under_policy(
    checkpoint: Path, scene: Scene, seed: int, times: list[float], visit: Visit
) -> list[float]:
    """One deterministic OpenSim episode of ``scene`` with the policy, ``visit`` after the
    control step nearest each time; returns the times visited."""
    policy, _ = load_policy(resolve_checkpoint(checkpoint))
    dt = 1.0 / scene.control_hz
    wanted = {max(1, round(t / dt)): t for t in times}
    seen: list[float] = []

    class AtTimes(Observer):
        step = 0

        def on_step(self, env: Any, *_: Any) -> None:
            self.step += 1
            if self.step in wanted:
                visit(env.sim, wanted[self.step])
                seen.append(wanted[self.step])

    with make_runner(policy, scene, "opensim") as runner:
        runner.run(policy_act(policy, "deterministic", seed), seed, [AtTimes()])
    return seen


def compare(op: Any, mujoco_scene: Scene, title: str) -> tuple[Table, Table]:
    """The tables (accelerations and moments; contact forces) at OpenSim's present state,
    MuJoCo (built from ``mujoco_scene``) put in it."""
    st, coords = op.osim_state, op._coords
    mj = make_simulator(mujoco_scene, "mujoco")
    mj.reset(0)
    m, d = mj.model, mj.data
    joints = [*ROOT, *mj.dof_names]
    dof = {n: int(m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)]) for n in joints}
    _put_in_state(mj, op)
    weight = mj.report.mass * GRAVITY
    contacts = {"OpenSim": _opensim_contact_wrenches(op, st), "MuJoCo": _mujoco_contact_forces(mj)}

    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    index = [dof[n] for n in joints]
    opensim_mass = _opensim_mass_matrix(op, st, [coords[n] for n in joints])
    mass_gap = np.abs(full[np.ix_(index, index)] - opensim_mass).max()

    rows = {"MuJoCo": d.qacc[index].copy()}
    op.model.realizeAcceleration(st)
    rows["OpenSim"] = np.array([coords[n].getAccelerationValue(st) for n in joints])
    muscle_moments = {
        "MuJoCo": d.qfrc_actuator[index[3:]],
        "OpenSim": opensim_muscle_moments(op),
    }

    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    d.xfrc_applied[:] = 0.0  # MuJoCo's own contacts out
    for body, (force, torque) in contacts["OpenSim"].items():
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, body)
        d.xfrc_applied[b, :3] = force  # OpenSim's torque is about the body origin; MuJoCo's
        d.xfrc_applied[b, 3:] = torque + np.cross(d.xpos[b] - d.xipos[b], force)  # its COM
    mujoco.mj_forward(m, d)
    rows["MuJoCo, OpenSim's contacts"] = d.qacc[index].copy()
    # what MuJoCo applies, muscles and those contact wrenches (qfrc_smooth = passive - bias
    # + applied + actuator + the xfrc's); inverse dynamics gives what OpenSim's qacc needs
    applied = d.qfrc_smooth - d.qfrc_passive + d.qfrc_bias
    d.qacc[index] = rows["OpenSim"]
    mujoco.mj_inverse(m, d)
    rows["force left, N m"] = (d.qfrc_inverse - applied)[index]

    table = Table(title=f"{title}; mass matrices differ by at most {mass_gap:.1e}")
    table.add_column("accelerations rad/s² (m/s²)", no_wrap=True)
    for name in joints:
        table.add_column(name, justify="right")
    for name, values in rows.items():
        table.add_row(name, *(f"{v:+.1f}" for v in values))
    for name, values in muscle_moments.items():
        table.add_row(f"muscles {name}, N m", "", "", "", *(f"{v:+.1f}" for v in values))
    ground = Table(title="contact forces in that state, body weights (forward, up)")
    ground.add_column("body")
    for name in contacts:
        ground.add_column(f"{name} forward", justify="right")
        ground.add_column(f"{name} up", justify="right")
    up, forward = mj.up_axis, mj.forward_axis
    for body in sorted({b for wrenches in contacts.values() for b in wrenches}):
        cells = []
        for wrenches in contacts.values():
            force = wrenches.get(body, (np.zeros(3), None))[0] / weight
            cells += [f"{force[forward]:+.2f}", f"{force[up]:+.2f}"]
        ground.add_row(body, *cells)
    return table, ground


def _put_in_state(mj, op) -> None:
    """MuJoCo's joint angles and speeds, pelvis pitch, speeds and height, and its muscles'
    activations set to OpenSim's."""
    st, coords = op.osim_state, op._coords
    own = {n: c for n, c in coords.items() if not n.startswith("pelvis")}
    mj.set_pose(
        Pose(
            coordinates={n: c.getValue(st) for n, c in own.items()},
            speeds={n: c.getSpeedValue(st) for n, c in own.items()},
            pelvis_height=float(op.state().pelvis_pos[op.up_axis]),
            pelvis_pitch=coords["pelvis_tilt"].getValue(st),
            pelvis_angular_speed=(coords["pelvis_tilt"].getSpeedValue(st), 0.0, 0.0),
            forward_speed=coords["pelvis_tx"].getSpeedValue(st),
            vertical_speed=coords["pelvis_ty"].getSpeedValue(st),
        )
    )
    m, d = mj.model, mj.data
    # set_pose keeps angles in MuJoCo's ranges; OpenSim's limits are springs a knee goes past
    for name, c in own.items():
        joint = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        d.qpos[m.jnt_qposadr[joint]] = c.getValue(st)
        d.qvel[m.jnt_dofadr[joint]] = c.getSpeedValue(st)
    activation = dict(zip(op.muscle_names, op.state().activations, strict=True))
    for i, name in enumerate(mj.muscle_names):  # every actuator is a muscle
        d.act[m.actuator_actadr[i]] = activation[name]
    mujoco.mj_forward(m, d)  # set_pose lifts feet out of the floor: put it back
    lift(mj, "mujoco", op.state().pelvis_pos[op.up_axis] - mj.state().pelvis_pos[mj.up_axis])


def _opensim_mass_matrix(op, state, coordinates: list) -> np.ndarray:
    """OpenSim's mass matrix over ``coordinates`` (their mobilities, in that order)."""
    every = list(op._coords.values())
    saved = [c.getSpeedValue(state) for c in every]
    speeds = []
    for coordinate in coordinates:  # which entry of U each coordinate's speed is
        for c in every:
            c.setSpeedValue(state, 0.0)
        coordinate.setSpeedValue(state, 1.0)
        speeds.append(int(np.argmax(np.abs(state.getU().to_numpy()))))
    for c, speed in zip(every, saved, strict=True):
        c.setSpeedValue(state, speed)
    op.model.realizePosition(state)
    matrix = np.zeros((len(coordinates), len(coordinates)))
    for a, column in enumerate(speeds):
        unit, product = opensim.Vector(state.getNU(), 0.0), opensim.Vector()
        unit.set(column, 1.0)
        op.model.getMatterSubsystem().multiplyByM(state, unit, product)
        matrix[:, a] = [product.get(row) for row in speeds]
    return matrix


def _opensim_contact_wrenches(op, state) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each body's contact force (N) and torque about its origin (N m) from OpenSim's
    Hunt-Crossley forces, by body name."""
    op.model.realizeDynamics(state)
    wrenches: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    forces = op.model.getForceSet()
    for i in range(forces.getSize()):
        force = forces.get(i)
        if force.getConcreteClassName() != "HuntCrossleyForce":
            continue
        labels, values = force.getRecordLabels(), force.getRecordValues(state)
        record = {labels.get(j): values.get(j) for j in range(labels.size())}
        for body in {label.split(".")[1] for label in record} - {"ground"}:
            f = np.array([record[f"{force.getName()}.{body}.force.{a}"] for a in "XYZ"])
            t = np.array([record[f"{force.getName()}.{body}.torque.{a}"] for a in "XYZ"])
            old_f, old_t = wrenches.get(body, (np.zeros(3), np.zeros(3)))
            wrenches[body] = (old_f + f, old_t + t)
    return wrenches


def _mujoco_contact_forces(mj) -> dict[str, tuple[np.ndarray, None]]:
    """Each body's ground contact force (N, world frame) on MuJoCo, by body name."""
    m, d = mj.model, mj.data
    forces: dict[str, tuple[np.ndarray, None]] = {}
    local = np.zeros(6)
    for i in range(d.ncon):
        contact = d.contact[i]
        mujoco.mj_contactForce(m, d, i, local)
        world = local[:3] @ contact.frame.reshape(3, 3)  # geom1 on geom2, along the normal
        for geom, sign in ((contact.geom1, -1.0), (contact.geom2, 1.0)):
            body = int(m.geom_bodyid[geom])
            if body != 0:
                name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, body)
                old = forces.get(name, (np.zeros(3), None))[0]
                forces[name] = (old + sign * world, None)
    return forces


if __name__ == "__main__":
    main()
