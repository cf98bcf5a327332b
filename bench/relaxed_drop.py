"""The body let go from its reset pose on both simulators, no policy: every muscle held at one
excitation (0: relaxed), from the same reset seed, on MuJoCo at each contact time constant
asked for and on OpenSim. A table against time of each variant's right heel and toe depth
(the contact sphere's lowest point against the floor, m; negative: inside it), how far the
toe has moved forward (m), the right foot's normal ground force (body weights), the right
ankle and knee angles (degrees) and the pelvis height (m). What differs is the simulators'
own modelling of the contact and the passive body, with no policy to react to it
(`bench/cross_sim.py` runs a policy on both).

Usage: python bench/relaxed_drop.py [--scene walk-2d+clock] [--excitation 0]
           [--timeconst 0.02 0.12] [--every-s 0.01] [--until-s 0.06] [--seed 0]
           [--lift-m 0]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import mujoco
import numpy as np
from gaitforge.workers.env import GRAVITY
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.sim import make_simulator
from rich.console import Console
from rich.table import Table

console = Console(width=180)
SERIES = ("heel m", "toe m", "toe slide m", "foot BW", "ankle deg", "knee deg", "pelvis m")


def drop(
    scene: Scene,
    backend: str,
    excitation: float,
    every_s: float,
    steps: int,
    seed: int,
    lift_m: float = 0.0,
) -> np.ndarray:
    """[steps, len(SERIES)]: the right foot's heel and toe sphere depths, the toe's forward
    travel, the foot's normal force, the right ankle and knee angles and the pelvis height
    after each ``every_s`` step; the body first raised ``lift_m`` above its reset (a drop
    onto the floor)."""
    sim = make_simulator(scene, backend)
    sim.reset(seed)
    if lift_m:
        lift(sim, backend, lift_m)
    weight = sim.report.mass * GRAVITY
    up, forward, foot = sim.up_axis, sim.forward_axis, sim.foot_names.index("foot_right")
    toe_start = sim.contact_spheres()["foot_right"][-1, forward]
    ankle, knee = sim.dof_names.index("ankle_angle_r"), sim.dof_names.index("knee_angle_r")
    excitations = np.full(len(sim.muscle_names), excitation)
    rows = []
    for _ in range(steps):
        health = sim.step(excitations, every_s)
        state = sim.state()
        spheres = sim.contact_spheres()["foot_right"]  # heel first, then toe: [n, 4]
        depth = spheres[:, up] - spheres[:, 3]
        rows.append(
            [
                depth[0],
                depth[-1],
                spheres[-1, forward] - toe_start,
                state.foot_forces[foot] / weight,
                np.degrees(state.dof_pos[ankle]),
                np.degrees(state.dof_pos[knee]),
                state.pelvis_pos[up],
            ]
        )
        if not health.ok:
            console.log(f"{backend}: {health} at {state.time:.3f} s")
            break
    out = np.full((steps, len(SERIES)), np.nan)
    out[: len(rows)] = rows
    return out


def lift(sim, backend: str, lift_m: float) -> None:
    """Raise the body by ``lift_m`` (m; negative lowers it) through the simulator's own
    vertical root dof (a bench probe; also bench/same_state.py's)."""
    if backend == "mujoco":
        sim.data.qpos[sim._lift_adr] += lift_m
        mujoco.mj_forward(sim.model, sim.data)
    else:
        lift = sim._coords[sim._lift_dof]
        lift.setValue(sim.osim_state, lift.getValue(sim.osim_state) + lift_m, False)


def with_contact_timeconst(scene: Scene, timeconst_s: float) -> Scene:
    """``scene`` with MuJoCo's contact time constant ``timeconst_s`` (s)."""
    options = scene.mujoco.model_copy(update={"contact_timeconst_s": timeconst_s})
    return scene.model_copy(update={"mujoco": options})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default="walk-2d+clock", help="a catalogue name or a file")
    parser.add_argument("--excitation", type=float, default=0.0, help="every muscle's, 0-1")
    parser.add_argument(
        "--timeconst",
        type=float,
        nargs="+",
        default=[0.02, 0.12],
        help="MuJoCo contact time constants (s), one variant each",
    )
    parser.add_argument("--every-s", type=float, default=0.01)
    parser.add_argument("--until-s", type=float, default=0.06)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--lift-m",
        type=float,
        default=0.0,
        help="drop the body from this high above its reset (m, 0-0.2)",
    )
    parser.add_argument("--json-out", type=Path, default=None)
    args = parser.parse_args()
    if not 0.0 <= args.excitation <= 1.0:
        raise SystemExit(f"--excitation: {args.excitation} is not within 0-1")
    if args.every_s <= 0 or args.until_s < args.every_s:
        raise SystemExit("--every-s must be > 0 and --until-s at least --every-s")
    if not 0.0 <= args.lift_m <= 0.2:
        raise SystemExit(f"--lift-m: {args.lift_m} is not within 0-0.2 m")
    if any(t <= 0 for t in args.timeconst):
        raise SystemExit(f"--timeconst: {args.timeconst}: each must be > 0 s")
    scene = load_scene(args.scene).resolved()
    steps = round(args.until_s / args.every_s)
    variants = {
        f"mujoco {t:g} s": (with_contact_timeconst(scene, t), "mujoco") for t in args.timeconst
    }
    variants["opensim"] = (scene, "opensim")
    logs = {
        name: drop(s, backend, args.excitation, args.every_s, steps, args.seed, args.lift_m)
        for name, (s, backend) in variants.items()
    }
    title = (
        f"{scene.name}: every muscle at excitation {args.excitation:g}, let go "
        f"{args.lift_m * 100:g} cm above the reset pose "
        f"(seed {args.seed}); right foot: heel / toe depth m, toe's forward travel, force BW; "
        "right ankle / knee deg; pelvis m"
    )
    table = Table(title=title)
    table.add_column("t s", justify="right")
    for name in logs:
        table.add_column(name, justify="right")
    for k in range(steps):
        cells = [f"{(k + 1) * args.every_s:.3f}"]
        for log in logs.values():
            heel, toe, slide, force, ankle, knee, pelvis = log[k]
            cells.append(
                f"{heel:+.3f}/{toe:+.3f} {slide * 1000:+.0f}mm {force:.2f} "
                f"{ankle:+.0f}/{knee:+.0f} {pelvis:.3f}"
            )
        table.add_row(*cells)
    console.print(table)
    if args.json_out is not None:
        data = {
            "series": list(SERIES),
            "every_s": args.every_s,
            "excitation": args.excitation,
            "scene": scene.name,
            "runs": {
                n: np.where(np.isfinite(v), v.round(5), None).tolist() for n, v in logs.items()
            },
        }
        args.json_out.write_text(json.dumps(data))


if __name__ == "__main__":
    main()
