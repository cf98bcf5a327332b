"""Render a scene's compile report (``ops.scenes.SceneReport``) for people (rich)."""

from __future__ import annotations

from gaitforge.service.console import table
from gaitforge.service.ops.scenes import SIZE_KEYS, SceneReport
from rich.console import Group
from rich.text import Text


def render_report(report: SceneReport) -> Group:
    p = report.profile
    head = Text.from_markup(
        f"[bold]{report.scene}[/bold] on {report.backend}: body {report.body}, "
        f"{p.integrator} at {p.timestep * 1000:g} ms, mass {report.mass_kg:.1f} kg"
    )
    size = table("model size", "full body", "scene", "saved", title="What pruning saved")
    for key in SIZE_KEYS:
        size.add_row(
            key,
            str(report.size_full.get(key, "-")),
            str(report.size.get(key, "-")),
            str(report.saved.get(key, "-")),
        )
    kept = table("kept", "dropped", title="Parts", key_columns=0)
    locked = ", ".join(f"{k}={v:.3g}" for k, v in report.locked_dofs.items()) or "none"
    kept.add_row(f"joints: {', '.join(report.kept_dofs)}", f"welded: {locked}")
    by_reason: dict[str, list[str]] = {}
    for muscle, why in report.removed_muscles.items():
        by_reason.setdefault(why, []).append(muscle)
    removed = "; ".join(f"{why}: {', '.join(ms)}" for why, ms in by_reason.items()) or "none"
    kept.add_row(f"muscles: {len(report.kept_muscles)}", f"muscles: {removed}")
    kept.add_row(
        f"contact geoms: {', '.join(report.contact_geoms) or 'none'}",
        f"obstacles: {report.obstacles}",
    )
    return Group(head, size, kept)
