"""Following a job: its status as one line, the live line over server-sent events (reconnecting
while the service restarts) and the log tail by offsets."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

from gaitforge.service.client.http import GaitforgeClient, ServerUnreachable

logger = logging.getLogger(__name__)

TERMINAL = frozenset({"succeeded", "failed", "cancelled"})
"""states a job does not leave (but for a resume, which queues it again)"""


def status_line(status: dict) -> str:
    """One line for a job's status: state, stage, env steps, speed and the latest episode
    metrics, e.g. ``j-0123456789ab running  stage 2/4 walk-2d 12,288/20,000  40,960 env steps
    1,234 steps/s  return 12.3  speed 0.52 m/s  falls 30 %``."""
    state, phase = status.get("state", "?"), status.get("phase")
    if state == "running" and status.get("cancel_requested"):
        phase = "cancel requested"
    busy = state == "running" and phase not in (None, "training")
    shown = f"{state} ({phase})" if busy else state
    parts = [f"{status.get('id', '?')} {shown}"]
    stage = status.get("stage") or {}
    if stage:
        count = stage.get("count")
        where = f"{stage.get('index', 0) + 1}/{count}" if count else str(stage.get("index", 0))
        budget = stage.get("budget_env_steps")
        steps = f" {stage.get('env_steps', 0):,}/{budget:,}" if budget else ""
        parts.append(f"stage {where} {stage.get('name') or stage.get('scene', '')}{steps}")
    if status.get("iteration"):
        parts.append(f"iteration {status['iteration']}")
    if status.get("env_steps"):
        parts.append(f"{status['env_steps']:,} env steps")
    if status.get("steps_per_s"):
        parts.append(f"{status['steps_per_s']:,.0f} steps/s")
    metrics = status.get("metrics") or {}
    for key, label, fmt in (
        ("return", "return", "{:.1f}"),
        ("speed", "speed", "{:.2f} m/s"),
        ("fall_rate", "falls", "{:.0%}"),
        ("survival", "survival", "{:.0%}"),
    ):
        if isinstance(metrics.get(key), int | float):
            parts.append(f"{label} {fmt.format(metrics[key])}")
    if status.get("error"):
        parts.append(f"error: {status['error']}")
    return "  ".join(parts)


def follow_events(
    client: GaitforgeClient,
    job_id: str,
    on_status: Callable[[dict], None],
    reconnect_s: float = 120.0,
    poll_s: float = 1.0,
) -> dict:
    """Call ``on_status`` with each ``progress`` event of ``job_id`` until the job ends;
    returns its final status. While the service is unreachable (a restart), retry every
    ``poll_s`` for up to ``reconnect_s`` seconds.

    Raises:
        ServerUnreachable: the service stayed away for ``reconnect_s``.
        ApiError: the service refused (an unknown job, a bad token).
    """
    away_since: float | None = None
    while True:
        try:
            for event, data in client.events(job_id):
                away_since = None
                if event == "progress" and isinstance(data, dict):
                    on_status(data)
                elif event == "end":
                    break
            status = client.status(job_id)
            if status.get("state") in TERMINAL:
                return status
            on_status(status)  # the stream ended early (a restart): go on
        except ServerUnreachable:
            now = time.monotonic()
            if away_since is None:
                away_since = now
                logger.warning("%s: unreachable; retrying for %.0f s", client.server, reconnect_s)
            elif now - away_since > reconnect_s:
                raise
        time.sleep(poll_s)


def tail_logs(
    client: GaitforgeClient,
    job_id: str,
    write: Callable[[str], None],
    offset: int = 0,
    follow: bool = False,
    poll_s: float = 1.0,
) -> int:
    """Write the job's log from byte ``offset`` on; with ``follow``, keep asking from the
    next offset until the service says ``eof`` (the job has ended and its log is read to
    the end). Returns the next offset."""
    while True:
        chunk = client.logs(job_id, offset)
        text = chunk.get("text") or ""
        if text:
            write(text)
        offset = int(chunk.get("next_offset", offset))
        if not follow or chunk.get("eof"):
            return offset
        if not text:
            time.sleep(poll_s)
