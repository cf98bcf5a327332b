"""``gaitforge bodies ...``: list the bodies, import an OpenSim model (the work is
:mod:`gaitforge.service.ops.bodies`'s; this parses and prints)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from gaitforge.service.cli_options import AsJson
from gaitforge.service.console import err, fail, out, print_json
from gaitforge.service.conversion_commands import compare
from gaitforge.service.ops import SpecError
from gaitforge.service.ops import bodies as ops

bodies_app = typer.Typer(
    help="Bodies: the shipped ones, and your OpenSim models.", no_args_is_help=True
)


@bodies_app.command("list")
def list_bodies(json: AsJson = False) -> None:
    """The bodies scenes can name."""
    names = ops.list_bodies()
    if json:
        print_json(names)
        return
    for name in names:
        out.print(name, highlight=False)


@bodies_app.command("import")
def import_model(
    model: Annotated[Path, typer.Argument(help="The OpenSim model (.osim).")],
    out_dir: Annotated[
        Path, typer.Option("--out", help="Folder for the body and its report.")
    ] = Path("."),
    contacts: Annotated[
        Path | None,
        typer.Option(help="YAML list of contact spheres replacing the model's and the rule's."),
    ] = None,
    name: Annotated[
        str | None, typer.Option(help="The body's name (default: the file's stem).")
    ] = None,
    overwrite: Annotated[bool, typer.Option(help="Replace an existing body file.")] = False,
    fit: Annotated[
        bool,
        typer.Option(
            help="Fit MuJoCo's stand-ins (wrap cylinders for conditional points, wrap sides) "
            "against the original."
        ),
    ] = True,
    json: AsJson = False,
) -> None:
    """Import an OpenSim model as a body file, with a report of what was approximated and
    dropped (``<name>.import.md``)."""
    try:
        result = ops.import_body(
            model, out_dir, contacts=contacts, name=name, overwrite=overwrite, fit=fit
        )
    except SpecError as exc:
        raise fail(exc) from None
    if json:
        print_json(result.model_dump(mode="json"))
        return
    counts = ", ".join(f"{v} {k}" for k, v in result.counts.items() if v)
    out.print(f"{result.body_file}: {counts} ({result.seconds:.2f} s)", highlight=False)
    err.print(
        f"{len(result.approximated)} approximated, {len(result.dropped)} dropped: "
        f"{result.report_file}",
        highlight=False,
    )
    for line in result.notes:
        err.print(f"note: {line}", highlight=False, soft_wrap=True)


bodies_app.command("compare")(compare)
