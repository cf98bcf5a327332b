"""Render a scene's compile report for people (rich)."""

from __future__ import annotations

from gaitforge.workers.sim.base import CompileReport
from rich.console import Group
from rich.table import Table
from rich.text import Text

SIZE_KEYS = (
    "dofs",
    "joints",
    "bodies",
    "muscles",
    "tendons",
    "wrap_objects",
    "geoms",
    "sites",
    "contact_pairs",
)


def render_report(report: CompileReport) -> Group:
    plan = report.plan
    head = Text.from_markup(
        f"[bold]{report.scene}[/bold] on {report.backend}: body {report.body}, "
        f"{report.profile.integrator} at {report.profile.timestep * 1000:g} ms, "
        f"mass {report.mass:.1f} kg"
    )
    size = Table("model size", "full body", "scene", "saved", title="What pruning saved")
    saved = report.saved()
    for key in SIZE_KEYS:
        size.add_row(
            key,
            str(report.size_full.get(key, "-")),
            str(report.size.get(key, "-")),
            str(saved.get(key, "-")),
        )
    kept = Table("kept", "dropped", title="Parts")
    locked = ", ".join(f"{k}={v:.3g}" for k, v in plan.locked_dofs.items()) or "none"
    kept.add_row(f"joints: {', '.join(plan.kept_dofs)}", f"welded: {locked}")
    by_reason: dict[str, list[str]] = {}
    for muscle, why in plan.removed_muscles.items():
        by_reason.setdefault(why, []).append(muscle)
    removed = "; ".join(f"{why}: {', '.join(ms)}" for why, ms in by_reason.items()) or "none"
    kept.add_row(f"muscles: {len(plan.kept_muscles)}", f"muscles: {removed}")
    kept.add_row(
        f"contact geoms: {', '.join(plan.contact_geoms) or 'none'}", f"obstacles: {plan.obstacles}"
    )
    return Group(head, size, kept)
