"""Reference motions: one periodic gait cycle per (body, motion), shipped as project data.

``data/<body>-<motion>.yaml`` (gait2d-walk, gait2d-run, myoleg-walk, myoleg-run) were written
once from OpenSim's example gait data by ``python bench/data/make_motions.py
<reference dir>``; nothing here reads the reference data. ``data/gait2d-walk-excitations.yaml``
holds the CMC muscle excitations of the same walk on the same phase grid.

Imports: bodies only (rank between bodies and scenes; see tests/test_import_graph.py).
"""

from __future__ import annotations

from functools import lru_cache
from importlib import resources
from pathlib import Path

import numpy as np
import yaml
from gaitforge.workers.motions.model import Motion, MotionProblem, MotionState
from gaitforge.workers.spec_io import SpecError, format_validation_error
from pydantic import BaseModel, ConfigDict, Field, ValidationError

__all__ = [
    "Excitations",
    "Motion",
    "MotionError",
    "MotionState",
    "available_motions",
    "data_dir",
    "excitations_at",
    "load_excitations",
    "load_motion",
    "load_motion_file",
    "motion_file",
]

EXCITATIONS_SUFFIX = "-excitations"


class MotionError(SpecError):
    """A motion (file) is unknown or invalid; the message is one line naming file and field."""


def data_dir() -> Path:
    """Folder of the shipped motion files."""
    return Path(str(resources.files("gaitforge.workers.motions") / "data"))


def motion_file(body: str, name: str) -> Path:
    """The shipped file of motion ``name`` for ``body`` (it may not exist)."""
    return data_dir() / f"{body}-{name}.yaml"


def available_motions(body: str) -> list[str]:
    """Names of the motions shipped for ``body``, sorted."""
    return sorted(
        p.stem.removeprefix(f"{body}-")
        for p in data_dir().glob(f"{body}-*.yaml")
        if not p.stem.endswith(EXCITATIONS_SUFFIX)
    )


def _read(path: Path) -> dict:
    try:
        raw = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise MotionError(f"{path}: cannot read the motion file ({exc.strerror})") from None
    except yaml.YAMLError as exc:
        raise MotionError(f"{path}: not valid YAML: {str(exc).splitlines()[0]}") from None
    if not isinstance(raw, dict):
        raise MotionError(f"{path}: <root>: expected a mapping of fields")
    return raw


def load_motion_file(path: str | Path, body: str | None = None) -> Motion:
    """Read and check a motion file.

    Args:
        path: the YAML file.
        body: if given, the body the motion must be for.

    Raises:
        MotionError: one line ``<file>: <field>: <what is wrong / allowed>``.
    """
    path = Path(path)
    raw = _read(path)
    try:
        motion = Motion.model_validate(raw)
    except ValidationError as err:
        raise MotionError(format_validation_error(str(path), err)) from None
    except MotionProblem as exc:
        raise MotionError(f"{path}: {exc.field}: {exc.message}") from None
    except SpecError as exc:  # the body itself is unknown
        raise MotionError(f"{path}: body: {exc}") from None
    if body is not None and motion.body != body:
        raise MotionError(f"{path}: body: the motion is for {motion.body!r}, not for {body!r}")
    return motion


@lru_cache(maxsize=32)
def load_motion(body: str, name: str) -> Motion:
    """The motion ``name`` of ``body`` (cached); ``name`` may also be a path to a motion file.

    Raises:
        MotionError: unknown motion (naming the available ones) or an invalid file.
    """
    if name.endswith((".yaml", ".yml")) or "/" in name:
        return load_motion_file(name, body)
    path = motion_file(body, name)
    if not path.exists() or name.endswith(EXCITATIONS_SUFFIX):
        shipped = ", ".join(available_motions(body)) or "none"
        raise MotionError(
            f"{path}: motion {name!r}: no such motion for body {body!r} (available: {shipped})"
        )
    return load_motion_file(path, body)


class Excitations(BaseModel):
    """Muscle excitations over one cycle of a motion (N samples at phases k/N, each in [0, 1])."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    body: str
    motion: str
    source: str
    excitations: dict[str, list[float]] = Field(min_length=1)


def load_excitations(body: str, motion: str) -> dict[str, np.ndarray]:
    """Recorded excitations for ``motion`` on ``body``: muscle -> array [N] in [0, 1].

    N and the phase grid are the motion's (``load_motion(body, motion).samples``).

    Raises:
        MotionError: no excitations shipped for this motion, or an invalid file.
    """
    path = data_dir() / f"{body}-{motion}{EXCITATIONS_SUFFIX}.yaml"
    if not path.exists():
        raise MotionError(f"{path}: no recorded excitations for motion {motion!r} of {body!r}")
    try:
        exc = Excitations.model_validate(_read(path))
    except ValidationError as err:
        raise MotionError(format_validation_error(str(path), err)) from None
    n = load_motion(body, motion).samples
    out: dict[str, np.ndarray] = {}
    for muscle, values in exc.excitations.items():
        arr = np.asarray(values, float)
        if arr.shape != (n,) or arr.min() < 0 or arr.max() > 1:
            raise MotionError(
                f"{path}: excitations.{muscle}: expected {n} values in [0, 1] (the motion's "
                "samples)"
            )
        out[muscle] = arr
    return out


def excitations_at(excitations: dict[str, np.ndarray], phase: float) -> dict[str, float]:
    """Excitations at ``phase`` (wrapped into [0, 1)), linear periodic interpolation."""
    out = {}
    for muscle, arr in excitations.items():
        n = len(arr)
        s = (float(phase) % 1.0) * n
        k = int(s) % n
        w = s - int(s)
        out[muscle] = float((1 - w) * arr[k] + w * arr[(k + 1) % n])
    return out
