"""Model error beside integration error: the same held rollout under another simulator,
another tendon model, or without pruning, each compared with the scene's reference.

All comparisons use the held variant (pelvis held, no contact, the same seeded excitations
by muscle name) so that they measure the model, not contact chaos. Rows carry the RMS
joint-angle difference (rad, over the dofs both runs share) and the speed of each side.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gaitforge.workers.fidelity.grid import SweepSize
from gaitforge.workers.fidelity.held import Rollout, describe, held_rollout, rms_error
from gaitforge.workers.fidelity.reference import REFERENCE
from gaitforge.workers.fidelity.task import task_runs
from gaitforge.workers.scenes import Scene
from gaitforge.workers.spec_io import validate_model


@dataclass
class ModelDifference:
    """One model comparison on the held variant.

    Attributes:
        what: e.g. ``"opensim vs mujoco"``.
        setting: the profiles used, in words.
        rms_short: RMS difference over the short window, rad.
        rms_long: RMS difference over the long window, rad.
        speed_ratio: held-variant steps/s of the alternative over the scene's model.
        note: anything the reader needs (e.g. why a comparison was skipped).
    """

    what: str
    setting: str
    rms_short: float
    rms_long: float
    speed_ratio: float
    note: str = ""


def _rate(r: Rollout) -> float:
    return r.steps / r.wall_s if r.wall_s else float("nan")


def _compare(
    what: str,
    setting: str,
    base: Rollout,
    other: Rollout,
    short: float,
    long: float,
    dt: float,
    note: str = "",
) -> ModelDifference:
    failed = f"failed: {other.health}" if other.health != "ok" else ""
    return ModelDifference(
        what,
        setting,
        rms_error(other, base, short, dt),
        rms_error(other, base, long, dt),
        _rate(other) / _rate(base),
        note or failed,
    )


def cross_simulator(
    scene: Scene, backend: str, reference: Rollout, short: float, long: float
) -> ModelDifference | None:
    """The other backend's reference against this one's (``None`` if the scene runs on one
    backend only): the difference the choice of simulator makes on the same neutral body."""
    others = [b for b in scene.backends if b != backend]
    if not others:
        return None
    other = others[0]
    run = held_rollout(scene, other, REFERENCE[other], long)
    setting = f"{describe(REFERENCE[other])} vs {describe(REFERENCE[backend])}"
    return _compare(
        f"{other} vs {backend}", setting, reference, run, short, long, 1.0 / scene.control_hz
    )


def tendon(
    scene: Scene, backend: str, short: float, long: float, accuracy: float = 1e-5
) -> ModelDifference | None:
    """OpenSim only: compliant against rigid tendons at ``accuracy`` (both runs alike)."""
    if backend != "opensim":
        return None
    profile = REFERENCE["opensim"].model_copy(update={"accuracy": accuracy})
    rigid = held_rollout(_with_tendon(scene, "rigid"), backend, profile, long)
    compliant = held_rollout(_with_tendon(scene, "compliant"), backend, profile, long)
    return _compare(
        "compliant vs rigid tendon",
        describe(profile),
        rigid,
        compliant,
        short,
        long,
        1.0 / scene.control_hz,
    )


def pruning(scene: Scene, backend: str, reference: Rollout, size: SweepSize) -> ModelDifference:
    """The unpruned body (every joint, muscle and contact geom kept, visuals too) against
    the scene's pruned model. Error: on the held variant at the reference setting. Speed
    ratio: unpruned over pruned env steps/s on the scene itself (with contact) at the
    scene's own profile (the one training uses), batches alternated ``size.repeats`` times,
    median."""
    raw = scene.model_dump(mode="python")
    raw["keep"] = {
        **raw["keep"],
        "joints": "all",
        "muscles": "all",
        "lock_at": {},
        "contacts": "all",
        "visuals": True,
    }
    full = validate_model(raw, Scene, f"scene {scene.name!r} unpruned")
    dt = 1.0 / scene.control_hz
    run = held_rollout(full, backend, REFERENCE[backend], size.long)
    own = scene.profile(backend)
    ratios = [
        task_runs(full, backend, own, size.seeds, size.task_s).steps_per_s
        / task_runs(scene, backend, own, size.seeds, size.task_s).steps_per_s
        for _ in range(max(1, size.repeats))
    ]
    diff = _compare(
        "unpruned vs pruned",
        describe(REFERENCE[backend]),
        reference,
        run,
        size.short,
        size.long,
        dt,
    )
    diff.speed_ratio = float(np.median(ratios))
    diff.note = (diff.note + f" speed at {describe(own)}, with contact").strip()
    return diff


def _with_tendon(scene: Scene, tendon: str) -> Scene:
    """``scene`` with OpenSim's muscles' tendons ``tendon`` (rigid or compliant)."""
    options = scene.opensim.model_copy(update={"tendon": tendon})
    return scene.model_copy(update={"opensim": options})
