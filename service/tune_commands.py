"""``gaitforge tune SCENE``: tune a scene's reflex gait controller with CMA-ES."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from gaitforge.learner.job import MAX_NUM_WORKERS
from gaitforge.learner.stage_spec import StageOptimize
from gaitforge.service.cli_options import SetFields, assignments
from gaitforge.service.console import fail, out
from gaitforge.service.ops.errors import validate_request
from gaitforge.service.ops.tune import tune as tune_op
from gaitforge.workers.spec_io import SpecError
from gaitforge.workers.spec_types import SEED_LIMIT


def tune(
    scene: Annotated[str, typer.Argument(help="A scene with action.kind: reflex_gait.")],
    out_dir: Annotated[Path, typer.Option("--out", help="Run folder (resumes its state).")],
    backend: Annotated[str, typer.Option(help="mujoco or opensim.")] = "mujoco",
    workers: Annotated[
        int, typer.Option(min=0, max=MAX_NUM_WORKERS, help="Ray actors (0: in-process).")
    ] = 0,
    population: Annotated[int, typer.Option(help="Candidates a generation.")] = 16,
    generations: Annotated[int, typer.Option(help="Generations in all.")] = 200,
    minutes: Annotated[float | None, typer.Option(help="Stop after this long.")] = None,
    sigma: Annotated[float, typer.Option(help="Initial step, share of each range.")] = 0.1,
    episodes: Annotated[int, typer.Option(help="Episodes a candidate.")] = 3,
    min_speed: Annotated[float, typer.Option(help="m/s the gait measure asks for.")] = 1.0,
    seed: Annotated[
        int, typer.Option(min=0, max=SEED_LIMIT - 1, help="The search's and the starts' seed.")
    ] = 0,
    set_fields: SetFields = None,
) -> None:
    """Tune a reflex gait controller's parameters with CMA-ES; writes OUT/tuned.yaml (the
    scene with them), OUT/progress.csv and TensorBoard scalars (OUT/tb)."""
    try:
        settings = validate_request(
            StageOptimize,
            population=population,
            generations=generations,
            minutes=minutes,
            sigma=sigma,
            episodes=episodes,
            measure={"min_speed": min_speed, "max_speed": max(min_speed, 1.6)},
        )
    except SpecError as exc:
        raise fail(exc) from None
    try:
        tuning, _ = tune_op(
            scene, out_dir, settings, backend, workers, seed=seed, overrides=assignments(set_fields)
        )
    except SpecError as exc:
        raise fail(exc) from None
    last = tuning.saved.last
    if last is not None:
        out.print(
            f"generation {last.generation}: best {last.best:.3f}, mean {last.mean:.3f}, "
            f"sigma {last.sigma:.3f}; {last.env_steps} env steps, {last.wall_s / 60:.1f} min"
        )
    out.print(f"tuned scene: {tuning.write_tuned()}")
