"""What older gaitforge wrote, read as today's: the one migration of scene files and of the
scenes and jobs that checkpoints store (``learner.checkpoint_meta`` applies it to a
``meta.json`` of an older ``schema_version``; a scene validates through
:func:`read_older_layout` whatever its source, so an older scene file loads too).

Scene fields (:func:`read_older_layout`, before a ``Scene`` validates them):

* the backend options at the top level move into ``mujoco:`` and ``opensim:``
  (``workers.scenes.backend_options``, and the retired ``contact_model`` and
  ``joint_limits``);
* a ``fault`` of null goes (fault injection is a test hook, ``workers.sim.faults``); any
  other value is refused;
* a retired setting (:data:`RETIRED_SETTINGS`) at the value that meant "off" goes; at any
  other value it is refused, naming the field and why it was retired; a removed value
  (:data:`REMOVED_VALUES`) is refused, naming the commit that still has it;
* ``task.imitate`` with a ``motion`` (the clock and the tracking in one block) splits into
  ``task.clock`` (motion, tempo, lead-in, speed from the clock, random phase, mirroring,
  ramp) and ``task.imitate`` (weights, scales, the early end, the starts). An imitation that
  tracked nothing (every weight 0, no early end, every episode standing) was a clock alone
  and leaves no ``task.imitate``.

Scene names (:data:`FORMER_NAMES`): catalogue names from before scenes were composed load
as the composition they were; a removed option or scene (:data:`REMOVED_NAMES`) is refused,
naming the commit that still has it.

Jobs as checkpoints store them (:func:`read_older_job`): a stage's ``fidelity``,
``control_hz`` and ``action`` move into its ``scene_set``, ``init_from_action_std`` becomes
the first stage's ``action_std``, the retired job fields (:data:`RETIRED_JOB_FIELDS`) go and
former scene names are renamed.
"""

from __future__ import annotations

from typing import Any

from gaitforge.workers.scenes.backend_options import MUJOCO_FIELDS, OPENSIM_FIELDS
from gaitforge.workers.scenes.imitate import ImitationWeights
from gaitforge.workers.spec_io import SpecError

OPENSIM_LAWS = (
    "MuJoCo on OpenSim's laws was removed; commit a1888fe has its code, "
    "docs/results/opensim.md its results"
)
PLANAR = (
    "the planar option (keep.planar) was removed; commit a1888fe has its code, "
    "docs/results/throughput.md its results"
)
REMOVED_NAMES = {
    "opensim-laws": OPENSIM_LAWS,
    "walk-2d-clock-opensim-laws-half-ms": OPENSIM_LAWS,
    "planar": PLANAR,
    "walk-3d-planar": PLANAR,
}
"""scene options and former scene names no longer shipped, refused with why (as parts of a
name)"""
REMOVED_VALUES = {"muscle_curves": "opensim", "muscle_passive": "opensim"}
"""``mujoco:`` values no longer known, refused with :data:`OPENSIM_LAWS`"""

FORMER_NAMES = {
    "imitate-run-2d-start": "imitate-run-2d+standing-starts",
    "imitate-walk-2d-start": "imitate-walk-2d+standing-starts",
    "obstacles-2d-clock": "obstacles-2d+clock",
    "obstacles-2d-clock-one-leg": "run-2d+clock+one-leg+forward+obstacles",
    "obstacles-2d-clock-overspeed": "run-2d+clock+one-leg+speed-range+obstacles",
    "run-2d-clock": "run-2d+clock",
    "run-2d-clock-forward": "run-2d+clock+forward",
    "run-2d-clock-one-leg": "run-2d+clock+one-leg+forward",
    "walk-2d-clock": "walk-2d+clock",
    "walk-2d-clock-paced": "walk-2d+clock",
}
"""catalogue names from before scenes were composed, as older checkpoints, their jobs and
job files name them: each loads as the composition it was (the same fields, a test checks)"""

