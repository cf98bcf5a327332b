"""MuJoCo put in OpenSim's state, and where their dynamics part: the body let go relaxed on
OpenSim (every excitation 0) for ``--at-s``, MuJoCo given the same joint angles, speeds and
pelvis placement; then, at that instant, each simulator's kept-joint accelerations (rad/s²),
MuJoCo's again with its contacts replaced by OpenSim's contact forces and torques on the
same bodies, both muscle moment sets (N m), and the generalized force OpenSim's accelerations
need beyond what MuJoCo applies (MuJoCo's inverse dynamics; "force left", N m). The mass
matrices are compared first. What is left once the contact forces are the same is the muscles' and
joints' own modelling.

Usage: python bench/same_state.py [--scene walk-2d-clock] [--at-s 0.03]
"""

from __future__ import annotations

import argparse

import mujoco
import numpy as np
import opensim
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.sim import make_simulator
from gaitforge.workers.sim.base import Pose
from passive_moments import opensim_muscle_moments  # bench/ (this folder is on sys.path)
from relaxed_drop import lift
from rich.console import Console
from rich.table import Table

console = Console(width=200)
STEP_S = 0.005
ROOT = ("pelvis_tx", "pelvis_ty", "pelvis_tilt")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default="walk-2d-clock", help="a catalogue name or a file")
    parser.add_argument("--at-s", type=float, default=0.03, help="OpenSim's time let go, s")
    args = parser.parse_args()
    if args.at_s < STEP_S:
        raise SystemExit(f"--at-s: {args.at_s} s is under one {STEP_S} s step")
    scene = load_scene(args.scene).resolved()
    op = make_simulator(scene, "opensim")  # the simulators' own objects: a bench probe
    op.reset(0)
    for _ in range(round(args.at_s / STEP_S)):
        op.step(np.zeros(len(op.muscle_names)), STEP_S)
    st, coords = op.osim_state, op._coords
    mj = make_simulator(scene, "mujoco")
    mj.reset(0)
    m, d = mj.model, mj.data
    joints = [*ROOT, *mj.dof_names]
    dof = {n: int(m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)]) for n in joints}
    _put_in_state(mj, op)

    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    index = [dof[n] for n in joints]
    opensim_mass = _opensim_mass_matrix(op, st, [coords[n] for n in joints])
    mass_gap = np.abs(full[np.ix_(index, index)] - opensim_mass).max()

    rows = {"MuJoCo": d.qacc[index].copy()}
    op.model.realizeAcceleration(st)
    rows["OpenSim"] = np.array([coords[n].getAccelerationValue(st) for n in joints])
    muscle_moments = {
        "MuJoCo": d.qfrc_actuator[index[3:]].copy(),
        "OpenSim": opensim_muscle_moments(op),
    }

    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    d.xfrc_applied[:] = 0.0
    for body, (force, torque) in _opensim_contact_wrenches(op, st).items():
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, body)
        d.xfrc_applied[b, :3] = force  # OpenSim's torque is about the body origin; MuJoCo's
        d.xfrc_applied[b, 3:] = torque + np.cross(d.xpos[b] - d.xipos[b], force)  # its COM
    mujoco.mj_forward(m, d)
    rows["MuJoCo, OpenSim's contacts"] = d.qacc[index].copy()
    # what MuJoCo applies, muscles and those contact wrenches (qfrc_smooth = passive - bias +
    # applied + actuator + the xfrc's); inverse dynamics gives what OpenSim's qacc needs
    applied = d.qfrc_smooth - d.qfrc_passive + d.qfrc_bias - d.qfrc_applied
    d.qacc[index] = rows["OpenSim"]
    mujoco.mj_inverse(m, d)
    rows["force left, N m"] = (d.qfrc_inverse - applied)[index]

    table = Table(title=f"{scene.name}, relaxed, {args.at_s:g} s after the reset on OpenSim; "
                        f"mass matrices differ by at most {mass_gap:.1e}")  # fmt: skip
    table.add_column("accelerations rad/s² (m/s²)", no_wrap=True)
    for name in joints:
        table.add_column(name, justify="right")
    for name, values in rows.items():
        table.add_row(name, *(f"{v:+.1f}" for v in values))
    for name, values in muscle_moments.items():
        table.add_row(f"muscles {name}, N m", "", "", "", *(f"{v:+.1f}" for v in values))
    console.print(table)


def _put_in_state(mj, op) -> None:
    """MuJoCo's joint angles and speeds, pelvis pitch, speeds and height set to OpenSim's."""
    st, coords = op.osim_state, op._coords
    own = {n: c for n, c in coords.items() if not n.startswith("pelvis")}
    mj.set_pose(Pose(coordinates={n: c.getValue(st) for n, c in own.items()},
                     speeds={n: c.getSpeedValue(st) for n, c in own.items()},
                     pelvis_height=float(op.state().pelvis_pos[op.up_axis]),
                     pelvis_pitch=coords["pelvis_tilt"].getValue(st),
                     pelvis_angular_speed=(coords["pelvis_tilt"].getSpeedValue(st), 0.0, 0.0),
                     forward_speed=coords["pelvis_tx"].getSpeedValue(st),
                     vertical_speed=coords["pelvis_ty"].getSpeedValue(st)))  # fmt: skip
    mujoco.mj_forward(mj.model, mj.data)  # set_pose lifts feet out of the floor: put it back
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


if __name__ == "__main__":
    main()
