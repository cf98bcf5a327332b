"""Saved fidelity profiles: what ``gaitforge fidelity sweep`` recommends, by name.

A sweep (``workers.fidelity``) saves its recommendation through this module as
``<scene>-<backend>-tol<tolerance>`` (one YAML file) in the profile directory:
``$GAITFORGE_PROFILES_DIR`` if set, else ``~/.gaitforge/profiles``. A scene then uses it by
name (``fidelity: walk-2d-mujoco-tol0.01``) or asks for ``fidelity: auto`` with
``fidelity_tolerance: 0.01`` (rad): the saved profile for that scene and backend with the
largest tolerance not above the one asked, fastest on a tie.

These files are user state on the machine that loads the scene. They are read only there,
on the driver, when the scene is resolved (``Scene.resolved``); worker nodes never read them.
"""

from __future__ import annotations

import os
from pathlib import Path

import yaml
from gaitforge.workers.scenes.profiles import FidelityProfile
from pydantic import BaseModel, ConfigDict, Field, ValidationError

ENV_DIR = "GAITFORGE_PROFILES_DIR"


class SavedProfile(BaseModel):
    """A recommended profile and what it was measured to do."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str
    scene: str
    backend: str
    tolerance: float = Field(gt=0, description="rad, RMS joint-angle error it was chosen for")
    profile: FidelityProfile
    error: float = Field(description="rad, measured RMS joint-angle error (larger window)")
    steps_per_s: float = Field(description="env steps/s measured on the scene")


def profiles_dir() -> Path:
    """Where saved profiles live (created on first save)."""
    return Path(os.environ.get(ENV_DIR) or Path.home() / ".gaitforge" / "profiles")


def saved_name(scene: str, backend: str, tolerance: float) -> str:
    return f"{scene}-{backend}-tol{tolerance:g}"


def save(saved: SavedProfile) -> Path:
    """Write ``saved`` to the profile directory; returns the file."""
    directory = profiles_dir()
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{saved.name}.yaml"
    tmp = path.with_suffix(".tmp")
    tmp.write_text(yaml.safe_dump(saved.model_dump(mode="json"), sort_keys=False))
    tmp.replace(path)
    return path


def load_all() -> list[SavedProfile]:
    """Every valid saved profile (files that do not parse are skipped)."""
    found = []
    for path in sorted(profiles_dir().glob("*.yaml")):
        try:
            found.append(SavedProfile.model_validate(yaml.safe_load(path.read_text())))
        except (yaml.YAMLError, ValidationError, TypeError):
            continue
    return found


def by_name(name: str, backend: str) -> SavedProfile | None:
    """The saved profile ``name`` for ``backend``; ``None`` if there is none.

    Raises:
        ValueError: it exists but was measured on another backend.
    """
    for saved in load_all():
        if saved.name == name:
            if saved.backend != backend:
                raise ValueError(
                    f"fidelity: saved profile {name!r} is for backend {saved.backend!r}, "
                    f"not {backend!r}"
                )
            return saved
    return None


def auto(scene: str | None, backend: str, tolerance: float | None) -> SavedProfile:
    """The saved profile ``fidelity: auto`` resolves to; ``ValueError`` (one line) if none."""
    if scene is None or tolerance is None:
        raise ValueError("fidelity: auto needs fidelity_tolerance (rad), e.g. 0.01")
    fits = [
        s
        for s in load_all()
        if s.scene == scene and s.backend == backend and s.tolerance <= tolerance
    ]
    if not fits:
        raise ValueError(
            f"fidelity: auto: no saved profile for scene {scene!r} on {backend} with tolerance "
            f"<= {tolerance:g} in {profiles_dir()}; run: gaitforge fidelity sweep {scene} "
            f"--backend {backend} --tolerance {tolerance:g}"
        )
    return max(fits, key=lambda s: (s.tolerance, s.steps_per_s))
