"""The relaxed muscles' joint moments on both simulators, posed statically: the body lifted
clear of the floor, every joint at the scene's standing pose but one swept over angles, no
speed, MuJoCo's activations at 0 and OpenSim's at its 0.01 floor, and each kept joint's moment
from all the muscles (N m; MuJoCo ``qfrc_actuator``, OpenSim the tendon forces times their
moment arms), MuJoCo once per ``muscle_passive`` option. How hard the stretched, relaxed
muscles pull is what the options fit; this says where each agrees with OpenSim's.

Usage: python bench/passive_moments.py [--scene walk-2d+clock] [--joint ankle_angle_r]
           [--degrees -20 -10 0 10 15] [--options gait thelen thelen-fibre]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import mujoco
import numpy as np
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.sim import make_simulator
from relaxed_drop import lift  # bench/relaxed_drop.py (this script's folder is on sys.path)
from rich.console import Console
from rich.table import Table

console = Console(width=180)
LIFT_M = 1.0
"""How far the body is raised above its reset height: no contact."""


def mujoco_moments(scene: Scene, joint: str, angles: np.ndarray) -> np.ndarray:
    """[angles, kept joints]: the muscles' joint moments (N m) on MuJoCo, relaxed."""
    sim = make_simulator(scene, "mujoco")
    sim.reset(0)
    m, d = sim.model, sim.data

    def address(name: str, kind: str) -> int:
        j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        return int(m.jnt_qposadr[j] if kind == "q" else m.jnt_dofadr[j])

    lift(sim, "mujoco", LIFT_M)
    dofs = [address(n, "v") for n in sim.dof_names]
    out = []
    for angle in angles:
        d.qpos[address(joint, "q")] = angle
        d.qvel[:] = 0.0
        d.act[:] = 0.0
        mujoco.mj_forward(m, d)
        out.append(d.qfrc_actuator[dofs].copy())
    return np.array(out)


def opensim_moments(scene: Scene, joint: str, angles: np.ndarray) -> np.ndarray:
    """[angles, kept joints]: the muscles' joint moments (N m) on OpenSim, at its minimum
    activation (0.01), fibres in equilibrium."""
    sim = make_simulator(scene, "opensim")
    sim.reset(0)
    lift(sim, "opensim", LIFT_M)
    state, coords = sim.osim_state, sim._coords  # the simulator's own (a bench probe)
    out = []
    for angle in angles:
        coords[joint].setValue(state, float(angle), False)
        for coord in coords.values():
            coord.setSpeedValue(state, 0.0)
        sim.model.equilibrateMuscles(state)
        out.append(opensim_muscle_moments(sim))
    return np.array(out)


def opensim_muscle_moments(sim) -> np.ndarray:
    """[kept joints]: the muscles' moments (N m) on OpenSim at its present state, tendon
    forces times ``sim.moment_arms()`` (also bench/same_state.py's)."""
    sim.model.realizeDynamics(sim.osim_state)
    forces = np.array([mu.getActuation(sim.osim_state) for mu in sim._muscles])
    return forces @ sim.moment_arms()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default="walk-2d+clock", help="a catalogue name or a file")
    parser.add_argument("--joint", default="ankle_angle_r", help="the kept joint swept")
    parser.add_argument("--degrees", type=float, nargs="+", default=[-20, -10, 0, 10, 15])
    parser.add_argument("--options", nargs="+", default=["gait", "thelen", "thelen-fibre"],
                        help="MuJoCo's muscle_passive options, one column each")  # fmt: skip
    parser.add_argument("--json-out", type=Path, default=None)
    args = parser.parse_args()
    scene = load_scene(args.scene).resolved()
    if args.joint not in scene.keep.joints:
        raise SystemExit(
            f"--joint: {args.joint!r} is not kept by {scene.name}: {scene.keep.joints}"
        )
    allowed = Scene.model_fields["muscle_passive"].annotation.__args__
    if bad := [o for o in args.options if o not in allowed]:
        raise SystemExit(f"--options: {bad} unknown; allowed: {list(allowed)}")
    angles = np.radians(args.degrees)
    moments = {
        f"mujoco {o}": mujoco_moments(
            scene.model_copy(update={"muscle_passive": o}), args.joint, angles
        )
        for o in args.options
    }
    moments["opensim"] = opensim_moments(scene, args.joint, angles)
    joints = list(scene.keep.joints)
    title = (f"{scene.name}: relaxed muscles' moments (N m) at the swept {args.joint}, "
             "the body in the air: hip / knee / ankle of its side")  # fmt: skip
    table = Table(title=title)
    table.add_column(f"{args.joint} deg", justify="right")
    for name in moments:
        table.add_column(name, justify="right")
    side = args.joint.rsplit("_", 1)[-1]
    shown = [j for j, n in enumerate(joints) if n.endswith(f"_{side}")]
    for k, degrees in enumerate(args.degrees):
        cells = [f"{degrees:+.0f}"]
        for values in moments.values():
            cells.append(" / ".join(f"{values[k, j]:+.0f}" for j in shown))
        table.add_row(*cells)
    console.print(table)
    if args.json_out is not None:
        data = {"scene": scene.name, "joint": args.joint, "degrees": args.degrees,
                "joints": joints,
                "moments_n_m": {n: v.round(3).tolist() for n, v in moments.items()}}  # fmt: skip
        args.json_out.write_text(json.dumps(data))


if __name__ == "__main__":
    main()
