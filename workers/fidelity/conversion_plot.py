"""The PNG of a conversion report (one per model): every muscle-coordinate pair's moment-arm
error against what it may have, and the worst pair's curves on both simulators."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from gaitforge.workers.fidelity.conversion_report import (
    PASS_RMS_M,
    PASS_SHARE,
    ConversionReport,
    PairResult,
)

PASS_COLOUR = "tab:green"
FAIL_COLOUR = "tab:red"
OPENSIM_STYLE = {"color": "black", "lw": 1.5, "label": "OpenSim (original)"}
MUJOCO_STYLE = {"color": "tab:orange", "lw": 1.5, "ls": "--", "label": "MuJoCo (converted)"}


def plot_conversion(report: ConversionReport, path: Path) -> None:
    """Write ``path`` (PNG). Left: each pair's moment-arm RMS error (mm, log scale), worst
    first, green where it passes, its allowance (the larger of ``PASS_RMS_M`` and
    ``PASS_SHARE`` of the peak) as a tick. Middle and right: the worst pair's moment arm (mm)
    and muscle-tendon length (mm) against its coordinate (degrees) on both simulators."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (pairs_ax, arm_ax, length_ax) = plt.subplots(
        1, 3, figsize=(14, 4.2), dpi=110, gridspec_kw={"width_ratios": [1.6, 1, 1]}
    )
    _pairs_panel(pairs_ax, report)
    worst = report.worst_pairs(1)
    if worst:
        _curves_panels(arm_ax, length_ax, worst[0])
    else:
        for ax in (arm_ax, length_ax):
            ax.text(0.5, 0.5, "no muscle-coordinate pairs", ha="center", transform=ax.transAxes)
    fig.suptitle(
        f"{report.model} converted to MuJoCo: {report.pass_share:.1%} of "
        f"{len(report.pairs)} muscle-coordinate pairs pass",
        fontsize=11,
    )
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)


def _pairs_panel(ax: object, report: ConversionReport) -> None:
    """Each pair's RMS error (bars) and allowance (black ticks), worst (furthest over its
    allowance) first."""
    order = report.worst_pairs(len(report.pairs))
    errors = np.array([_finite(p.arm_rms_mm) for p in order])
    floor = 1e-3  # mm: a bar of zero would vanish on the log scale
    index = np.arange(len(order))
    colours = [PASS_COLOUR if p.passed else FAIL_COLOUR for p in order]
    ax.bar(index, np.maximum(errors, floor), width=1.0, color=colours, linewidth=0)
    ax.scatter(
        index,
        [p.allowed_mm for p in order],
        marker="_",
        color="black",
        s=12,
        label=f"allowed ({PASS_RMS_M * 1000:g} mm or {PASS_SHARE:.0%} of peak)",
    )
    ax.set_yscale("log")
    ax.set_xlim(-0.5, max(len(order), 1) - 0.5)
    ax.set_xlabel("muscle-coordinate pair, worst first")
    ax.set_ylabel("moment-arm RMS error (mm)")
    ax.set_title("moment arms over each coordinate's range", fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    for rank, pair in enumerate(order[:3]):
        ax.annotate(
            f"{pair.muscle} / {pair.coordinate}",
            (rank, max(errors[rank], floor)),
            xytext=(4, -10 * rank),
            textcoords="offset points",
            fontsize=6,
        )


def _curves_panels(arm_ax: object, length_ax: object, pair: PairResult) -> None:
    degrees = np.degrees(pair.q)
    arm_ax.plot(degrees, pair.arm_opensim * 1000.0, **OPENSIM_STYLE)
    arm_ax.plot(degrees, pair.arm_mujoco * 1000.0, **MUJOCO_STYLE)
    arm_ax.set_xlabel(f"{pair.coordinate} (deg)")
    arm_ax.set_ylabel("moment arm (mm)")
    arm_ax.set_title(f"worst: {pair.muscle}, RMS error {pair.arm_rms_mm:.2f} mm", fontsize=9)
    arm_ax.legend(fontsize=7)
    length_ax.plot(degrees, pair.length_opensim * 1000.0, **OPENSIM_STYLE)
    length_ax.plot(degrees, pair.length_mujoco * 1000.0, **MUJOCO_STYLE)
    length_ax.set_xlabel(f"{pair.coordinate} (deg)")
    length_ax.set_ylabel("muscle-tendon length (mm)")
    length_ax.set_title(f"{pair.muscle}: RMS error {pair.length_rms_mm:.2f} mm", fontsize=9)


def _finite(value: float) -> float:
    """``value``, or a large stand-in where it is not finite (a missing muscle sorts first)."""
    return value if math.isfinite(value) else 1e3
