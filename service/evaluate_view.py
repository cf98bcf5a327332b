"""Render an ``EvaluationReport`` for people (rich): means ± the half-width of their 95 %
interval, rates with their 95 % Wilson interval. Where a pelvis turned about the vertical (a
3-D body; a planar one cannot) the tables add the turn, deg (per episode signed,
counter-clockwise seen from above; per mode its mean size). Imitation scenes add two
columns, the tracking error (rad) and the share of episodes that kept the gait; obstacle
scenes three, the share of episodes that touched an obstacle and the fall rate among those
that did and those that did not; other scenes' tables are as they were. Where the summary or
sweep table (one row per mode or sweep point) is wider than the terminal, it turns on its
side (one row per quantity), so that nothing is cut or folded at 80 columns."""

from __future__ import annotations

from typing import Any

from gaitforge.service.console import table
from rich.console import Console, Group
from rich.measure import Measurement
from rich.table import Table


def _ci(stat: Any, fmt: str = ".2f") -> str:
    if stat.n == 0:
        return "-"
    if stat.n == 1:
        return f"{stat.mean:{fmt}}"
    return f"{stat.mean:{fmt}} ± {(stat.high - stat.low) / 2:{fmt}}"


def _rate(rate: Any) -> str:
    if rate.n == 0:
        return "-"
    return f"{100 * rate.value:.0f} % ({100 * rate.low:.0f}-{100 * rate.high:.0f})"


def _health(counts: dict[str, int]) -> str:
    failures = {k: v for k, v in counts.items() if k != "ok"}
    return ", ".join(f"{k}: {v}" for k, v in failures.items()) or "none"


def _oriented(title: str, headers: list[str], rows: list[list[str]], console: Console) -> Table:
    """``rows`` under ``headers`` if that fits ``console``'s width, else transposed (a row
    per header, a column per row)."""
    wide = table(*headers, title=title)
    for row in rows:
        wide.add_row(*row)
    unlimited = console.options.update_width(10_000)
    if Measurement.get(console, unlimited, wide).maximum <= console.width:
        return wide
    tall = table(headers[0], *(row[0] for row in rows), title=title)
    for i, header in enumerate(headers[1:], start=1):
        tall.add_row(header, *(row[i] for row in rows))
    return tall


def _all_results(report: Any) -> list[Any]:
    """The mode results of a report, its sweep's included."""
    return [*report.results.values(), *(p.result for p in report.sweep)]


def _turning(report: Any) -> bool:
    """Whether any episode of the report (modes and sweep) turned about the vertical."""
    return any(r.turned for r in _all_results(report))


def _imitating(report: Any) -> bool:
    """Whether any result of the report (modes and sweep) tracked a motion."""
    return any(r.tracking_error_rad is not None for r in _all_results(report))


def _tracking(r: Any) -> list[str]:
    """The imitation columns of a mode result: tracking error (rad) and kept-gait share."""
    if r.tracking_error_rad is None or r.kept_gait_rate is None:
        return ["-", "-"]
    return [_ci(r.tracking_error_rad, ".3f"), _rate(r.kept_gait_rate)]


def _with_obstacles(report: Any) -> bool:
    """Whether any result of the report (modes and sweep) ran among obstacles."""
    return any(r.touched_rate is not None for r in _all_results(report))


def _obstacles(r: Any) -> list[str]:
    """The obstacle columns of a mode result: the share of episodes that touched an
    obstacle, and the fall rate among those that did and those that did not."""
    if r.touched_rate is None:
        return ["-", "-", "-"]
    return [_rate(r.touched_rate), _rate(r.fall_rate_touched), _rate(r.fall_rate_untouched)]


OBSTACLE_HEADERS = ["touched an obstacle", "falls if touched", "falls if not"]


def render_episodes(report: Any) -> list[Table]:
    """One table per mode: every episode of an ``EvaluationReport``."""
    tables = []
    turning, imitating, obstacles = _turning(report), _imitating(report), _with_obstacles(report)
    extra = ["turned\ndeg"] if turning else []
    extra += ["tracking\nrad", "kept\ngait"] if imitating else []
    extra += ["first touch\ns"] if obstacles else []
    for mode, r in report.results.items():
        episodes = table(
            "seed",
            "steps",
            "time\ns",
            "distance\nm",
            "speed\nm/s",
            "fell",
            "health",
            "effort",
            "return",
            *extra,
            title=f"Episodes ({mode})",
        )
        for e in r.episodes:
            cells = [
                str(e.seed),
                str(e.steps),
                f"{e.time_s:.2f}",
                f"{e.distance_m:.2f}",
                f"{e.mean_speed_m_s:.2f}",
                "yes" if e.fell else "no",
                e.health,
                f"{e.effort:.3f}",
                f"{e.return_:.1f}",
            ]
            if turning:
                cells.append(f"{e.turned_deg:+.0f}")
            if imitating:
                error = "-" if e.tracking_error_rad is None else f"{e.tracking_error_rad:.3f}"
                cells += [error, "-" if e.kept_gait is None else "yes" if e.kept_gait else "no"]
            if obstacles:
                touch = e.first_obstacle_touch_s
                cells.append("-" if touch is None else f"{touch:.2f}")
            episodes.add_row(*cells)
        tables.append(episodes)
    return tables


