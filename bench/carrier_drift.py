"""How far MuJoCo's coupled dofs leave their polynomials under muscle load: an imported
body (fits on) hung by its pelvis, its muscles excited at random (new excitations every
0.1 s) or fully, 2 s at each integrator and timestep. One table: the worst distance of the
moving points' carriers and of the other coupled dofs (the knee translations) from their
polynomials, while their driver is within its range, for each carrier armature.

Usage: python bench/carrier_drift.py [--model examples/models/gait10dof18musc.osim]
           [--armature 0.1 1 10] [--seconds 2]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import mujoco
import numpy as np
from gaitforge.service.ops.bodies import convert
from gaitforge.workers.sim.mujoco import couplings as mujoco_couplings
from gaitforge.workers.sim.mujoco.build import build_spec
from gaitforge.workers.sim.mujoco.couplings import (
    CARRIER_SUFFIX,
    COUPLING_PREFIX,
    set_coupled_qpos,
)
from gaitforge.workers.sim.mujoco.lock import coupled_qpos, joint_couplings, lock_joints
from rich.console import Console
from rich.table import Table

PROFILES = [("implicitfast", 0.002), ("implicitfast", 0.005), ("rk4", 0.002)]
PELVIS_HEIGHT_M = 1.2


def worst_drift(
    body, integrator: str, timestep: float, excitation: str, seconds: float
) -> tuple[float, float]:
    """(carriers, other coupled dofs): the largest |q - poly(driver)| (m or rad)."""
    spec = build_spec(body)
    spec.option.timestep = timestep
    spec.option.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")
    root = [d.name for d in body.ordered_joints()[0].dofs]
    lock_joints(spec, {n: PELVIS_HEIGHT_M if n.endswith("ty") else 0.0 for n in root})
    model = spec.compile()
    data = mujoco.MjData(model)
    set_coupled_qpos(model, data)
    couplings = joint_couplings(model, COUPLING_PREFIX)
    carried = [
        model.body(model.jnt_bodyid[a]).name.endswith(CARRIER_SUFFIX) for a, _, _ in couplings
    ]
    rng = np.random.default_rng(0)
    worst = np.zeros(2)
    every = round(0.1 / timestep)
    for step in range(round(seconds / timestep)):
        if step % every == 0:
            data.ctrl[:] = rng.random(model.nu) if excitation == "random" else 1.0
        mujoco.mj_step(model, data)
        if not np.all(np.isfinite(data.qpos)):
            return float("inf"), float("inf")
        exact = coupled_qpos(model, data.qpos)  # each coupled dof where its polynomial puts it
        for (driven, driver, _), carrier in zip(couplings, carried, strict=True):
            lo, hi = model.jnt_range[driver]
            if not lo <= data.qpos[model.jnt_qposadr[driver]] <= hi:
                continue
            adr = model.jnt_qposadr[driven]
            off = abs(data.qpos[adr] - exact[adr])
            worst[0 if carrier else 1] = max(worst[0 if carrier else 1], off)
    return float(worst[0]), float(worst[1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", type=Path, default=Path("examples/models/gait10dof18musc.osim"))
    parser.add_argument("--armature", type=float, nargs="+", default=[0.1, 1.0, 10.0])
    parser.add_argument("--seconds", type=float, default=2.0)
    args = parser.parse_args()
    body = convert(args.model).body
    table = Table(title=f"{args.model.name}: worst drift from the polynomial, mm")
    for column in ("armature kg", "integrator", "step ms", "excitation", "carriers", "others"):
        table.add_column(column)
    for armature in args.armature:
        mujoco_couplings.CARRIER_ARMATURE = armature
        for integrator, timestep in PROFILES:
            for excitation in ("random", "full"):
                carriers, others = worst_drift(body, integrator, timestep, excitation, args.seconds)
                table.add_row(
                    f"{armature:g}",
                    integrator,
                    f"{timestep * 1e3:g}",
                    excitation,
                    f"{carriers * 1e3:.2f}",
                    f"{others * 1e3:.2f}",
                )
    Console().print(table)


if __name__ == "__main__":
    main()
