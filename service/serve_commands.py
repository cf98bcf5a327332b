"""``gaitforge serve``: the REST service (uvicorn) on ``settings.host:port``, jobs on Ray.

Settings come from the environment (``GAITFORGE_HOME``, ``GAITFORGE_TOKENS``, ...; see
:class:`~gaitforge.service.settings.ServiceSettings`), the options override them. Without
configured tokens the service generates one (``{home}/token``, which the CLI client reads)
and listens on loopback only: any other address is refused. ``--stop-ray`` stops the local
Ray head a service started under ``home`` (it outlives the service so that jobs keep running
across restarts) and exits.
"""

from __future__ import annotations

import ipaddress
import logging
import socket
from pathlib import Path
from typing import Annotated

import typer
from gaitforge.service.console import err, fail
from gaitforge.service.settings import ServiceSettings
from pydantic import ValidationError

logger = logging.getLogger(__name__)


def is_loopback(host: str) -> bool:
    """``host`` (an address or a name) reaches this machine only: every address it resolves
    to is a loopback one. A wildcard (0.0.0.0, ::) or an unresolvable name is not."""
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        pass
    try:
        found = {info[4][0] for info in socket.getaddrinfo(host, None)}
    except OSError:
        return False
    return bool(found) and all(ipaddress.ip_address(a.split("%")[0]).is_loopback for a in found)


def load_settings(**overrides: object) -> ServiceSettings:
    """``ServiceSettings`` from the environment with the given (non-None) overrides; a bad
    value (or token list) is one line naming the setting (exit 2)."""
    try:
        settings = ServiceSettings(**{k: v for k, v in overrides.items() if v is not None})
        settings.token_map()
    except ValidationError as exc:
        first = exc.errors()[0]
        field = ".".join(str(p) for p in first["loc"]) or "settings"
        raise fail(f"GAITFORGE_{field.upper()}: {first['msg']}") from None
    except ValueError as exc:
        raise fail(str(exc)) from None
    return settings


def serve(
    host: Annotated[
        str | None, typer.Option(help="address to listen on [default: GAITFORGE_HOST or 127.0.0.1]")
    ] = None,
    port: Annotated[
        int | None, typer.Option(help="TCP port [default: GAITFORGE_PORT or 8765]")
    ] = None,
    home: Annotated[
        Path | None,
        typer.Option(
            help="state directory: database, artifacts, Ray, token "
            "[default: GAITFORGE_HOME or .gaitforge]"
        ),
    ] = None,
    stop_ray: Annotated[
        bool, typer.Option("--stop-ray", help="stop the local Ray head of HOME and exit")
    ] = False,
    log_level: Annotated[str, typer.Option(help="uvicorn's log level")] = "info",
) -> None:
    """Run the REST service: submit, follow and download training jobs (docs at /docs)."""
    settings = load_settings(host=host, port=port, home=home)
    if stop_ray:
        _stop_ray(settings)
        return
    if not settings.configured_tokens() and not is_loopback(settings.host):
        raise fail(
            f"--host {settings.host}: beyond loopback the service needs tokens; set "
            "GAITFORGE_TOKENS='owner:token' or GAITFORGE_TOKENS_FILE, or listen on 127.0.0.1"
        )
    import uvicorn
    from gaitforge.service.api import create_app
    from gaitforge.service.private_files import make_private_dir

    service_logger = logging.getLogger("gaitforge.service")
    if service_logger.getEffectiveLevel() > logging.INFO:  # job starts, ends, re-attaches
        service_logger.setLevel(logging.INFO)

    make_private_dir(settings.home)
    try:
        app = create_app(settings)
    except ValueError as exc:
        raise fail(str(exc)) from None
    where = f"http://{settings.host}:{settings.port}"
    err.print(
        f"gaitforge service on {where} (API docs {where}/docs), home {settings.home}",
        soft_wrap=True,
        highlight=False,
    )
    if settings.configured_tokens():
        err.print("tokens: from GAITFORGE_TOKENS / GAITFORGE_TOKENS_FILE", highlight=False)
    else:
        err.print(
            f"token file: {settings.token_file} (owner 'local'; the CLI reads it: "
            f"GAITFORGE_HOME={settings.home})",
            soft_wrap=True,
            highlight=False,
        )
    uvicorn.run(app, host=settings.host, port=settings.port, log_level=log_level)


def _stop_ray(settings: ServiceSettings) -> None:
    """Stop the local Ray head recorded under ``settings.home`` (if any)."""
    from gaitforge.service.jobs.ray_cluster import stop_local_ray

    stopped = stop_local_ray(settings.home)
    err.print(
        f"local Ray head of {settings.home}: {'stopped' if stopped else 'none running'}",
        highlight=False,
    )
