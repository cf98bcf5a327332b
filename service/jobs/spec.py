"""Submitted jobs: a REST body (a mapping, or YAML/JSON text) checked as a job file is, and
as data only, then written into a job's folder for its trainer.

Data only: a stage's ``scene`` is a catalogue name or an inline scene (a mapping validated as a
``Scene``); names that reach the file system (the scene, an inline scene's ``body`` and
``task.clock.motion``, ``evaluate.scene``) must be plain names,
never paths; ``workers.ray_address`` is refused (the service decides where jobs run);
anything not in the schema is refused, as are more rollout actors than the cluster has CPUs
(where the caller knows them: ``max_num_workers``). Then the job is written into a scratch
folder and loaded exactly as its trainer will load it (``learner.job.load_job``: every scene
compiled and resolved; the stages checked to fit one policy lineage), so that a job that
cannot run fails here, with a 422, not minutes later.
"""

from __future__ import annotations

import copy
import json
import os
import re
import tempfile
from pathlib import Path
from typing import Any

import yaml
from gaitforge.learner.job import MAX_STAGES, Job, load_job
from gaitforge.service.jobs.layout import JobLayout
from gaitforge.workers.overrides import set_fields
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.scenes.compose import is_reference
from gaitforge.workers.spec_io import (
    MAX_MESSAGE_CHARS,
    MAX_PROBLEMS,
    SpecError,
    shorten,
    validation_problems,
)
from pydantic import ValidationError

MAX_TEXT_BYTES = 1_000_000
"""the largest job text accepted, bytes"""
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,127}")
MAX_REF_CHARS = 300
"""the longest catalogue reference (a base and its options)"""
_INLINE_FILE = re.compile(r"scenes/[a-z0-9-]+\.yaml: (?:(?P<field>[\w.<>]+): )?(?P<problem>.*)")
_PLACEHOLDER = "stand-2d"
"""stands in for an inline scene while the rest of the job is validated"""


class SubmissionError(SpecError):
    """A submitted job that is refused; ``errors`` lists each (field, problem), ``field``
    is the first field. The message is one line: ``<source>: <field>: <problem>; ...``.
    At most ``MAX_PROBLEMS`` are kept (one more entry counts the others), each cut short
    (``workers.spec_io``): the error is never much larger than a few lines."""

    def __init__(self, source: str, errors: list[tuple[str, str]]) -> None:
        kept = [(shorten(f), shorten(p, MAX_MESSAGE_CHARS)) for f, p in errors[:MAX_PROBLEMS]]
        if len(errors) > MAX_PROBLEMS:
            kept.append(("<root>", f"{len(errors) - MAX_PROBLEMS} more problems not listed"))
        super().__init__("; ".join(f"{source}: {field}: {problem}" for field, problem in kept))
        self.errors = kept
        self.field = kept[0][0]


class NoAliasLoader(yaml.SafeLoader):
    """YAML without aliases (``*name``): a few bytes of them can expand without bound."""

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            mark = self.peek_event().start_mark
            raise yaml.YAMLError(f"aliases (*name) are not allowed (line {mark.line + 1})")
        return super().compose_node(parent, index)


def parse_spec(
    spec: dict | str | bytes, source: str = "job", max_bytes: int = MAX_TEXT_BYTES
) -> dict:
    """A job mapping from a mapping, or YAML/JSON text (at most ``max_bytes``).

    Raises:
        SubmissionError: too large, not YAML/JSON, or not a mapping (field ``<root>``).
    """
    if isinstance(spec, dict):
        return spec
    if isinstance(spec, bytes | str):
        size = len(spec if isinstance(spec, bytes) else spec.encode())
        if size > max_bytes:
            raise SubmissionError(source, [("<root>", f"{size} bytes; at most {max_bytes}")])
        try:
            spec = _load_text(spec)
        except (yaml.YAMLError, RecursionError, UnicodeDecodeError, ValueError) as exc:
            # ValueError: an integer of more digits than Python converts
            first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise SubmissionError(
                source, [("<root>", f"not valid YAML or JSON: {first}")]
            ) from None
    if not isinstance(spec, dict):
        got = type(spec).__name__
        raise SubmissionError(source, [("<root>", f"expected a mapping of fields, got {got}")])
    return spec


def _load_text(text: str | bytes) -> object:
    """JSON if it parses as JSON (tabs and all), else YAML without aliases."""
    if text.lstrip()[:1] in ("{", b"{"):
        try:
            return json.loads(text)
        except json.JSONDecodeError:
            pass  # YAML's flow style starts with '{' too
    return yaml.load(text, Loader=NoAliasLoader)  # a SafeLoader


def _name_problem(value: str, what: str) -> str | None:
    """Why ``value`` is not a plain name (None: it is one)."""
    if _NAME.fullmatch(value) and not value.lower().endswith((".yaml", ".yml")):
        return None
    return f"{shorten(repr(value))}: {what}; file paths are not accepted"


