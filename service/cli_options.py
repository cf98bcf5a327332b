"""Options that several commands share, spelled the same way everywhere."""

from __future__ import annotations

from typing import Annotated, Any

import typer
from gaitforge.workers.overrides import parse_assignments
from gaitforge.workers.spec_io import SpecError
from gaitforge.workers.spec_types import SEED_LIMIT

SetFields = Annotated[
    list[str] | None,
    typer.Option(
        "--set",
        "-o",
        metavar="PATH=VALUE",
        help="Set a field by dotted path, the value read as YAML (repeat for more).",
    ),
]
AsJson = Annotated[
    bool, typer.Option("--json", help="Print the result as JSON (for programs) instead of text.")
]
JobSeed = Annotated[
    int | None,
    typer.Option(min=0, max=SEED_LIMIT - 1, help="The job's seed, in place of its own."),
]


def assignments(values: list[str] | None) -> dict[str, Any]:
    """``--set`` values as {dotted path: value}.

    Raises:
        typer.BadParameter: one that is not PATH=VALUE (typer prints it as a usage error).
    """
    try:
        return parse_assignments(values or [], where="--set")
    except SpecError as exc:
        raise typer.BadParameter(str(exc).removeprefix("--set: "), param_hint="--set") from None
