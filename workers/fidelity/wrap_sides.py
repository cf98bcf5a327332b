"""Which muscles keep MuJoCo's side sites on their wraps, chosen against the OpenSim original.

OpenSim's wrap ``quadrant`` and MuJoCo's ``sidesite`` (the body's ``WrapObject.side``) agree
where the straight path crosses the wrap from the named side. Elsewhere they part: MuJoCo's
side site forces the path round its side, the long way (Rajagopal2016's psoas over the
pelvic brim: 170 mm too long below 30 degrees of hip flexion), where OpenSim leaves it
straight or wraps it the near way. A tendon's length depends only on its own path, so two
MuJoCo models, every wrap with its side site and every wrap without, decide each muscle at
once: the one whose moment arms stay closer to OpenSim's over the coordinates it spans
(the sum over its pairs of RMS error over what the conversion allows) is kept.
"""

from __future__ import annotations

import logging
from pathlib import Path

from gaitforge.workers.bodies.schema import Body, Muscle, WrapRef
from gaitforge.workers.fidelity.conversion_sides import MujocoSide, OpenSimSide
from gaitforge.workers.fidelity.conversion_sweeps import DEFAULT_SWEEP_POINTS, sweep_pairs
from gaitforge.workers.sim.mujoco.build import build_spec

logger = logging.getLogger(__name__)


def _with_sides(body: Body, use_side: bool) -> Body:
    def muscle(m: Muscle) -> Muscle:
        path = [
            e.model_copy(update={"use_side": use_side}) if isinstance(e, WrapRef) else e
            for e in m.path
        ]
        return m.model_copy(update={"path": path})

    return body.model_copy(update={"muscles": [muscle(m) for m in body.muscles]})


def choose_wrap_sides(
    osim_path: Path, body: Body, sweep_points: int = DEFAULT_SWEEP_POINTS
) -> tuple[Body, list[str]]:
    """``body`` with each muscle's wraps keeping their side sites or not, whichever keeps its
    moment arms closer to the OpenSim model at ``osim_path``; and one line per muscle that
    drops them."""
    sided = {w.name for w in body.wrap_objects if w.side is not None}
    muscles = [m.name for m in body.muscles if set(m.wraps) & sided]
    if not muscles:
        return body, []
    opensim_side = OpenSimSide(Path(osim_path))
    scores: dict[bool, dict[str, float]] = {}
    for use_side in (True, False):
        model = build_spec(_with_sides(body, use_side)).compile()
        pairs = sweep_pairs(opensim_side, MujocoSide(model), sweep_points, [], only=muscles)
        totals: dict[str, float] = {}
        for p in pairs:
            totals[p.muscle] = totals.get(p.muscle, 0.0) + p.arm_rms_mm / p.allowed_mm
        scores[use_side] = totals
    drop = {m for m in muscles if scores[False].get(m, 0.0) < scores[True].get(m, 0.0)}
    chosen = [
        _with_sides(body.model_copy(update={"muscles": [m]}), False).muscles[0]
        if m.name in drop
        else m
        for m in body.muscles
    ]
    notes = [
        f"muscle {name}: its wraps without MuJoCo's side sites (moment-arm error "
        f"{scores[True][name]:.1f} -> {scores[False][name]:.1f} allowances)"
        for name in sorted(drop)
    ]
    logger.info("%s: %d of %d muscles drop their side sites", body.name, len(drop), len(muscles))
    return body.model_copy(update={"muscles": chosen}), notes