STAGE_SCENE_FIELDS = ("fidelity", "control_hz", "action")
"""scene fields older jobs set on a stage itself, now keys of the stage's ``scene_set``"""
RETIRED_JOB_FIELDS = ("warm_start", "clone_actor")
"""job fields no recipe set (a stage's ``warm_start``, a blend's ``clone_actor``): they go
where they hold their former default (null, false)"""

RETIRED_SETTINGS: tuple[tuple[str, object, str], ...] = (
    ("task.imitate.clock_rate_span", None, "it made falls worse"),
    ("task.imitate.weights.pelvis_position", 0.0, "it made falls worse"),
    ("task.imitate.weights.pelvis_lag", 0.0, "it made falls worse"),
    ("task.imitate.scales.pelvis_position", 0.5, "its term made falls worse"),
    ("task.imitate.scales.pelvis_lag", 0.1, "its term made falls worse"),
    (
        "task.imitate.tempo_speed_exponent",
        1.0,
        "the cadence always scales with a drawn target speed",
    ),
    ("obstacles.observe_behind", 0, "no scene observed the spheres passed"),
    ("task.reward.obstacle_touch", 0.0, "no scene weighed it; evaluation still reports touches"),
    ("observe_muscles", True, "leaving the muscles' states out did not help MyoLeg learn"),
    ("observe_heading", False, "observing the pelvis's heading did not help MyoLeg learn"),
    ("task.imitate.weights.pelvis_heading", 0.0, "tracking the heading did not help MyoLeg"),
    ("task.imitate.scales.pelvis_heading", 10.0, "its term did not help MyoLeg"),
    ("mujoco.contact_model", "mujoco", OPENSIM_LAWS),  # its other value: hunt-crossley
    ("mujoco.joint_limits", "mujoco", OPENSIM_LAWS),  # its other value: opensim
    ("keep.planar", False, PLANAR),
    (
        "task.assist",
        None,
        "the pelvis's assist was removed; commit a1888fe has its code, "
        "docs/results/walk-3d.md its results",
    ),
)
"""Scene settings no longer read: (dotted field, the value that meant "off", why retired).
Older files and checkpoints that hold one at that value load without it."""


def read_older_layout(raw: dict[str, Any]) -> dict[str, Any]:
    """``raw`` (a scene's fields) in today's layout; ``raw`` itself is left as it is.

    Raises:
        ValueError: one line naming a ``fault`` or a retired field that holds a value.
    """
    raw = dict(raw)
    former = (*MUJOCO_FIELDS, "contact_model", "joint_limits")
    for block, names in (("mujoco", former), ("opensim", OPENSIM_FIELDS)):
        flat = {name: raw.pop(name) for name in names if name in raw}
        if flat:
            nested = raw.get(block)
            raw[block] = {**nested, **flat} if isinstance(nested, dict) else flat
    raw = _without_retired_settings(raw)
    task = raw.get("task")
    if isinstance(task, dict) and _holds_the_clock(task.get("imitate")):
        raw["task"] = _clock_apart_from_imitation(task)
    mujoco = raw.get("mujoco")
    for name, value in REMOVED_VALUES.items():
        if isinstance(mujoco, dict) and mujoco.get(name) == value:
            raise ValueError(f"mujoco.{name} {value!r}: {OPENSIM_LAWS}")
    if "fault" in raw and raw.pop("fault") is not None:
        raise ValueError(
            "fault: fault injection is a test hook (workers.sim.faults), not a scene field"
        )
    return raw


def _without_retired_settings(raw: dict[str, Any]) -> dict[str, Any]:
    """``raw`` without the ``RETIRED_SETTINGS`` it holds at their former defaults; the
    mappings on the way copied, ``raw``'s own left as they are.

    Raises:
        ValueError: one line naming a retired field that holds another value.
    """
    for dotted, default, reason in RETIRED_SETTINGS:
        *path, name = dotted.split(".")
        parent = raw
        for key in path:
            child = parent.get(key)
            if not isinstance(child, dict):
                break
            parent[key] = child = dict(child)
            parent = child
        else:
            if name not in parent:
                continue
            value = parent.pop(name)
            if value != default or isinstance(value, bool) != isinstance(default, bool):
                raise ValueError(f"{dotted}: retired ({reason}); remove it")
    return raw


