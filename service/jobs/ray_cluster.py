"""The Ray cluster the runner submits jobs to: a local head started for the service
(:mod:`gaitforge.service.jobs.local_ray`), or a cluster named by ``GAITFORGE_RAY_ADDRESS``.

    connection = connect_ray(settings)      # starts or re-attaches to {home}'s local head
    connection.client.submit_job(...)       # Ray's jobs API, token-authenticated
    gcs_problem(connection.dashboard_url)   # None, or why Ray's GCS does not answer
    stop_local_ray(settings.home)           # `gaitforge serve --stop-ray`, tests

The jobs client sends the Ray token as a bearer header, so the service process needs no Ray
environment of its own; every request has a timeout.
"""

from __future__ import annotations

import os
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any
from urllib.parse import urlsplit

from gaitforge.service.jobs.local_ray import (
    STATE_FILE,
    TOKEN_FILE,
    LocalHead,
    RayError,
    first_line,
    head_death,
    head_processes,
    local_head,
    read_head,
    read_token,
    running_head,
    start_local_ray,
    stop_local_ray,
)

if TYPE_CHECKING:
    from gaitforge.service.settings import ServiceSettings
    from ray.job_submission import JobSubmissionClient

__all__ = [
    "STATE_FILE",
    "TOKEN_FILE",
    "LocalHead",
    "RayConnection",
    "RayError",
    "connect_cluster",
    "connect_ray",
    "default_dashboard",
    "first_line",
    "gcs_problem",
    "head_death",
    "head_processes",
    "jobs_client",
    "local_head",
    "read_head",
    "read_token",
    "running_head",
    "start_local_ray",
    "stop_local_ray",
]

DEFAULT_DASHBOARD_PORT = 8265
REQUEST_TIMEOUT_S = 30.0
"""the longest one call to the jobs API may take"""
GCS_HEALTH_PATH = "/api/gcs_healthz"
"""the dashboard's check of its GCS (public: no token needed); 503 when the GCS does not
answer"""


@dataclass
class RayConnection:
    """Where jobs go: the cluster's address, its jobs API and a client for it."""

    address: str
    dashboard_url: str
    client: JobSubmissionClient
    started: bool
    """this call started a new local head"""
    local: bool
    """a head on this machine managed by the service (entrypoints use ``sys.executable``)"""
    num_cpus: int | None = None
    """the CPUs jobs may use, where the cluster cannot grow (a local head's); None: a
    cluster given by address (it may autoscale)"""


def connect_ray(settings: ServiceSettings) -> RayConnection:
    """A connection to ``settings.ray_address``'s cluster, or to the local head of
    ``settings.home`` (re-attached if it answers, else started: about 7 s).

    Raises:
        RayError: the head did not start, or the cluster's jobs API did not answer.
    """
    if settings.ray_address:
        return connect_cluster(settings.ray_address)
    home = Path(settings.home)
    head, started = local_head(home)
    token = read_token(home)
    client = jobs_client(head.dashboard_url, token)
    return RayConnection(
        head.address,
        head.dashboard_url,
        client,
        started=started,
        local=True,
        num_cpus=head.num_cpus,
    )


def connect_cluster(address: str) -> RayConnection:
    """A connection to an existing cluster: its jobs API at ``GAITFORGE_RAY_DASHBOARD``
    (default ``http://<host of address>:8265``), with the token from ``RAY_AUTH_TOKEN``,
    ``RAY_AUTH_TOKEN_PATH`` or ``~/.ray/auth_token`` if there is one."""
    dashboard = os.environ.get("GAITFORGE_RAY_DASHBOARD") or default_dashboard(address)
    client = jobs_client(dashboard, cluster_token())
    return RayConnection(address, dashboard, client, started=False, local=False)


def default_dashboard(address: str) -> str:
    """``http://<host>:8265`` for a Ray address (``host:port``, ``ray://host:port``, an
    ``http(s)://`` URL is kept; ``auto``/``local`` -> 127.0.0.1)."""
    if address.startswith(("http://", "https://")):
        return address.rstrip("/")
    host = urlsplit(address if "://" in address else f"ray://{address}").hostname
    if not host or address in ("auto", "local"):
        host = "127.0.0.1"
    host = f"[{host}]" if ":" in host else host
    return f"http://{host}:{DEFAULT_DASHBOARD_PORT}"


def gcs_problem(dashboard_url: str, timeout_s: float = 5.0) -> str | None:
    """Why the Ray cluster behind ``dashboard_url`` is not up, in a few words: its jobs API
    does not answer, or answers that its GCS does not (:data:`GCS_HEALTH_PATH`); None when it
    is up. Any other answer counts as up (a dashboard without that route, say)."""
    try:
        with urllib.request.urlopen(f"{dashboard_url}{GCS_HEALTH_PATH}", timeout=timeout_s):
            return None
    except urllib.error.HTTPError as exc:
        if exc.code < 500:
            return None
        return f"its GCS does not answer (HTTP {exc.code}: {first_line(str(exc.reason))})"
    except (OSError, ValueError) as exc:
        return f"its jobs API at {dashboard_url} does not answer ({first_line(exc)})"


def cluster_token() -> str | None:
    """The Ray token of a cluster, found where Ray looks for it (None: none)."""
    if token := os.environ.get("RAY_AUTH_TOKEN", "").strip():
        return token
    for path in (os.environ.get("RAY_AUTH_TOKEN_PATH"), "~/.ray/auth_token"):
        if path and (file := Path(path).expanduser()).is_file():
            return file.read_text().strip() or None
    return None


def jobs_client(dashboard_url: str, token: str | None) -> JobSubmissionClient:
    """Ray's jobs API client for ``dashboard_url``, sending ``token`` as a bearer header.

    Raises:
        RayError: the jobs API did not answer.
    """
    from ray.job_submission import JobSubmissionClient  # lazy: imports much of Ray

    class TimedClient(JobSubmissionClient):
        """Ray's client with a timeout on every request (it sets none: a hung dashboard
        would hang the runner)."""

        def _do_request(self, method: str, endpoint: str, **kwargs: Any) -> Any:
            kwargs.setdefault("timeout", REQUEST_TIMEOUT_S)
            return super()._do_request(method, endpoint, **kwargs)

    headers = {"Authorization": f"Bearer {token}"} if token else None
    try:
        return TimedClient(dashboard_url, headers=headers)
    except Exception as exc:  # ConnectionError, AuthenticationError, RuntimeError, ...
        raise RayError(f"Ray jobs API at {dashboard_url}: {first_line(exc)}") from None
