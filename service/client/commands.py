"""The client commands: ``submit``, ``jobs``, ``status``, ``logs``, ``cancel``, ``resume`` and
``download`` talk to a running ``gaitforge serve`` (``--server``, default
http://127.0.0.1:8765; the token from ``--token``/``GAITFORGE_TOKEN``, else
``--token-file``/``GAITFORGE_TOKEN_FILE``, else the service's ``{GAITFORGE_HOME}/token``).
Results go to stdout (``--json`` on every read), live lines and errors to stderr; an error
is one line and a non-zero exit."""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from contextlib import contextmanager
from enum import StrEnum
from pathlib import Path
from typing import Annotated

import typer
from gaitforge.service.cli_options import AsJson, JobSeed, SetFields, assignments
from gaitforge.service.client.download import Downloaded, download
from gaitforge.service.client.follow import follow_events, status_line, tail_logs
from gaitforge.service.client.http import DEFAULT_SERVER, ClientError, GaitforgeClient
from gaitforge.service.client.http import resolve_token as find_token
from gaitforge.service.client.spec import read_job_file
from gaitforge.service.client.views import jobs_table, status_table
from gaitforge.service.console import err, out, print_json
from rich.live import Live
from rich.markup import escape
from rich.text import Text

logger = logging.getLogger("gaitforge.service.client")

Server = Annotated[
    str, typer.Option("--server", envvar="GAITFORGE_SERVER", help="the service's URL")
]
Token = Annotated[
    str | None,
    typer.Option("--token", envvar="GAITFORGE_TOKEN", help="bearer token", show_default=False),
]
TokenFile = Annotated[
    Path | None,
    typer.Option(
        "--token-file",
        envvar="GAITFORGE_TOKEN_FILE",
        help="file holding the token [default: $GAITFORGE_HOME/token]",
    ),
]
JobId = Annotated[str, typer.Argument(help="the job's id (j-...)")]
LogEvery = Annotated[
    float, typer.Option(min=0.5, help="s between status lines when not on a terminal")
]


class StateChoice(StrEnum):
    queued = "queued"
    running = "running"
    succeeded = "succeeded"
    failed = "failed"
    cancelled = "cancelled"


@contextmanager
def connected(server: str, token: str | None, token_file: Path | None) -> Iterator[GaitforgeClient]:
    """A client for ``server``; any :class:`ClientError` becomes one line and exit 1."""
    try:
        with GaitforgeClient(server, find_token(token, token_file)) as client:
            yield client
    except ClientError as exc:
        err.print(f"[red]error:[/red] {escape(str(exc))}", soft_wrap=True, highlight=False)
        raise typer.Exit(1) from None


def submit(
    job_file: Annotated[Path, typer.Argument(help="job YAML (see examples/)")],
    follow: Annotated[bool, typer.Option("--follow", help="follow it until it ends")] = False,
    budget_scale: Annotated[
        float, typer.Option(min=1e-6, max=100.0, help="multiply every stage's env-step budget")
    ] = 1.0,
    seed: JobSeed = None,
    set_fields: SetFields = None,
    log_every: LogEvery = 5.0,
    json_out: AsJson = False,
    server: Server = DEFAULT_SERVER,
    token: Token = None,
    token_file: TokenFile = None,
) -> None:
    """Submit a job file (scene files in it go inline); --follow exits 1 unless it succeeds."""
    overrides = assignments(set_fields)
    if seed is not None:
        overrides["seed"] = seed
    with connected(server, token, token_file) as client:
        job = client.submit(read_job_file(job_file, budget_scale, overrides))
        if not follow:
            print_json(job) if json_out else out.print(status_line(job), highlight=False)
            return
        err.print(f"submitted {job['id']} ({job.get('name', '')})", highlight=False)
        final = _follow(client, job["id"], log_every)
    _finish(final, json_out)


def jobs(
    state: Annotated[StateChoice | None, typer.Option(help="only jobs in this state")] = None,
    offset: Annotated[int, typer.Option(min=0)] = 0,
    limit: Annotated[int, typer.Option(min=1, max=500)] = 50,
    json_out: AsJson = False,
    server: Server = DEFAULT_SERVER,
    token: Token = None,
    token_file: TokenFile = None,
) -> None:
    """List your jobs, newest first."""
    with connected(server, token, token_file) as client:
        page = client.jobs(state.value if state else None, offset, limit)
    if json_out:
        print_json(page)
    elif not page.get("items"):
        out.print(f"no jobs{f' {state.value}' if state else ''} (total {page.get('total', 0)})")
    else:
        out.print(jobs_table(page))


def status(
    job_id: JobId,
    follow: Annotated[bool, typer.Option("--follow", help="follow it until it ends")] = False,
    log_every: LogEvery = 5.0,
    json_out: AsJson = False,
    server: Server = DEFAULT_SERVER,
    token: Token = None,
    token_file: TokenFile = None,
) -> None:
    """A job's state, stage and promotion progress, metrics, health and artifacts."""
    with connected(server, token, token_file) as client:
        if follow:
            final = _follow(client, job_id, log_every)
        else:
            found = client.status(job_id)
            print_json(found) if json_out else out.print(status_table(found))
            return
    _finish(final, json_out)


