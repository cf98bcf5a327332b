"""Catalogue scenes with some clock and imitation fields changed, for tests: each keyword
names a field of ``task.clock`` or ``task.imitate.starts``."""

from __future__ import annotations

from gaitforge.workers.scenes import Scene, load_scene

FIELD_PATHS = {
    "motion": "task.clock.motion",
    "tempo": "task.clock.tempo",
    "random_phase": "task.clock.random_phase",
    "mirror": "task.clock.mirror",
    "ramp_s": "task.clock.ramp_s",
    "lead_in": "task.clock.lead_in",
    "standing": "task.imitate.starts.standing",
    "starts_lead_in": "task.imitate.starts.lead_in",
    "noise": "task.imitate.starts.noise",
}
"""keyword -> dotted scene field"""


def scene_with(name: str, overrides: dict | None = None, **fields: object) -> Scene:
    """Catalogue scene ``name`` with ``fields`` (keywords of :data:`FIELD_PATHS`) and
    ``overrides`` (dotted field -> value) set."""
    dotted = {FIELD_PATHS[key]: value for key, value in fields.items()}
    return load_scene(name, {**dotted, **(overrides or {})})
