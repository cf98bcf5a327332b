"""Muscle geometry of the ``gait2d`` body in MuJoCo against the OpenSim reference fixture.

The fixture ``tests/fixtures/gait2d_reference.json`` was computed once from the original
``gait9dof18musc.osim`` by ``tests/fixtures/make_gait2d_reference.py``; it holds, for every
muscle and each hinge dof it spans, a sweep of poses with OpenSim's muscle-tendon length and
moment arms (moment arm = -dL/dq).

Tolerance rule (the body file replaces the reference's moving knee centre, conditional and
moving path points with a fixed knee location, fixed points and wrap cylinders, so the
geometry is close, not identical):

* length: ``|L_mujoco - L_ref| <= max(0.05 * |L_ref|, 0.005 m)`` at every pose;
* moment arm about dof ``q``: ``|r_mujoco - r_ref| <= max(0.05 * peak, 0.005 m)`` at every
  pose, where ``peak`` is the largest ``|r_ref|`` of that muscle about ``q`` over all of the
  muscle's sweeps in the fixture.

MuJoCo's moment arm is ``-dL/dq`` read from the tendon Jacobian ``data.ten_J`` after
``mujoco.mj_fwdPosition`` (dense or sparse storage, whichever the MuJoCo version uses).
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest
from gaitforge.workers.bodies import load_body
from gaitforge.workers.sim.mujoco.build import build_spec

FIXTURE = Path(__file__).resolve().parents[2] / "fixtures" / "gait2d_reference.json"
REL_TOL = 0.05
ABS_TOL = 0.005  # m


@cache
def _fixture() -> dict[str, Any]:
    return json.loads(FIXTURE.read_text())


@cache
def _model() -> mujoco.MjModel:
    return build_spec(load_body("gait2d")).compile()


def _tendon_jacobian(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """``data.ten_J`` as a dense (ntendon, nv) array."""
    if hasattr(model, "ten_J_rownnz"):  # sparse storage (newer MuJoCo)
        dense = np.zeros((model.ntendon, model.nv))
        mujoco.mju_sparse2dense(
            dense, data.ten_J, model.ten_J_rownnz, model.ten_J_rowadr, model.ten_J_colind
        )
        return dense
    return np.asarray(data.ten_J).reshape(model.ntendon, model.nv)


def _peaks(muscle: str) -> dict[str, float]:
    """Largest reference |moment arm| of ``muscle`` about each dof, over all its sweeps."""
    peaks: dict[str, float] = {}
    for sweep in _fixture()["sweeps"]:
        if sweep["muscle"] == muscle:
            for dof, arms in sweep["moment_arm"].items():
                peaks[dof] = max(peaks.get(dof, 0.0), max(abs(a) for a in arms))
    return peaks


def _simulate_sweep(sweep: dict[str, Any]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """MuJoCo lengths and moment arms at the poses of one fixture sweep."""
    model = _model()
    data = mujoco.MjData(model)
    tendon = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, sweep["muscle"])
    assert tendon >= 0, f"no tendon {sweep['muscle']!r} in the compiled model"

    def joint(name: str) -> int:
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        assert jid >= 0, f"no joint {name!r} in the compiled model"
        return jid

    defaults = load_body("gait2d")
    lengths: list[float] = []
    arms: dict[str, list[float]] = {dof: [] for dof in sweep["moment_arm"]}
    for q in sweep["q"]:
        pose = {d: defaults.dof(d).default for d in defaults.dof_names}
        pose |= sweep["fixed"] | {sweep["dof"]: q}
        for name, value in pose.items():
            data.qpos[model.jnt_qposadr[joint(name)]] = value
        mujoco.mj_fwdPosition(model, data)
        lengths.append(float(data.ten_length[tendon]))
        jac = _tendon_jacobian(model, data)
        for dof in arms:
            arms[dof].append(float(-jac[tendon, model.jnt_dofadr[joint(dof)]]))
    return np.array(lengths), {k: np.array(v) for k, v in arms.items()}


def _sweep_ids() -> list[str]:
    return [f"{s['muscle']}-{s['dof']}" for s in _fixture()["sweeps"]]


def test_fixture_covers_all_muscles() -> None:
    body = load_body("gait2d")
    assert {s["muscle"] for s in _fixture()["sweeps"]} == {m.name for m in body.muscles}
    assert len(body.muscles) == 18


def test_spanned_dofs_match_reference() -> None:
    body = load_body("gait2d")
    for muscle in body.muscles:
        ref = {s["dof"] for s in _fixture()["sweeps"] if s["muscle"] == muscle.name}
        hinge = {d for d in body.dofs_spanned(muscle) if d != "lumbar_extension"}
        assert hinge == ref, muscle.name


@pytest.mark.parametrize("index", range(len(_fixture()["sweeps"])), ids=_sweep_ids())
def test_length_and_moment_arms(index: int) -> None:
    sweep = _fixture()["sweeps"][index]
    lengths, arms = _simulate_sweep(sweep)
    ref_len = np.array(sweep["length"])
    len_tol = np.maximum(REL_TOL * np.abs(ref_len), ABS_TOL)
    len_err = np.abs(lengths - ref_len)
    assert np.all(len_err <= len_tol), (
        f"{sweep['muscle']} over {sweep['dof']}: length error {len_err.max() * 1000:.1f} mm "
        f"(q={sweep['q'][int(np.argmax(len_err / len_tol))]:.2f})"
    )
    peaks = _peaks(sweep["muscle"])
    for dof, ref in sweep["moment_arm"].items():
        tol = max(REL_TOL * peaks[dof], ABS_TOL)
        err = np.abs(arms[dof] - np.array(ref))
        assert np.all(err <= tol), (
            f"{sweep['muscle']} over {sweep['dof']}: moment arm about {dof} off by "
            f"{err.max() * 1000:.1f} mm > {tol * 1000:.1f} mm "
            f"(q={sweep['q'][int(np.argmax(err))]:.2f})"
        )


def test_total_mass() -> None:
    body = load_body("gait2d")
    assert body.total_mass == pytest.approx(_fixture()["total_mass"], abs=1e-3)
    model = _model()
    assert float(np.sum(model.body_mass)) == pytest.approx(_fixture()["total_mass"], abs=1e-3)


def test_default_pose_segment_origins() -> None:
    """Segment origins at the default pose within 1.5 cm (the knee centre no longer slides)."""
    model = _model()
    data = mujoco.MjData(model)
    body = load_body("gait2d")
    for name in body.dof_names:
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        data.qpos[model.jnt_qposadr[jid]] = body.dof(name).default
    mujoco.mj_kinematics(model, data)
    for segment, ref in _fixture()["default_segment_origins"].items():
        if segment == "ground":
            continue
        bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, segment)
        assert bid >= 0, segment
        assert np.linalg.norm(data.xpos[bid] - np.array(ref)) < 0.015, segment
