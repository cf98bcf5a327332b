"""``Scene.resolved``: named, saved and ``auto`` fidelity profiles become concrete ones on
every backend, and a resolved scene reads no saved profile again (a worker node's view)."""

from __future__ import annotations

from pathlib import Path

import pytest
from gaitforge.workers.scenes import Scene, load_scene, saved_profiles
from gaitforge.workers.scenes.profiles import NAMED_PROFILES, FidelityProfile
from gaitforge.workers.scenes.saved_profiles import ENV_DIR, SavedProfile

SAVED = FidelityProfile(integrator="euler", timestep=0.001)


def _save(name: str) -> None:
    saved_profiles.save(
        SavedProfile(
            name=name,
            scene="walk-2d",
            backend="mujoco",
            tolerance=0.02,
            profile=SAVED,
            error=0.01,
            steps_per_s=1.0,
        )
    )


def test_named_profiles_resolve_on_every_backend() -> None:
    scene = load_scene("walk-2d")
    assert not scene.is_resolved and scene.fidelity == "default"
    resolved = scene.resolved()
    assert resolved.is_resolved and resolved.backends == scene.backends
    assert resolved.fidelity == {b: NAMED_PROFILES[b]["default"] for b in scene.backends}
    assert resolved.fidelity_names == {"mujoco": "default", "opensim": "default"}
    assert resolved.profile_name("opensim") == scene.profile_name("opensim") == "default"
    assert resolved.resolved() is resolved
    again = Scene.model_validate(resolved.model_dump(mode="json"))  # as a checkpoint reads it
    assert again == resolved and again.is_resolved


def test_saved_and_auto_resolve_and_need_no_profiles_afterwards(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(ENV_DIR, str(tmp_path / "driver"))
    _save("walk-2d-mujoco-tol0.02")
    raw = load_scene("walk-2d").model_dump(mode="json") | {"backends": ["mujoco"]}
    by_name = Scene.model_validate(raw | {"fidelity": "walk-2d-mujoco-tol0.02"}).resolved()
    auto = Scene.model_validate(raw | {"fidelity": "auto", "fidelity_tolerance": 0.05})
    auto = auto.resolved()
    assert by_name.fidelity == auto.fidelity == {"mujoco": SAVED}
    assert by_name.profile_name("mujoco") == "walk-2d-mujoco-tol0.02"
    assert auto.profile_name("mujoco") == "auto: walk-2d-mujoco-tol0.02"

    monkeypatch.setenv(ENV_DIR, str(tmp_path / "empty"))  # another machine
    with pytest.raises(ValueError, match="no saved profile"):
        Scene.model_validate(raw | {"fidelity": "auto", "fidelity_tolerance": 0.05})
    shipped = Scene.model_validate(auto.model_dump(mode="json"))
    assert shipped.profile("mujoco") == SAVED


def test_an_explicit_profile_is_already_resolved() -> None:
    raw = load_scene("elbow-reach").model_dump(mode="json")
    scene = Scene.model_validate(raw | {"fidelity": {"integrator": "rk4", "timestep": 0.001}})
    assert scene.is_resolved and scene.resolved() is scene
    assert scene.profile_name("mujoco") == "custom"
    with pytest.raises(ValueError, match="not resolved"):
        load_scene("elbow-reach").require_resolved("here")
