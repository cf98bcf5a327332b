#!/usr/bin/env python3
"""The image's HEALTHCHECK (installed as ``gaitforge-healthcheck``): exit 0 when healthy.

``GAITFORGE_HEALTHCHECK`` picks what this container is for:

- ``api`` (default): the gaitforge service answers ``GET /healthz`` with 200 on
  ``127.0.0.1:$GAITFORGE_PORT`` (8765);
- ``ray``: a Ray node container without the service: a ``raylet`` process runs here;
- ``none``: always healthy (one-off commands).

Standard library only; one line on stderr saying why when unhealthy.
"""

from __future__ import annotations

import os
import sys
import urllib.error
import urllib.request
from pathlib import Path

TIMEOUT_S = 4.0


def api_healthy(port: str) -> str | None:
    """None when ``/healthz`` answers 200, else why not."""
    url = f"http://127.0.0.1:{port}/healthz"
    try:
        with urllib.request.urlopen(url, timeout=TIMEOUT_S) as response:
            status = response.status
    except urllib.error.HTTPError as exc:
        status = exc.code
    except (OSError, ValueError) as exc:
        return f"{url}: {exc}"
    return None if status == 200 else f"{url}: HTTP {status}"


def raylet_running(proc: Path = Path("/proc")) -> str | None:
    """None when a process of this container is a Ray ``raylet``, else why not."""
    for entry in proc.iterdir():
        if not entry.name.isdigit():
            continue
        try:
            argv0 = (entry / "cmdline").read_bytes().split(b"\0", 1)[0]
        except OSError:
            continue
        if argv0.endswith(b"/raylet") or argv0 == b"raylet":
            return None
    return "no raylet process runs here"


def main() -> int:
    mode = os.environ.get("GAITFORGE_HEALTHCHECK", "api").strip().lower()
    if mode == "none":
        return 0
    if mode == "ray":
        problem = raylet_running()
    elif mode == "api":
        problem = api_healthy(os.environ.get("GAITFORGE_PORT", "8765"))
    else:
        problem = f"GAITFORGE_HEALTHCHECK={mode!r}: expected api, ray or none"
    if problem:
        sys.stderr.write(f"unhealthy: {problem}\n")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
