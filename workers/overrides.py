"""Fields set by dotted path, as a user writes them on the command line, in a job file or in
a REST body: ``task.target_speed=2.5``, ``ppo.lr=1e-4``, ``stages.1.env_steps=500000``.

    fields = parse_assignments(["task.target_speed=2.5"])   # {"task.target_speed": 2.5}
    raw = set_fields(raw, fields, where="--set")

A part that is a whole number indexes a list; a mapping set where a mapping is merges into it
(``task.reward={forward: 4}`` keeps the other weights); anything else is replaced. The result
is validated by the caller's model, so an unknown field fails there, named.
"""

from __future__ import annotations

import copy
from typing import Any

import yaml
from gaitforge.workers.spec_io import SpecError

SET_SYNTAX = "PATH=VALUE, e.g. task.target_speed=2.5 (the value is read as YAML)"


def parse_assignments(assignments: list[str], where: str = "--set") -> dict[str, Any]:
    """``["task.target_speed=2.5", ...]`` -> {"task.target_speed": 2.5, ...} (values read
    as YAML: numbers, booleans, null, lists ``[1, 2]`` and mappings ``{a: 1}``).

    Raises:
        SpecError: an assignment without ``=`` or a path, or a value that is not YAML.
    """
    fields: dict[str, Any] = {}
    for text in assignments:
        path, sep, value = text.partition("=")
        path = path.strip()
        if not sep or not path:
            raise SpecError(f"{where}: {text!r}: expected {SET_SYNTAX}")
        try:
            fields[path] = yaml.safe_load(value) if value.strip() else None
        except yaml.YAMLError:
            raise SpecError(f"{where}: {text!r}: the value is not YAML") from None
    return fields


def set_fields(raw: dict[str, Any], fields: dict[str, Any], where: str) -> dict[str, Any]:
    """A copy of ``raw`` with each dotted path of ``fields`` set to its value.

    Raises:
        SpecError: a path that is empty, has an empty part, indexes past a list's end, or
            passes through a value that is neither a mapping nor a list.
    """
    out = copy.deepcopy(raw)
    for path, value in fields.items():
        parts = str(path).split(".")
        if not all(parts):
            raise SpecError(f"{where}: {path!r}: a dotted field path, e.g. task.target_speed")
        node: Any = out
        for depth, part in enumerate(parts):
            above = ".".join(parts[: depth + 1])
            last = depth == len(parts) - 1
            if isinstance(node, list):
                if not part.isdigit() or int(part) >= len(node):
                    raise SpecError(
                        f"{where}: {path!r}: {above}: an index into a list of {len(node)}"
                    )
                key: Any = int(part)
            elif isinstance(node, dict):
                key = part
                if not last and node.get(key) is None:
                    node[key] = {}
            else:
                value_at = ".".join(parts[:depth])
                raise SpecError(f"{where}: {path!r}: {value_at} is a value, not a group of fields")
            if last:
                current = node[key] if isinstance(node, list) else node.get(key)
                node[key] = _merged(current, copy.deepcopy(value))
            else:
                node = node[key]
    return out


def _merged(old: Any, new: Any) -> Any:
    """``new`` merged into ``old`` where both are mappings; else ``new``."""
    if isinstance(old, dict) and isinstance(new, dict):
        out = dict(old)
        for key, value in new.items():
            out[key] = _merged(out.get(key), value)
        return out
    return new
