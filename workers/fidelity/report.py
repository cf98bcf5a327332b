"""Write a sweep: CSV (one row per profile), JSON (everything), and the Pareto plot PNG
(integration error against speed, one marker per profile, unstable ones marked)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

from gaitforge.workers.fidelity.sweep import SweepResult

CSV_FIELDS = (
    "label",
    "integrator",
    "timestep_ms",
    "accuracy",
    "fixed_step",
    "steps_per_s",
    "realtime",
    "err_short",
    "err_long",
    "error",
    "stable",
    "within",
    "health",
)
TASK_FIELDS = (
    "distance_m",
    "distance_ci",
    "distance_vs_ref",
    "distance_vs_ref_ci",
    "fall_rate",
    "fall_rate_lo",
    "fall_rate_hi",
    "peak_grf_bw",
    "peak_grf_ci",
    "grf_vs_ref",
    "grf_vs_ref_ci",
)


def _clean(value: object) -> object:
    """JSON has no inf/NaN: write them as strings."""
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    return value


def write_all(result: SweepResult, out: Path) -> dict[str, Path]:
    """Write ``<scene>-<backend>.csv/.json/.png`` under ``out``; returns the paths by kind."""
    out.mkdir(parents=True, exist_ok=True)
    stem = out / f"{result.scene}-{result.backend}"
    paths = {
        "csv": stem.with_suffix(".csv"),
        "json": stem.with_suffix(".json"),
        "png": stem.with_suffix(".png"),
    }
    with paths["csv"].open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow([*CSV_FIELDS, *TASK_FIELDS])
        for row in result.rows:
            writer.writerow(
                [getattr(row, k) for k in CSV_FIELDS] + [row.task.get(k, "") for k in TASK_FIELDS]
            )
    paths["json"].write_text(json.dumps(_clean(result.to_json()), indent=1))
    pareto_plot(result, paths["png"])
    return paths


def pareto_plot(result: SweepResult, path: Path) -> None:
    """Error (rad, log) against env steps/s (log); unstable profiles drawn as red crosses at
    the top edge; the tolerance as a dashed line; model differences (simulator, tendon,
    pruning) as dotted lines; the recommended profile ringed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5), dpi=110)
    finite = [r.error for r in result.rows if r.stable and 0 < r.error < math.inf]
    top = max([*finite, result.tolerance]) * 3
    bottom = min([*finite, result.tolerance]) / 3
    markers = dict(zip(sorted({r.integrator for r in result.rows}), "osD^v<>ph*", strict=False))
    for integ, marker in markers.items():
        rows = [r for r in result.rows if r.integrator == integ and r.stable]
        ax.scatter(
            [r.steps_per_s for r in rows],
            [max(r.error, bottom) for r in rows],
            marker=marker,
            label=integ,
        )
    for r in result.rows:
        if r.stable:
            short = r.label.split(" ", 1)[-1].replace("acc ", "")
            ax.annotate(
                short,
                (r.steps_per_s, max(r.error, bottom)),
                fontsize=5,
                xytext=(3, 2),
                textcoords="offset points",
                color="dimgrey",
            )
    for m in result.model:
        if 0 < m["rms_long"] < math.inf:
            ax.axhline(m["rms_long"], ls=":", lw=1, color="purple")
            ax.text(
                0.01,
                m["rms_long"] * 1.1,
                f"model: {m['what']}",
                fontsize=6,
                transform=ax.get_yaxis_transform(),
                color="purple",
            )
            top = max(top, m["rms_long"] * 3)
    bad = [r for r in result.rows if not r.stable]
    if bad:
        ax.scatter(
            [max(r.steps_per_s, 1e-3) for r in bad],
            [top] * len(bad),
            marker="x",
            color="red",
            label="unstable",
        )
    ax.axhline(result.tolerance, ls="--", color="grey", lw=1)
    ax.text(
        0.99,
        result.tolerance * 1.1,
        "tolerance",
        fontsize=8,
        transform=ax.get_yaxis_transform(),
        ha="right",
        color="grey",
    )
    if result.recommended is not None:
        r = result.recommended
        ax.scatter(
            [r.steps_per_s],
            [max(r.error, bottom)],
            s=200,
            facecolors="none",
            edgecolors="black",
            label=f"recommended: {r.label}",
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylim(bottom, top * 1.5)
    ax.set_xlabel("env steps/s (one process)")
    windows = f"{result.size.short:g} s and {result.size.long:g} s"
    ax.set_ylabel(f"RMS joint-angle error (rad),\nlarger of {windows}")
    ax.set_title(f"{result.scene} on {result.backend}: error against speed")
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
