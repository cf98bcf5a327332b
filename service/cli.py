"""The ``gaitforge`` command line: ``scenes``, ``train``, ``evaluate`` (and more sub-apps)."""

from __future__ import annotations

import logging

import typer
from gaitforge.service.evaluate_commands import evaluate
from gaitforge.service.fidelity_commands import fidelity_app
from gaitforge.service.scene_commands import scenes_app
from gaitforge.service.train_commands import train
from rich.console import Console

app = typer.Typer(
    help="gaitforge: train muscle-driven bodies on heavy simulators.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
)
app.add_typer(scenes_app, name="scenes")
app.add_typer(fidelity_app, name="fidelity")
app.command("evaluate")(evaluate)
app.command("train")(train)
console = Console()


@app.callback()
def main(verbose: bool = typer.Option(False, "--verbose", "-v", help="Log at DEBUG.")) -> None:
    logging.basicConfig(
        level=logging.DEBUG if verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )


if __name__ == "__main__":
    app()
