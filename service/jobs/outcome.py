"""How a job whose Ray job ended comes out: its state and error, from Ray's status, the
trainer's last progress and whether a cancel was asked for.

    fields = outcome(record, info, progress, died=lambda: died_reason(sid, info, tail))
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

from gaitforge.service.jobs.local_ray import first_line
from gaitforge.service.jobs.progress import JobProgress
from gaitforge.service.store import JobRecord

LOG_TAIL_LINES = 5
"""log lines quoted in the error of a trainer that died"""
FORCED_STOP = "stopped by Ray after the cancel's grace (no clean stop)"


def outcome(
    record: JobRecord, info: Any | None, progress: JobProgress | None, died: Callable[[], str]
) -> dict[str, Any]:
    """``state`` and ``error`` of ``record``'s job now that its Ray job has ended.

    Args:
        info: Ray's ``JobDetails`` of the attempt (None: Ray has no such job).
        progress: the attempt's last ``progress.json`` (None: none written).
        died: how the trainer ended, in Ray's words and its log's (called when needed).
    """
    phase = progress.phase if progress is not None else None
    status = str(info.status.value) if info is not None else None
    if phase == "finished" and status == "SUCCEEDED":
        return {"state": "succeeded", "error": None}
    if phase == "failed":
        return {"state": "failed", "error": progress.error or f"trainer failed: {died()}"}
    if record.cancel_requested:
        if phase == "stopped":
            return {"state": "cancelled", "error": None}
        error = FORCED_STOP if status == "STOPPED" else f"trainer died: {died()}"
        return {"state": "cancelled", "error": error}
    return {"state": "failed", "error": f"trainer died: {died()}"}


def died_reason(sid: str, info: Any | None, tail: str) -> str:
    """One line: how Ray says submission ``sid`` ended (``info``: its ``JobDetails``, None if
    Ray has none), then the log's last lines ``tail``."""
    if info is None:
        reason = f"Ray has no job {sid} (its cluster was restarted?)"
    else:
        message = first_line(info.message or "").split(", last available")[0]
        code = info.driver_exit_code
        reason = f"Ray job {str(info.status.value).lower()}"
        reason += f" (exit code {code})" if code is not None else ""
        reason += f": {message}" if message else ""
    return f"{reason}; log: {tail}" if tail else reason


def log_tail(log_file: Path, ray_logs: Callable[[], str] | None = None) -> str:
    """The last :data:`LOG_TAIL_LINES` lines of ``log_file`` joined by `` | `` (the trainer's
    own log; if it has none, ``ray_logs()``: Ray's log of the Ray job)."""
    text = ""
    with contextlib.suppress(OSError), log_file.open("rb") as f:
        f.seek(max(0, log_file.stat().st_size - 8192))
        text = f.read().decode(errors="replace")
    if not text.strip() and ray_logs is not None:
        with contextlib.suppress(Exception):  # Ray's log is a fallback: never fail on it
            text = ray_logs()[-8192:]
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return " | ".join(lines[-LOG_TAIL_LINES:])
