"""The ``gaitforge`` command line: ``scenes``, ``bodies``, ``train``, ``tune``, ``evaluate``,
``ship`` and ``fidelity``; the REST service (``serve``) and its client (``submit``, ``jobs``,
``status``, ``logs``, ``cancel``, ``resume``, ``download``).

Commands parse their arguments, call :mod:`gaitforge.service.ops` and print: results to
stdout (``--json`` on list, show and evaluate commands for programs), errors, progress and
log lines to stderr.
"""

from __future__ import annotations

import typer
from gaitforge.service.body_commands import bodies_app
from gaitforge.service.client.commands import register as register_client
from gaitforge.service.console import configure_logging
from gaitforge.service.evaluate_commands import evaluate
from gaitforge.service.fidelity_commands import fidelity_app
from gaitforge.service.scene_commands import scenes_app
from gaitforge.service.serve_commands import serve
from gaitforge.service.ship_commands import ship
from gaitforge.service.train_commands import train
from gaitforge.service.tune_commands import tune

app = typer.Typer(
    help="gaitforge: train muscle-driven bodies on heavy simulators.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
)
app.add_typer(scenes_app, name="scenes")
app.add_typer(bodies_app, name="bodies")
app.add_typer(fidelity_app, name="fidelity")
app.command("evaluate")(evaluate)
app.command("train")(train)
app.command("tune")(tune)
app.command("serve")(serve)
app.command("ship")(ship)
register_client(app)


@app.callback()
def main(verbose: bool = typer.Option(False, "--verbose", "-v", help="Log at DEBUG.")) -> None:
    configure_logging(verbose)


if __name__ == "__main__":
    app()
