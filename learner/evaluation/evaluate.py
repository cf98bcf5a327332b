"""Evaluation: run a checkpoint's policy on its scene (or another with the same sizes) for N
episodes with fixed seeds and report distance, speed, falls, effort, return and health.

Two action modes: ``deterministic`` (the policy's mean excitation) and ``stochastic`` (a
sample from its Gaussian, drawn from a generator seeded per episode, so a stochastic
evaluation repeats exactly too). Episode ``i`` resets the env with seed ``seed + i`` in every
mode and at every sweep point: the modes and speeds are compared on the same initial states.

The *speed-against-safety sweep* lowers the scene's target speed (m/s) by fractions (0, 10,
20, 30 % by default) and evaluates at each: the target speed is in the observation, so the
same policy is asked to go slower, and the fall rate at each speed says what speed buys.

Everything runs in-process on one env (no Ray), through the one episode loop
(``workers.episode``): the statistics are an observer (``learner.evaluation.observers``), and so are
the MCAP recording and the video of the first episode. This module picks and loads the
checkpoint; ``learner.evaluation.episodes`` runs the episodes and the sweep. Results are
dataclasses (``learner.evaluation.results``, units there); ``to_dict()`` gives JSON-able dicts
and :func:`write_json` a file.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any, Literal

from gaitforge.learner.checkpoint import checkpoints, load_policy, select_checkpoint
from gaitforge.learner.checkpoint_meta import META_FILE, CheckpointMeta
from gaitforge.learner.curriculum import StageIO
from gaitforge.learner.evaluation.episodes import (
    DEFAULT_REDUCTIONS,
    ProgressFn,
    check_sweep,
    evaluate_episode,
    evaluate_policy,
    make_runner,
    one_pace_note,
    policy_act,
    speed_sweep,
    with_target_speed,
)
from gaitforge.learner.evaluation.gait_quality import GaitRecorder, gait_quality, plot_gait
from gaitforge.learner.evaluation.observers import (
    EvaluationError,
    check_recording_available,
    mcap_observer,
    recording_metadata,
    video_observer,
)
from gaitforge.learner.evaluation.results import (
    MODES,
    EpisodeResult,
    EvaluationReport,
    Mode,
    ModeResult,
    SweepPoint,
    write_json,
)
from gaitforge.learner.policy import ActorCritic, widen_inputs
from gaitforge.learner.transitions import collapsed
from gaitforge.workers.episode import EpisodeObserver
from gaitforge.workers.motions import Motion, MotionError, load_motion
from gaitforge.workers.overrides import set_fields
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.spec_io import SpecError, validate_model

logger = logging.getLogger(__name__)

__all__ = [
    "DEFAULT_REDUCTIONS",
    "MODES",
    "EpisodeResult",
    "EvaluationError",
    "EvaluationReport",
    "Mode",
    "ModeResult",
    "SweepPoint",
    "evaluate_checkpoint",
    "evaluate_episode",
    "evaluate_policy",
    "fitted_to_scene",
    "make_runner",
    "policy_act",
    "resolve_checkpoint",
    "speed_sweep",
    "with_target_speed",
    "write_json",
]


def resolve_checkpoint(
    path: Path, pick: Literal["latest", "best"] = "latest", best_metric: str = "return"
) -> Path:
    """The checkpoint directory ``path`` names: a checkpoint itself, or a run directory (with
    ``checkpoints/`` under it) or a checkpoints directory, from which the latest or the best
    (highest ``metrics[best_metric]``) is taken (``learner.checkpoint.select_checkpoint``).

    Raises:
        EvaluationError: nothing there, or no checkpoint under it.
    """
    if not path.exists():
        raise EvaluationError(f"{path}: no such file or directory")
    if not path.is_dir():
        raise EvaluationError(f"{path}: not a directory (a checkpoint or a run directory)")
    if (path / "manifest.json").exists() or path.name.startswith("ckpt-"):
        return path
    root = path / "checkpoints" if (path / "checkpoints").is_dir() else path
    if not checkpoints(root):
        raise EvaluationError(f"{path}: no checkpoint in it (looked in {root})")
    chosen = select_checkpoint(root, pick, best_metric)
    if chosen is None:
        raise EvaluationError(f"{root}: no checkpoint has metric {best_metric!r} to pick the best")
    return chosen


def _scene_of(
    meta: CheckpointMeta,
    path: Path,
    override: str | Path | Scene | None,
    scene_set: dict[str, Any] | None = None,
) -> Scene:
    """The scene to evaluate on (``override``, else the checkpoint's own) with ``scene_set``
    (dotted path -> value) set, resolved here (``Scene.resolved``), where it is loaded."""
    if isinstance(override, Scene):
        scene = override
    elif override is not None:
        try:
            scene = load_scene(override)
        except SpecError as exc:
            raise EvaluationError(str(exc)) from None
    else:
        scene = meta.scene_spec(path / META_FILE)
    if scene_set:
        where = f"--set: scene {scene.name!r}"
        try:
            raw = set_fields(scene.model_dump(mode="json"), scene_set, where=where)
            scene = validate_model(raw, Scene, where)
        except SpecError as exc:
            raise EvaluationError(str(exc)) from None
    try:
        return scene.resolved()
    except ValueError as exc:
        raise EvaluationError(f"{path}: {exc}") from None


def compared_motion(scene: Scene) -> Motion:
    """The recorded gait a gait is judged beside: the scene's clock motion, else the body's
    walk.

    Raises:
        EvaluationError: the scene has no clock and the body no recorded walk.
    """
    clock = getattr(scene.task, "clock", None)
    name = clock.motion if clock is not None else "walk"
    try:
        return load_motion(scene.body, name)
    except MotionError as exc:
        raise EvaluationError(
            f"gait: scene {scene.name!r} has no gait clock and body {scene.body!r} no recorded "
            f"walk to compare with ({exc})"
        ) from None


def fitted_to_scene(
    policy: ActorCritic, obs_names: list[str] | None, scene: Scene, backend: str
) -> tuple[ActorCritic, list[str] | None]:
    """``policy`` (observing ``obs_names``) widened with zero weights for the inputs
    ``scene`` observes besides (as ``init_from`` does), so a runner can be evaluated on the
    obstacles it has not yet learned to see; and the names it now observes. Unchanged if the
    scene observes nothing new or something the policy did not observe (then the sizes are
    checked as before)."""
    if not obs_names or backend not in scene.backends:
        return policy, obs_names
    names = StageIO(scene, backend).obs_names
    extra = [n for n in names if n not in obs_names]
    if extra and len(names) - len(extra) == len(obs_names):
        logger.warning(
            "scene %r observes %s, which the policy never saw: zero weights for them",
            scene.name,
            extra,
        )
        policy, obs_names = widen_inputs(collapsed(policy), obs_names, names).eval(), names
    return policy, obs_names


def evaluate_checkpoint(
    path: Path,
    *,
    scene: str | Path | Scene | None = None,
    scene_set: dict[str, Any] | None = None,
    backend: str | None = None,
    episodes: int = 10,
    modes: Sequence[Mode] = ("deterministic",),
    seed: int = 0,
    sweep: Iterable[float] | None = None,
    sweep_mode: Mode = "deterministic",
    observers: Sequence[EpisodeObserver] = (),
    record: Path | None = None,
    video: Path | None = None,
    gait: Path | None = None,
    pick: Literal["latest", "best"] = "latest",
    progress: ProgressFn | None = None,
) -> EvaluationReport:
    """Evaluate the checkpoint at ``path`` (see :func:`resolve_checkpoint`).

    Args:
        scene: a catalogue name, scene YAML or Scene to evaluate on instead of the
            checkpoint's own (its observation and action sizes must match the policy's, or
            its observation add inputs: see :func:`fitted_to_scene`).
        scene_set: fields of that scene (or of the checkpoint's own) set by dotted path
            (``{"task.target_speed": 1.0}``).
        backend: simulator; default the checkpoint's ``config.backend``, else "mujoco".
        episodes: per mode and per sweep point.
        modes: action modes at the scene's own target speed.
        seed: episode ``i`` resets with ``seed + i``.
        sweep: target-speed reductions (fractions in [0, 1)) for the speed-against-safety
            sweep, run in ``sweep_mode``; None for no sweep.
        observers: see every step of the first episode (seed ``seed``) of the first mode.
        record: write that episode as an MCAP recording here (``learner.evaluation.recording``).
        video: write that episode as an MP4 video here (``learner.evaluation.video``).
        gait: judge that episode's gait beside the recorded one (the scene's clock motion,
            else the body's walk; ``learner.evaluation.gait_quality``) into the report's
            ``gait``, and plot its joint angles over the gait cycle as a PNG here.
        pick: "latest" or "best" when ``path`` is a run directory.
        progress: ``(label, done, total)`` after each episode.

    Raises:
        EvaluationError: bad path, scene, backend, sizes or options (one line).
        CheckpointError: a damaged checkpoint (naming the file).
    """
    if episodes <= 0:
        raise EvaluationError(f"episodes must be > 0, got {episodes}")
    bad = [m for m in modes if m not in MODES]
    if bad or not modes:
        raise EvaluationError(f"modes {list(modes)}: expected some of {list(MODES)}")
    if record is not None or video is not None:
        check_recording_available(record is not None, video is not None)
    ckpt = resolve_checkpoint(Path(path), pick)
    policy, meta = load_policy(ckpt)
    chosen = _scene_of(meta, ckpt, scene, scene_set)
    backend = backend or meta.backend
    obs_names = meta.obs_names
    if scene is not None:
        policy, obs_names = fitted_to_scene(policy, obs_names, chosen, backend)
    sweep_list = None if sweep is None else list(sweep)
    if sweep_list is not None:
        check_sweep(chosen, sweep_list)
    gait_motion = None if gait is None else compared_motion(chosen)
    gait_recorder = GaitRecorder()
    results: dict[str, ModeResult] = {}
    for k, mode in enumerate(modes):
        with make_runner(policy, chosen, backend, obs_names if scene else None) as run:
            watching: list[EpisodeObserver] = []
            if k == 0:
                watching = list(observers) + ([gait_recorder] if gait is not None else [])
                info = recording_metadata(ckpt, mode, seed)
                try:
                    if record is not None:
                        watching.append(mcap_observer(record, run.env, info))
                    if video is not None:
                        watching.append(video_observer(video, run.env))
                except BaseException:
                    for observer in watching[len(observers) :]:
                        observer.on_end(None)  # close the recording already opened
                    raise
            results[mode] = evaluate_policy(
                policy,
                chosen,
                backend,
                episodes=episodes,
                mode=mode,
                seed=seed,
                runner=run,
                observers=watching,
                progress=progress,
            )
    points: list[SweepPoint] = []
    if sweep_list is not None:
        points = speed_sweep(
            policy,
            chosen,
            backend,
            reductions=sweep_list,
            episodes=episodes,
            mode=sweep_mode,
            seed=seed,
            progress=progress,
        )
    quality = None
    if gait is not None and gait_motion is not None and gait_recorder.trace is not None:
        quality = gait_quality(gait_recorder.trace, gait_motion)
        plot_gait(quality, gait, f"{chosen.name}, seed {seed}")
    trained_on = meta.scene_spec(ckpt / META_FILE)
    pace_note = one_pace_note(trained_on, chosen, sweep=sweep_list is not None)
    return EvaluationReport(
        checkpoint=str(ckpt),
        env_steps=meta.env_steps,
        scene=chosen.name,
        backend=backend,
        seed=seed,
        results=results,
        sweep=points,
        sweep_mode=sweep_mode if sweep_list is not None else None,
        stage=None if meta.stage is None else meta.stage.model_dump(),
        notes=[pace_note] if pace_note else [],
        recording=None if record is None else str(record),
        video=None if video is None else str(video),
        gait=quality,
        gait_plot=None if quality is None else str(gait),
    )
