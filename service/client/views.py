"""Tables for the client commands: the job list and one job's status (the JSON of
``GET /v1/jobs`` and ``GET /v1/jobs/{id}``, read leniently: a missing field is left out)."""

from __future__ import annotations

from gaitforge.service.console import table
from rich.table import Table

SHOWN = frozenset({"iteration", "env_steps", "stage", "stage_env_steps", "steps_per_s", "epochs"})
"""metrics the status table shows elsewhere (or that say little)"""


def jobs_table(page: dict) -> Table:
    """``GET /v1/jobs``'s page: one row per job, and the page's place in the total."""
    items = page.get("items", [])
    offset, total = page.get("offset", 0), page.get("total", len(items))
    shown = f"{offset + 1}-{offset + len(items)} of {total}" if items else f"none of {total}"
    rows = table("id", "name", "state", "stage", "env steps", "updated", title=f"jobs ({shown})")
    for job in items:
        stage = job.get("stage") or {}
        where = f"{stage.get('index', 0) + 1}/{stage.get('count', '?')} " if stage else ""
        rows.add_row(
            job.get("id", ""),
            job.get("name", ""),
            job.get("state", ""),
            where + str(stage.get("name") or stage.get("scene") or ""),
            f"{job.get('env_steps') or 0:,}",
            _time(job.get("updated_at")),
        )
    return rows


def status_table(job: dict) -> Table:
    """One job's status as a two-column table (what it is, how it stands)."""
    rows = table("", "", key_columns=1, show_header=False, box=None, padding=(0, 2))
    rows.add_row("job", f"{job.get('id', '')} {job.get('name', '')}")
    state = f"{job.get('state', '')} (attempt {job.get('attempt', 0)})"
    if job.get("progress_age_s") is not None:
        state += f", progress {job['progress_age_s']:.1f} s old"
    rows.add_row("state", state)
    stage = job.get("stage") or {}
    if stage:
        budget = stage.get("budget_env_steps")
        rows.add_row(
            "stage",
            f"{stage.get('index', 0) + 1}/{stage.get('count', '?')} "
            f"{stage.get('name') or stage.get('scene', '')}: {stage.get('env_steps', 0):,}"
            + (f" / {budget:,} env steps" if budget else " env steps"),
        )
        for rule in stage.get("promote") or []:
            value = rule.get("value")
            got = "no data yet" if value is None else f"now {value:.3g}"
            mark = "passing" if rule.get("passing") else "not yet"
            rows.add_row("  promote", f"{rule.get('rule', '')}: {got} ({mark})")
    steps = f"env steps {job.get('env_steps') or 0:,}   {job.get('steps_per_s') or 0:,.0f} steps/s"
    rows.add_row("progress", f"iteration {job.get('iteration') or 0}   {steps}")
    if job.get("latest_checkpoint"):
        rows.add_row("checkpoint", str(job["latest_checkpoint"]))
    metrics = job.get("metrics") or {}
    scalars = {k: v for k, v in metrics.items() if isinstance(v, int | float) and k not in SHOWN}
    if scalars:
        rows.add_row("metrics", "   ".join(f"{k} {v:.4g}" for k, v in scalars.items()))
    terms = metrics.get("reward_terms") or {}
    if terms:
        rows.add_row("reward terms", "   ".join(f"{k} {v:.4g}" for k, v in terms.items()))
    health = job.get("health") or metrics.get("health") or {}
    rows.add_row("health", ", ".join(f"{k} {v}" for k, v in health.items()) or "ok")
    if job.get("error"):
        rows.add_row("error", str(job["error"]))
    for key in ("created_at", "started_at", "finished_at", "updated_at"):
        if job.get(key):
            rows.add_row(key.removesuffix("_at"), _time(job[key]))
    links = job.get("links") or {}
    for name, href in links.items():
        rows.add_row(f"link {name}", str(href))
    if job.get("actions"):
        names = (a.get("name", "") if isinstance(a, dict) else str(a) for a in job["actions"])
        rows.add_row("actions", ", ".join(names))
    return rows


def _time(value: str | None) -> str:
    """An ISO timestamp to the second: ``2026-11-22 21:40:03`` (UTC as the service sends)."""
    return (value or "").replace("T", " ")[:19]
