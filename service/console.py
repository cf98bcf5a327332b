"""What the CLI writes where: results (tables, JSON) to stdout; errors, progress displays and
log lines to stderr, through one rich console so that log lines appear above a live display
instead of breaking it."""

from __future__ import annotations

import json
import logging
import math
from typing import Any

import typer
from gaitforge.service.ops import InputError
from pydantic_core import to_jsonable_python
from rich.console import Console, ConsoleDimensions
from rich.logging import RichHandler
from rich.markup import escape
from rich.table import Column, Table

UNWRAPPED_WIDTH = 10_000
"""columns of stdout off a terminal: wider than any table, so that no row wraps"""


class ResultConsole(Console):
    """stdout's console. On a terminal, or where ``COLUMNS`` sets a width, rich's own width
    (cells wrap between words); off a terminal with no width set (a pipe, a file), one no
    table reaches, so that a row is one line and no word or number is ever split."""

    @property
    def size(self) -> ConsoleDimensions:
        dimensions = super().size
        if self._width is not None or "COLUMNS" in self._environ or self.file.isatty():
            return dimensions
        return ConsoleDimensions(UNWRAPPED_WIDTH, dimensions.height)

    @size.setter
    def size(self, new_size: tuple[int, int]) -> None:
        self._width, self._height = new_size


out = ResultConsole()
"""results: tables and final lines (stdout)"""
err = Console(stderr=True)
"""errors, progress bars, live displays and log lines (stderr)"""

LOG_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"


def configure_logging(verbose: bool) -> None:
    """Log at DEBUG with ``verbose``, else WARNING: through rich on a terminal (above any
    live display), else plain timestamped lines on stderr. No-op if logging is set up."""
    handler: logging.Handler
    if err.is_terminal:
        handler = RichHandler(console=err, show_path=False, markup=False)
        handler.setFormatter(logging.Formatter("%(message)s"))
    else:
        handler = logging.StreamHandler()
        handler.setFormatter(logging.Formatter(LOG_FORMAT))
    logging.basicConfig(level=logging.DEBUG if verbose else logging.WARNING, handlers=[handler])


def option_name(field: str) -> str:
    """An operation's argument as the CLI option that sets it: ``task_tolerance`` ->
    ``--task-tolerance``."""
    return "--" + field.replace("_", "-")


def message(exc: Exception) -> str:
    """One line for a user error: an :class:`InputError` names its option."""
    if isinstance(exc, InputError):
        return f"{option_name(exc.field)}: {exc.problem}"
    return str(exc)


def fail(problem: Exception | str) -> typer.Exit:
    """Print ``error: <one line>`` to stderr; the exit (status 2) to raise."""
    text = problem if isinstance(problem, str) else message(problem)
    err.print(f"[red]error:[/red] {escape(text)}", soft_wrap=True, highlight=False)
    return typer.Exit(2)


def jsonable(data: Any) -> Any:
    """``data`` (pydantic models, dataclasses, paths, lists and dicts of them) as JSON-able
    Python, NaN and infinities as None."""
    data = to_jsonable_python(data)
    if isinstance(data, float):
        return data if math.isfinite(data) else None
    if isinstance(data, dict):
        return {k: jsonable(v) for k, v in data.items()}
    if isinstance(data, list):
        return [jsonable(v) for v in data]
    return data


def print_json(data: Any) -> None:
    """``data`` (see :func:`jsonable`) as indented JSON on stdout: no colour, no wrapping."""
    typer.echo(json.dumps(jsonable(data), indent=2, allow_nan=False))


def table(*headers: str, title: str | None = None, key_columns: int = 1, **kwargs: Any) -> Table:
    """A table that never truncates a cell: the first ``key_columns`` (names) never wrap,
    the others wrap at spaces and fold words too long for their column."""
    columns = [Column(h, no_wrap=i < key_columns, overflow="fold") for i, h in enumerate(headers)]
    return Table(*columns, title=title, **kwargs)