def logs(
    job_id: JobId,
    follow: Annotated[bool, typer.Option("--follow", "-f", help="until the job ends")] = False,
    offset: Annotated[int, typer.Option(min=0, help="start at this byte")] = 0,
    json_out: AsJson = False,
    server: Server = DEFAULT_SERVER,
    token: Token = None,
    token_file: TokenFile = None,
) -> None:
    """A job's log (trainer output); --follow keeps reading until the job ends."""
    with connected(server, token, token_file) as client:
        if json_out:
            print_json(client.logs(job_id, offset))
            return

        def write(text: str) -> None:
            typer.echo(text, nl=False)

        tail_logs(client, job_id, write, offset=offset, follow=follow)


def cancel(
    job_id: JobId,
    json_out: AsJson = False,
    server: Server = DEFAULT_SERVER,
    token: Token = None,
    token_file: TokenFile = None,
) -> None:
    """Cancel a job: queued at once, running after its iteration (with a final checkpoint)."""
    with connected(server, token, token_file) as client:
        found = client.cancel(job_id)
    print_json(found) if json_out else out.print(status_line(found), highlight=False)


def resume(
    job_id: JobId,
    json_out: AsJson = False,
    server: Server = DEFAULT_SERVER,
    token: Token = None,
    token_file: TokenFile = None,
) -> None:
    """Queue a failed or cancelled job again, from its newest checkpoint."""
    with connected(server, token, token_file) as client:
        found = client.resume(job_id)
    print_json(found) if json_out else out.print(status_line(found), highlight=False)


def download_command(
    job_id: JobId,
    checkpoint: Annotated[
        list[str] | None, typer.Option(help="a checkpoint's name, or latest (repeatable)")
    ] = None,
    recording: Annotated[
        list[str] | None,
        typer.Option(help="a recording's name, or latest: the final evaluation's (repeatable)"),
    ] = None,
    report: Annotated[
        list[str] | None, typer.Option(help="an evaluation report's name, or latest")
    ] = None,
    out_dir: Annotated[Path, typer.Option("--out", help="where to put them")] = Path("."),
    json_out: AsJson = False,
    server: Server = DEFAULT_SERVER,
    token: Token = None,
    token_file: TokenFile = None,
) -> None:
    """Download checkpoints (unzipped), recordings and reports, each sha256-checked.

    A checkpoint lands in OUT/<name>/, ready for `gaitforge evaluate OUT/<name>`; with no
    --checkpoint, --recording or --report, the latest checkpoint."""
    wanted = [("checkpoints", n) for n in checkpoint or []]
    wanted += [("recordings", n) for n in recording or []]
    wanted += [("reports", n) for n in report or []]
    done: list[Downloaded] = []
    with connected(server, token, token_file) as client:
        for kind, name in wanted or [("checkpoints", "latest")]:
            done += download(client, job_id, kind, name, out_dir)
    if json_out:
        print_json({"job": job_id, "files": done})
        return
    for item in done:
        out.print(
            f"{item.kind} {item.name}: {item.path} ({item.bytes:,} bytes, sha256 "
            f"{item.sha256[:12]}... verified)",
            soft_wrap=True,
            highlight=False,
        )


def _follow(client: GaitforgeClient, job_id: str, log_every: float) -> dict:
    """Follow a job: a live line on a terminal, else a log line every ``log_every`` s."""
    if err.is_terminal:
        line = Text("waiting for the first status ...")
        with Live(line, console=err, refresh_per_second=4, transient=True) as live:
            return follow_events(
                client,
                job_id,
                lambda s: live.update(Text(status_line(s), no_wrap=True, overflow="ellipsis")),
            )
    if logger.getEffectiveLevel() > logging.INFO:
        logger.setLevel(logging.INFO)
    last = [0.0, ""]

    def log_line(found: dict) -> None:
        state, now = found.get("state", ""), time.monotonic()
        if now - last[0] >= log_every or state != last[1]:
            logger.info("%s", status_line(found))
            last[:] = [now, state]

    return follow_events(client, job_id, log_line)


def _finish(final: dict, json_out: bool) -> None:
    """Print the final status; exit 1 unless the job succeeded."""
    if json_out:
        print_json(final)
    else:
        out.print(status_line(final), soft_wrap=True, highlight=False)
    if final.get("state") != "succeeded":
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    """Add the client commands to the ``gaitforge`` app."""
    for name, command in (
        ("submit", submit),
        ("jobs", jobs),
        ("status", status),
        ("logs", logs),
        ("cancel", cancel),
        ("resume", resume),
        ("download", download_command),
    ):
        app.command(name)(command)
