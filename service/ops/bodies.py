"""Bodies: the shipped ones, and importing a user's OpenSim model as a body file."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING

from gaitforge.service.ops.errors import InputError
from pydantic import BaseModel

if TYPE_CHECKING:  # a heavy import (OpenSim): loaded when an operation runs
    from gaitforge.workers.bodies.osim_import import ImportResult


class BodyImport(BaseModel):
    """Where an import wrote its body and report, and what the report says."""

    body_file: str
    report_file: str
    name: str
    seconds: float
    counts: dict[str, int]
    approximated: list[str]
    dropped: list[str]
    notes: list[str]


def list_bodies() -> list[str]:
    """The shipped neutral bodies and MyoSuite's MJCF bodies, by name."""
    from gaitforge.workers.bodies import available_bodies
    from gaitforge.workers.bodies.topology import MJCF_BODIES

    return [*available_bodies(), *MJCF_BODIES]


def convert(
    model: Path, *, contacts: Path | None = None, name: str | None = None, fit: bool = True
) -> ImportResult:
    """The OpenSim ``model`` as a body (``import_osim``); with ``fit``, MuJoCo's stand-ins
    then fitted against the original: wrap cylinders for conditional points
    (``fit_conditional_wraps``) and which muscles keep their wraps' side sites
    (``choose_wrap_sides``). The report's time covers all."""
    from gaitforge.workers.bodies.osim_import import ImportResult, import_osim
    from gaitforge.workers.fidelity.conditional_wraps import fit_conditional_wraps
    from gaitforge.workers.fidelity.wrap_sides import choose_wrap_sides

    started = time.perf_counter()
    result = import_osim(model, contacts=contacts, name=name)
    body = result.body
    if fit:
        try:
            body, wrapped = fit_conditional_wraps(model, body)
            body, sides = choose_wrap_sides(model, body)
            result.report.approximated += wrapped + sides
        except (ValueError, RuntimeError) as exc:  # MuJoCo cannot build the body: say so
            reason = " ".join(str(exc).split())[:300]
            result.report.notes.append(f"MuJoCo's stand-ins not fitted: {reason}")
    result.report.seconds = time.perf_counter() - started
    return ImportResult(body=body, report=result.report)


def import_body(
    model: Path,
    out_dir: Path,
    *,
    contacts: Path | None = None,
    name: str | None = None,
    overwrite: bool = False,
    fit: bool = True,
) -> BodyImport:
    """Import the OpenSim ``model`` into ``out_dir/<name>.yaml`` with its report beside it
    (``<name>.import.md``), MuJoCo's stand-ins fitted unless ``fit`` is off (:func:`convert`).

    Raises:
        SpecError: the model (or the contacts file) cannot be imported; one line naming the
            element and what was done.
        InputError: ``out`` or ``name`` is unusable, or the body file exists and
            ``overwrite`` is not set.
    """
    from gaitforge.workers.bodies import body_yaml

    if model.suffix.lower() != ".osim":
        raise InputError("model", f"{model}: an OpenSim model file ending in .osim")
    if name is not None and (not name or not name.replace("_", "").replace("-", "").isalnum()):
        raise InputError("name", f"{name!r}: letters, digits, '_' and '-' only")
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError("out", f"{out_dir} is not a folder")
    result = convert(model, contacts=contacts, name=name, fit=fit)
    body_file = out_dir / f"{result.body.name}.yaml"
    report_file = out_dir / f"{result.body.name}.import.md"
    if body_file.exists() and not overwrite:
        raise InputError("out", f"{body_file} exists (--overwrite replaces it)")
    out_dir.mkdir(parents=True, exist_ok=True)
    header = (
        f"{result.body.name}: imported from {model.name} by gaitforge bodies import.\n"
        f"What was approximated and dropped: {report_file.name}."
    )
    body_file.write_text(body_yaml(result.body, header))
    report_file.write_text(result.report.to_markdown())
    report = result.report
    return BodyImport(
        body_file=str(body_file),
        report_file=str(report_file),
        name=result.body.name,
        seconds=report.seconds,
        counts=report.counts,
        approximated=report.approximated,
        dropped=report.dropped,
        notes=report.notes,
    )
