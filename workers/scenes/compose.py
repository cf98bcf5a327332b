"""Scenes composed from a base and named options, with dotted overrides.

    compose("run-2d+clock+one-leg")                         # a base, then options in order
    compose("run-2d+clock", {"task.target_speed": 2.5})     # and fields set by dotted path

A *base* is a catalogue scene file (``catalogue/<name>.yaml``), either whole or itself
composed (``base:``, ``options:``, ``set:``, its own ``name`` and ``description``). An
*option* (``options/<name>.yaml``) overlays a few fields: ``set`` on every base it is for,
and ``bases`` per base where its values depend on the base (a walk's clock is not a run's);
an option is looked up by the base's lineage (``obstacles-2d`` is made from ``run-2d``, so
``run-2d``'s entry serves it). Overlays merge into mappings; anything else is replaced.

Overrides and option fields name fields by dotted path (``task.reward.forward``); the
result is validated as a :class:`~gaitforge.workers.scenes.spec.Scene` by the caller, so an
unknown path fails there with the field named.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from gaitforge.workers.overrides import set_fields
from gaitforge.workers.scenes.migration import current_name
from gaitforge.workers.scenes.spec import SCENE_NAME_PATTERN
from gaitforge.workers.spec_io import SpecError, read_yaml_mapping
from pydantic import BaseModel, ConfigDict, Field, ValidationError

REF_PATTERN = re.compile(SCENE_NAME_PATTERN)
"""``base`` or ``base+option+option``"""


class SceneOption(BaseModel):
    """A named overlay of a few scene fields (``options/<name>.yaml``)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str = Field(pattern=r"^[a-z0-9][a-z0-9-]*$")
    description: str = Field(min_length=1, description="what the option changes and why")
    requires: list[str] = Field(
        default_factory=list, description="options that must come before this one"
    )
    set: dict[str, Any] = Field(
        default_factory=dict, description="dotted field path -> value, on every base"
    )
    bases: dict[str, dict[str, Any]] = Field(
        default_factory=dict,
        description="base name -> dotted field path -> value (over ``set``); when given, the "
        "option is for these bases (and the bases made from them) only",
    )

    def overlay_for(self, lineage: list[str]) -> dict[str, Any]:
        """The dotted fields this option sets on a base of ``lineage`` (the base's name,
        then the bases it is made from).

        Raises:
            SpecError: the option is not for any base of the lineage.
        """
        if not self.bases:
            return dict(self.set)
        for base in lineage:
            if base in self.bases:
                return {**self.set, **self.bases[base]}
        raise SpecError(
            f"option {self.name!r}: not for base {lineage[0]!r}; it is for {sorted(self.bases)}"
        )


@dataclass(frozen=True)
class Composed:
    """A scene's fields as composed, before validation."""

    raw: dict[str, Any]
    """the scene's fields (``name`` is the reference, ``description`` the parts' own)"""
    lineage: list[str]
    """the base, then the bases it is made from"""


def catalogue_dir() -> Path:
    """The shipped base scenes."""
    return Path(str(resources.files("gaitforge.workers.scenes") / "catalogue"))


def options_dir() -> Path:
    """The shipped scene options."""
    return Path(str(resources.files("gaitforge.workers.scenes") / "options"))


def base_names() -> list[str]:
    """Names of the shipped base scenes."""
    return sorted(p.stem for p in catalogue_dir().glob("*.yaml"))


def option_names() -> list[str]:
    """Names of the shipped scene options."""
    return sorted(p.stem for p in options_dir().glob("*.yaml"))


@functools.cache
def load_option(name: str) -> SceneOption:
    """The shipped option ``name`` (read once: options ship with the code).

    Raises:
        SpecError: unknown, or its file is invalid.
    """
    path = options_dir() / f"{name}.yaml"
    if not path.is_file():
        raise SpecError(f"scene option {name!r}: unknown; options: {option_names()}")
    try:
        return SceneOption.model_validate(read_yaml_mapping(path))
    except ValidationError as err:
        raise SpecError(f"{path}: {err.errors()[0]['msg']}") from None


