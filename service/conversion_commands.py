"""``gaitforge bodies compare MODEL.osim``: how faithful a converted body is, the original
OpenSim model against the MuJoCo model built from the body (the work is
:mod:`gaitforge.workers.fidelity.conversion`'s; this parses and prints)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from gaitforge.service.cli_options import AsJson
from gaitforge.service.console import err, fail, out, print_json
from gaitforge.workers.spec_io import SpecError


def compare(
    model: Annotated[Path, typer.Argument(help="The original OpenSim model (.osim).")],
    body: Annotated[
        Path | None,
        typer.Option(help="The converted body (YAML); default: the model imported afresh."),
    ] = None,
    png: Annotated[
        Path | None,
        typer.Option(help="Also draw each pair's moment-arm error and the worst pair's curves."),
    ] = None,
    json_out: AsJson = False,
) -> None:
    """Compare a converted body with its OpenSim original: masses, centres of mass over
    random poses, every muscle's length and moment arms over each coordinate it spans,
    muscle forces at rest, and a relaxed drop (about 2-30 s)."""
    from gaitforge.workers.bodies.schema import Body
    from gaitforge.workers.fidelity.conversion import measure_conversion
    from gaitforge.workers.fidelity.conversion_sides import load_opensim_model
    from gaitforge.workers.spec_io import load_yaml_model

    try:
        load_opensim_model(model)  # a bad model fails here, before an import is tried
        if body is None:
            from gaitforge.service.ops.bodies import convert

            converted = convert(model).body
        else:
            converted = load_yaml_model(body, Body)
        with err.status(f"measuring {model.name} on OpenSim and MuJoCo"):
            report = measure_conversion(model, converted)
    except SpecError as exc:
        raise fail(exc) from None
    if png is not None:
        from gaitforge.workers.fidelity.conversion_plot import plot_conversion

        try:
            plot_conversion(report, png)
        except OSError as exc:
            raise fail(f"{png}: cannot write the figure: {exc.strerror or exc}") from None
    if json_out:
        print_json(report.to_json())
        return
    out.print(report.markdown(), markup=False, highlight=False, soft_wrap=True)
    if png is not None:
        out.print(f"figure written to {png}", highlight=False)