def render(report: Any, console: Console) -> Group:
    """The head line, the summary per mode and (if run) the speed-against-safety sweep,
    laid out for ``console``'s width."""
    first = next(iter(report.results.values()))
    head = (
        f"[bold]{report.checkpoint}[/bold]: {report.env_steps} env steps; scene "
        f"{report.scene} on {report.backend}; seeds {report.seed}.."
        f"{report.seed + len(first.episodes) - 1}; means ± 95 % intervals"
    )
    turning, imitating, obstacles = _turning(report), _imitating(report), _with_obstacles(report)
    extra = ["turned deg"] if turning else []
    extra += ["tracking rad", "kept gait"] if imitating else []
    extra += OBSTACLE_HEADERS if obstacles else []
    headers = [
        "mode",
        "target m/s",
        "distance m",
        "speed m/s",
        "fall rate",
        "survival",
        "time s",
        "effort",
        "return",
        "health failures",
        *extra,
    ]
    rows = []
    for mode, r in report.results.items():
        target = "-" if r.target_speed_m_s is None else f"{r.target_speed_m_s:.2f}"
        rows.append(
            [
                mode,
                target,
                _ci(r.distance_m),
                _ci(r.mean_speed_m_s),
                _rate(r.fall_rate),
                _rate(r.survival_rate),
                _ci(r.time_s),
                _ci(r.effort, ".3f"),
                _ci(r.return_, ".1f"),
                _health(r.health),
                *([_ci(r.turned_deg, ".0f")] if turning else []),
                *(_tracking(r) if imitating else []),
                *(_obstacles(r) if obstacles else []),
            ]
        )
    parts: list[Any] = [head, _oriented("Evaluation", headers, rows, console)]
    if report.sweep:
        headers = [
            "slower by",
            "target m/s",
            "fall rate",
            "distance m",
            "speed m/s",
            "return",
            "health failures",
            *extra,
        ]
        rows = []
        for point in report.sweep:
            r = point.result
            rows.append(
                [
                    f"{100 * point.reduction:.0f} %",
                    f"{point.target_speed_m_s:.2f}",
                    _rate(r.fall_rate),
                    _ci(r.distance_m),
                    _ci(r.mean_speed_m_s),
                    _ci(r.return_, ".1f"),
                    _health(r.health),
                    *([_ci(r.turned_deg, ".0f")] if turning else []),
                    *(_tracking(r) if imitating else []),
                    *(_obstacles(r) if obstacles else []),
                ]
            )
        title = f"Speed against safety ({report.sweep_mode})"
        parts.append(_oriented(title, headers, rows, console))
    if getattr(report, "gait", None) is not None:
        parts.append(_gait_line(report.gait, report.gait_plot))
    parts += [f"[yellow]note[/yellow]: {note}" for note in getattr(report, "notes", [])]
    return Group(*parts)


def _gait_line(gait: Any, plot: str | None) -> str:
    """One line of the first episode's gait figures (``learner.evaluation.gait_quality``)."""
    legs = ""
    if gait.leg_gap_min_m is not None:
        legs = (
            f"; legs at least {gait.leg_gap_min_m:.3f} m apart (through each other in "
            f"{100 * gait.interpenetrating_fraction:.0f} % of steps)"
        )
    if not gait.strides:
        return f"gait (first episode): no whole stride{legs} (plot: {plot})"
    clearance = ", ".join(f"{foot} {height:.3f}" for foot, height in gait.clearance_m.items())
    return (
        f"gait (first episode): {gait.strides} strides of {gait.stride_length_m:.2f} m in "
        f"{gait.stride_time_s:.2f} s ({gait.cadence_steps_per_min:.0f} steps/min), step "
        f"time asymmetry {gait.step_time_asymmetry:.2f}, foot clearance m: {clearance}; "
        f"joint angles {gait.summary()['joint_rms_rad_mean']:.3f} rad RMS from the recording "
        f"on average{legs} (plot: {plot})"
    )
