"""Fidelity operations: the sweep (speed against accuracy, its recommendation, saved as a
named profile) and the stress test (stability at the extremes, limits by bisection)."""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from gaitforge.service.ops.errors import InputError
from gaitforge.service.ops.scenes import load_for
from pydantic import BaseModel, ConfigDict, Field

if TYPE_CHECKING:
    from gaitforge.workers.fidelity.stress import Limit
    from gaitforge.workers.fidelity.sweep import SweepResult
    from gaitforge.workers.scenes.saved_profiles import SavedProfile

ProgressFn = Callable[[str, str, int, int | None], None]
"""``(label, what was just measured, measurements done, in total or None)``"""


class SweepRequest(BaseModel):
    """A fidelity sweep of one scene on one backend."""

    model_config = ConfigDict(extra="forbid")

    scene: str = Field(description="catalogue name or scene YAML")
    backend: Literal["mujoco", "opensim"] | None = Field(
        default=None, description="default: the scene's first"
    )
    tolerance: float = Field(default=0.01, description="rad: allowed RMS joint-angle error")
    quick: bool = Field(default=False, description="a small grid and short runs (tests)")
    integrators: list[str] | None = Field(
        default=None, description="integrators to keep from the grid (None: all)"
    )
    model_checks: bool = Field(default=True, description="measure the model-error checks")
    task_tolerance: float | None = Field(
        default=None,
        description="m: also require the mean distance covered within this of the reference's",
    )
    save: bool = Field(default=True, description="save the recommendation as a named profile")
    out: Path | None = Field(default=None, description="write CSV, JSON and a Pareto plot here")


@dataclass
class SweepOutcome:
    """A sweep's measurements (``result.rows``, ``result.reference``, ``result.model``), the
    recommendation (``result.recommended``, None if no stable profile is within tolerance),
    the saved profile and its file, and the files written (by kind: csv, json, png)."""

    result: SweepResult
    saved: SavedProfile | None = None
    saved_path: Path | None = None
    files: dict[str, Path] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """JSON-able (inf and NaN written as strings, as in the sweep's JSON file)."""
        return {
            "result": _finite(self.result.to_json()),
            "saved": None if self.saved is None else self.saved.model_dump(mode="json"),
            "saved_path": None if self.saved_path is None else str(self.saved_path),
            "files": {k: str(v) for k, v in self.files.items()},
        }


def _finite(value: Any) -> Any:
    """JSON has no inf or NaN: write them as strings ("inf", "nan")."""
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def sweep(request: SweepRequest, progress: ProgressFn | None = None) -> SweepOutcome:
    """Measure every profile of the grid and recommend the fastest stable one within
    tolerance; save it (``request.save``) and write the tables (``request.out``).

    Raises:
        InputError: a non-positive tolerance, a negative task tolerance, an empty grid.
        SpecError: an unknown or bad scene, a backend it does not run on.
    """
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from gaitforge.workers.fidelity.grid import SweepSize, sweep_grid
    from gaitforge.workers.fidelity.report import write_all
    from gaitforge.workers.fidelity.sweep import run_sweep, save_recommendation

    if not request.tolerance > 0:
        raise InputError("tolerance", f"must be > 0 rad, got {request.tolerance:g}")
    if request.task_tolerance is not None and not request.task_tolerance >= 0:
        raise InputError("task_tolerance", f"must be >= 0 m, got {request.task_tolerance:g}")
    scene, backend = load_for(request.scene, request.backend)
    grid = sweep_grid(scene, backend, request.quick)
    if request.integrators is not None:
        keep = set(request.integrators)
        grid = [p for p in grid if p.integrator in keep]
        if not grid:
            raise InputError(
                "integrators",
                f"no profile left to sweep for {scene.name!r} on {backend} (kept {sorted(keep)})",
            )
    size = SweepSize.for_run(backend, request.quick)
    model_checks = request.model_checks and not request.quick
    label, total, done = f"{scene.name} [{backend}]", len(grid) + 2 + 3 * model_checks, 0

    def advance(text: str) -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(label, text, done, total)

    result = run_sweep(
        scene,
        backend,
        request.tolerance,
        grid,
        size,
        advance,
        model_checks,
        request.task_tolerance,
    )
    outcome = SweepOutcome(result)
    if request.save and (written := save_recommendation(result)) is not None:
        outcome.saved, outcome.saved_path = written
    if request.out is not None:
        outcome.files = write_all(result, request.out)
    return outcome


class StressRequest(BaseModel):
    """A stress test of one scene on one backend."""

    model_config = ConfigDict(extra="forbid")

    scene: str = Field(description="catalogue name or scene YAML")
    backend: Literal["mujoco", "opensim"] | None = Field(
        default=None, description="default: the scene's first"
    )
    seconds: float = Field(default=1.0, description="simulated s per scenario")
    quick: bool = Field(default=False, description="fewer profiles, scenarios and checks")
    bisect: bool = Field(default=True, description="bisect for the largest stable setting")


@dataclass
class StressOutcome:
    """The stability map (``rows``: one per profile, ``{"profile": label, scenario: health
    cause or "ok"}``) and, with bisection, per integrator the largest stable MuJoCo step (s)
    or loosest stable OpenSim accuracy (``limit_kind``)."""

    scene: str
    backend: str
    scenarios: tuple[str, ...]
    rows: list[dict[str, str]]
    limits: list[Limit] = field(default_factory=list)
    limit_kind: Literal["timestep_s", "accuracy"] = "timestep_s"

    def to_dict(self) -> dict[str, Any]:
        from dataclasses import asdict

        return {**asdict(self), "scenarios": list(self.scenarios)}


def stress(request: StressRequest, progress: ProgressFn | None = None) -> StressOutcome:
    """Every profile of the stress grid under hostile inputs (all 0, all 1, bang-bang,
    random, spinning joints, a 0.5 m drop), then (``request.bisect``) the limits.

    Raises:
        InputError: non-positive seconds. SpecError: see :func:`ops.scenes.load_for`.
    """
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from gaitforge.workers.fidelity.grid import stress_grid
    from gaitforge.workers.fidelity.stress import SCENARIOS, bisect_limits, stability_map

    if not request.seconds > 0:
        raise InputError("seconds", f"must be > 0 s, got {request.seconds:g}")
    scene, backend = load_for(request.scene, request.backend)
    profiles = stress_grid(scene, backend, request.quick)
    scenarios = ("ones", "random") if request.quick else SCENARIOS
    total, done = len(profiles) * len(scenarios), 0

    def on_map(text: str) -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(f"stress {scene.name} [{backend}]", text, done, total)

    rows = stability_map(scene, backend, profiles, request.seconds, scenarios, on_map)
    kind: Literal["timestep_s", "accuracy"] = "timestep_s" if backend == "mujoco" else "accuracy"
    outcome = StressOutcome(scene.name, backend, tuple(scenarios), rows, limit_kind=kind)
    if request.bisect:
        checks = 0

        def on_bisect(text: str) -> None:
            nonlocal checks
            checks += 1
            if progress is not None:
                progress("bisection", text, checks, None)

        integrators = (profiles[0].integrator,) if request.quick else None
        outcome.limits = bisect_limits(
            scene, backend, request.seconds, integrators, scenarios, on_bisect
        )
    return outcome