CLOCK_FIELDS = ("motion", "tempo", "lead_in", "speed_target_from_clock")
"""Fields of the former ``task.imitate`` that are the clock's under the same names."""
CLOCK_START_FIELDS = ("random_phase", "mirror", "ramp_s")
"""Fields of the former ``task.imitate.init`` that are the clock's under the same names."""


def _holds_the_clock(imitate: object) -> bool:
    """Whether ``imitate`` is the former block that held the clock too (it names a motion)."""
    return isinstance(imitate, dict) and "motion" in imitate


def _clock_apart_from_imitation(task: dict[str, Any]) -> dict[str, Any]:
    """``task`` (not changed) with its former ``imitate`` block split into ``clock`` and
    ``imitate`` (see the module's docstring)."""
    former = dict(task["imitate"])
    init = former.pop("init", None) or {}
    clock = {name: former.pop(name) for name in CLOCK_FIELDS if name in former}
    clock |= {name: init[name] for name in CLOCK_START_FIELDS if name in init}
    all_standing = init.get("start", "motion") == "standing"
    weights = former.get("weights")
    tracks = (
        not all_standing
        or not isinstance(weights, dict)  # absent: the default weights, which track
        or any(
            weights.get(name, field.default) != 0
            for name, field in ImitationWeights.model_fields.items()
        )
        or former.get("max_pose_error_rad", 0.5) is not None
    )
    task = {**task, "clock": clock}
    task.pop("imitate")
    if tracks:
        starts = {"standing": 1.0} if all_standing else {}
        if "standing_fraction" in init and not all_standing:
            starts["standing"] = init["standing_fraction"]
        if "lead_in_fraction" in init:
            starts["lead_in"] = init["lead_in_fraction"]
        if "noise" in init:
            starts["noise"] = init["noise"]
        task["imitate"] = {**former, "starts": starts}
    return task


def current_name(ref: str) -> str:
    """Scene reference ``ref`` as today's catalogue names it.

    Raises:
        SpecError: it names a removed option or scene (:data:`REMOVED_NAMES`).
    """
    for part in ref.split("+"):
        if part in REMOVED_NAMES:
            named = f" ({part!r})" if part != ref else ""
            raise SpecError(f"scene {ref!r}{named}: {REMOVED_NAMES[part]}")
    return FORMER_NAMES.get(ref, ref)


def read_older_job(raw: dict[str, Any]) -> dict[str, Any]:
    """A job's fields as an older checkpoint stored them (``Job.model_dump``), in today's
    layout (see the module's docstring); ``raw`` itself is left as it is."""
    raw = dict(raw)
    first_std = raw.pop("init_from_action_std", None)
    stages = []
    for index, stage in enumerate(raw.get("stages") or []):
        if not isinstance(stage, dict):
            stages.append(stage)
            continue
        stage = {k: v for k, v in stage.items() if k not in RETIRED_JOB_FIELDS or v}
        moved = {k: stage.pop(k) for k in STAGE_SCENE_FIELDS if k in stage}
        moved = {k: v for k, v in moved.items() if v is not None}
        if moved:
            stage["scene_set"] = {**moved, **(stage.get("scene_set") or {})}
        if isinstance(stage.get("blend"), dict):
            blend = stage["blend"]
            stage["blend"] = {k: v for k, v in blend.items() if k not in RETIRED_JOB_FIELDS or v}
        if isinstance(stage.get("scene"), str):
            stage["scene"] = current_name(stage["scene"])
        if index == 0 and first_std is not None:
            stage["action_std"] = first_std
        stages.append(stage)
    if "stages" in raw:
        raw["stages"] = stages
    return raw