def _within(field: str, inner: str) -> str:
    """The dotted path of ``inner`` (a scene's own field, or ``<root>``) below ``field``."""
    return field if inner == "<root>" else f"{field}.{inner}"


def _inline_scene(raw: dict, field: str, errors: list[tuple[str, str]]) -> Scene | None:
    try:
        scene = Scene.model_validate(raw)
    except ValidationError as err:
        errors.extend((_within(field, f), m) for f, m in validation_problems(err, limit=None))
        return None
    bad = _scene_problems(scene, field)
    errors.extend(bad)
    return None if bad else scene


def _scene_problems(scene: Scene, field: str) -> list[tuple[str, str]]:
    """Why ``scene`` (inline, or a catalogue scene with a stage's ``scene_set``) is not data
    only: a body or motion named by a path."""
    names = [("body", scene.body, "a shipped body name")]
    clock = getattr(scene.task, "clock", None)
    if clock is not None:
        names.append(("task.clock.motion", clock.motion, "a motion shipped for the body"))
        if clock.lead_in is not None:
            lead_in = ("task.clock.lead_in.motion", clock.lead_in.motion, "a shipped motion")
            names.append(lead_in)
    bad = [(f"{field}.{f}", p) for f, v, what in names if (p := _name_problem(v, what))]
    return bad


def _check_scene_set(
    stage: dict, index: int, job_backend: object, errors: list[tuple[str, str]]
) -> None:
    """A catalogue or inline scene with the stage's ``scene_set``, checked on the stage's
    backend as the job file's loading checks it (``learner.job.resolve_scenes``): the fields
    it sets may not bring in paths."""
    scene_set, ref = stage.get("scene_set"), stage.get("scene")
    if not isinstance(scene_set, dict) or not scene_set:
        return
    field = f"stages.{index}.scene_set"
    backend = stage.get("backend") or job_backend or "mujoco"
    if isinstance(backend, str):
        scene_set = {**scene_set, "backends": [backend]}
    try:
        if isinstance(ref, dict):
            scene = Scene.model_validate(set_fields(ref, scene_set, where=field))
        elif isinstance(ref, str) and _ref_problem(ref, "") is None:
            scene = load_scene(ref, scene_set)
        else:
            return  # the scene's own error is reported
    except ValidationError as err:
        errors.extend((_within(field, f), m) for f, m in validation_problems(err, limit=None))
        return
    except (SpecError, RecursionError) as exc:
        errors.append((field, shorten(str(exc), 300)))
        return
    errors.extend(_scene_problems(scene, field))


def _ref_problem(value: str, what: str) -> str | None:
    """Why ``value`` is not a catalogue reference (``base`` or ``base+option+...``; None:
    it is one)."""
    if is_reference(value) and len(value) <= MAX_REF_CHARS:
        return None
    return f"{shorten(repr(value))}: {what}; file paths are not accepted"


def _check_data_only(raw: dict, errors: list[tuple[str, str]]) -> dict[int, Scene]:
    """Refuse paths and ``workers.ray_address`` in ``raw`` (edited: inline scenes replaced by
    their names, ``ray_address`` dropped); returns the inline scenes by stage index."""
    workers = raw.get("workers")
    if isinstance(workers, dict) and workers.pop("ray_address", None) is not None:
        errors.append(("workers.ray_address", "not accepted: the service decides where jobs run"))
    if raw.pop("init_from", None) is not None:
        errors.append(
            (
                "init_from",
                "not accepted: a checkpoint path on the server's disk "
                "(file paths are not accepted); start from scratch",
            )
        )
    stages = raw.get("stages")
    if not isinstance(stages, list):
        return {}
    if len(stages) > MAX_STAGES:
        errors.append(("stages", f"{len(stages)} stages; at most {MAX_STAGES}"))
        return {}
    inline: dict[int, Scene] = {}
    for i, stage in enumerate(stages):
        if not isinstance(stage, dict):
            continue  # the job's validation names it
        _check_scene_set(stage, i, raw.get("backend"), errors)
        scene = stage.get("scene")
        if isinstance(scene, dict):
            found = _inline_scene(scene, f"stages.{i}.scene", errors)
            if found is not None:
                inline[i] = found
            stage["scene"] = found.name if found is not None else _PLACEHOLDER
        elif isinstance(scene, str):
            what = "a catalogue scene (base or base+option+...) or an inline scene (a mapping)"
            if problem := _ref_problem(scene, what):
                errors.append((f"stages.{i}.scene", problem))
        judged = stage.get("evaluate")
        judged_scene = judged.get("scene") if isinstance(judged, dict) else None
        if isinstance(judged_scene, str) and (
            problem := _ref_problem(judged_scene, "a catalogue scene (base or base+option+...)")
        ):
            errors.append((f"stages.{i}.evaluate.scene", problem))
    seen: dict[str, tuple[int, Scene]] = {}
    for i, scene in inline.items():
        first = seen.setdefault(scene.name, (i, scene))
        if first[1] != scene:
            errors.append(
                (
                    f"stages.{i}.scene.name",
                    f"{scene.name!r}: stage {first[0]}'s "
                    "inline scene has this name and other content; rename one",
                )
            )
    return inline