def is_reference(text: str) -> bool:
    """Whether ``text`` reads as a catalogue reference (``base`` or ``base+option...``)."""
    return bool(REF_PATTERN.match(text))


def compose(ref: str, overrides: dict[str, Any] | None = None) -> Composed:
    """The fields of scene ``ref`` (``base+option+...``) with ``overrides`` (dotted path ->
    value) set last.

    Raises:
        SpecError: an unknown base or option, an option out of order or for another base,
            a malformed path.
    """
    ref = current_name(ref)
    if not is_reference(ref):
        raise SpecError(
            f"scene {ref!r}: expected a catalogue name, base+option+..., or a .yaml path; "
            f"bases: {base_names()}; options: {option_names()}"
        )
    base, *options = ref.split("+")
    composed = _compose_base(base, seen=())
    raw, lineage = composed.raw, composed.lineage
    raw = apply_options(raw, lineage, options, where=f"scene {ref!r}")
    if overrides:
        raw = set_fields(raw, overrides, where=f"scene {ref!r}")
    descriptions = [composed.raw.get("description", "").strip()]
    descriptions += [load_option(o).description.strip() for o in options]
    raw["name"] = ref
    raw["description"] = " ".join(d for d in descriptions if d)
    return Composed(raw, lineage)


def compose_file(raw: dict[str, Any], source: str) -> Composed:
    """A scene file's fields: as written, or (with ``base:``) composed from a catalogue base,
    its ``options`` and its ``set`` fields, with its own ``name`` and ``description``.

    Raises:
        SpecError: naming ``source``.
    """
    if "base" not in raw:
        return Composed(raw, [])
    unknown = set(raw) - {"base", "options", "set", "name", "description"}
    if unknown:
        raise SpecError(
            f"{source}: {sorted(unknown)}: a composed scene file has base, options, set, "
            "name and description only (put other fields under set)"
        )
    options = raw.get("options") or []
    fields = raw.get("set") or {}
    if not isinstance(raw["base"], str) or not isinstance(options, list):
        raise SpecError(f"{source}: base: a catalogue name; options: a list of option names")
    if not isinstance(fields, dict):
        raise SpecError(f"{source}: set: a mapping of dotted field paths to values")
    try:
        composed = compose("+".join([raw["base"], *map(str, options)]), fields)
    except SpecError as exc:
        raise SpecError(f"{source}: {exc}") from None
    for key in ("name", "description"):
        if key in raw:
            composed.raw[key] = raw[key]
    return composed


def apply_options(
    raw: dict[str, Any], lineage: list[str], options: list[str], where: str
) -> dict[str, Any]:
    """``raw`` with each option in ``options`` overlaid in order.

    Raises:
        SpecError: an unknown option, one given twice, one before an option it requires, or
            one not for this base.
    """
    applied: list[str] = []
    for name in options:
        option = load_option(name)
        if name in applied:
            raise SpecError(f"{where}: option {name!r} given twice")
        missing = [r for r in option.requires if r not in applied]
        if missing:
            raise SpecError(f"{where}: option {name!r} needs {missing} before it")
        try:
            raw = set_fields(raw, option.overlay_for(lineage), where=f"option {name!r}")
        except SpecError as exc:
            raise SpecError(f"{where}: {exc}") from None
        applied.append(name)
    return raw


def _compose_base(name: str, seen: tuple[str, ...]) -> Composed:
    """Base ``name``'s fields and lineage (following ``base:`` through other bases)."""
    path = catalogue_dir() / f"{name}.yaml"
    if not path.is_file():
        raise SpecError(f"scene {name!r}: unknown base; bases: {base_names()}")
    raw = read_yaml_mapping(path)
    if "base" not in raw:
        return Composed(raw, [name])
    if raw["base"] in (*seen, name):
        raise SpecError(f"{path}: base: {raw['base']!r} makes a cycle")
    parent = _compose_base(str(raw["base"]), (*seen, name))
    fields = apply_options(parent.raw, parent.lineage, raw.get("options") or [], str(path))
    fields = set_fields(fields, raw.get("set") or {}, str(path))
    fields["name"], fields["description"] = raw.get("name", name), raw.get("description", "")
    return Composed(fields, [name, *parent.lineage])