def prepare_submission(
    spec: dict | str | bytes,
    source: str = "job",
    max_bytes: int = MAX_TEXT_BYTES,
    max_num_workers: int | None = None,
) -> dict[str, Any]:
    """The submitted job, validated as a job file is and as data only (see the module),
    normalised: every field spelled out, inline scenes kept as mappings (JSON-able).

    ``max_num_workers``: the CPUs of the cluster the job will run on, where it cannot grow
    (a local Ray head: its ``num_cpus``); ``workers.num_workers`` above it is refused, as
    such actors would wait for CPUs forever. None: not checked here (an autoscaling cluster
    adds nodes for them).

    Raises:
        SubmissionError: each refused field (``errors``) and why, one line.
    """
    raw = copy.deepcopy(parse_spec(spec, source, max_bytes))
    errors: list[tuple[str, str]] = []
    inline = _check_data_only(raw, errors)
    try:
        job = Job.model_validate(raw)
    except ValidationError as err:
        errors.extend(validation_problems(err, limit=None))  # SubmissionError keeps the first
    except RecursionError:
        errors.append(("<root>", "nested too deeply"))
    else:
        errors.extend(_check_num_workers(job, max_num_workers))
    if errors:
        raise SubmissionError(source, errors)
    normalised = job.model_dump(mode="json")
    for i, scene in inline.items():
        normalised["stages"][i]["scene"] = scene.model_dump(mode="json")
    _check_loads(normalised, source)
    return normalised


def _check_num_workers(job: Job, max_num_workers: int | None) -> list[tuple[str, str]]:
    """``workers.num_workers`` against the cluster's CPUs (one actor takes one CPU)."""
    wanted = job.workers.num_workers
    if max_num_workers is None or wanted is None or wanted <= max_num_workers:
        return []
    return [
        (
            "workers.num_workers",
            f"{wanted} rollout actors need {wanted} CPUs (one each); the cluster has "
            f"{max_num_workers}: at most {max_num_workers} (or leave it out: the cluster's "
            "CPUs less one)",
        )
    ]


def _check_loads(spec: dict[str, Any], source: str) -> None:
    """Write ``spec`` into a scratch job folder and load it as the trainer will."""
    from gaitforge.learner.curriculum import check_stages  # lazy: heavier imports
    from gaitforge.learner.evaluation.stage_judge import judged_scene

    with tempfile.TemporaryDirectory(prefix="gaitforge-submit-") as tmp:
        layout = JobLayout(Path(tmp), "check")
        job_file = write_job_files(layout, spec)
        try:
            job, scenes, judged = load_job(job_file)
            io, _ = check_stages(job, scenes)
            for i, stage in enumerate(job.stages):
                if stage.evaluate is not None:
                    backend = job.stage_backend(i)
                    judged_scene(stage, i, scenes[i], io[i], backend, judged.get(i))
        except (SpecError, ValueError) as exc:
            text = str(exc).replace(f"{job_file}: ", "").replace(f"{layout.dir}{os.sep}", "")
            field, _, problem = text.partition(": ")
            if not problem or " " in field:
                field, problem = "stages", text
            inner = _INLINE_FILE.fullmatch(problem)  # an inline scene's file: name its field
            if inner and inner["field"] not in (None, "<root>"):
                field, problem = f"{field}.{inner['field']}", inner["problem"]
            raise SubmissionError(source, [(field, problem)]) from None


def write_job_files(layout: JobLayout, spec: dict[str, Any]) -> Path:
    """Write ``spec`` (:func:`prepare_submission`'s result) as ``layout.job_file``, each
    inline scene as ``scenes/<name>.yaml`` referenced by that relative path; returns the job
    file. ``learner.job.load_job(layout.job_file)`` loads it."""
    data = copy.deepcopy(spec)
    layout.dir.mkdir(parents=True, exist_ok=True)
    for stage in data["stages"]:
        if isinstance(stage["scene"], dict):
            name = Scene.model_validate(stage["scene"]).name  # a plain name (its pattern)
            layout.scenes_dir.mkdir(exist_ok=True)
            _write_atomic(layout.scenes_dir / f"{name}.yaml", stage["scene"])
            stage["scene"] = f"scenes/{name}.yaml"
    _write_atomic(layout.job_file, data)
    return layout.job_file


def _write_atomic(path: Path, data: dict[str, Any]) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(yaml.safe_dump(data, sort_keys=False))
    os.replace(tmp, path)
