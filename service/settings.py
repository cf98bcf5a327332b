"""The service's settings, from the environment (prefix ``GAITFORGE_``) or arguments.

    settings = ServiceSettings()                      # GAITFORGE_HOME, GAITFORGE_PORT, ...
    settings = ServiceSettings(home=Path("/srv/gf"), port=9000)

Everything the service keeps lives under ``home`` unless moved: the database
(``database_url``, any SQLAlchemy URL), the job artifacts (``artifact_root``: on a cluster a
path every node sees), the local Ray head's state and the generated token.
"""

from __future__ import annotations

from pathlib import Path

from pydantic import Field, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

LOCAL_OWNER = "local"
"""the owner of the token the service generates when none is configured"""


class ServiceSettings(BaseSettings):
    """Where the service keeps its state, how it is reached and its limits."""

    model_config = SettingsConfigDict(env_prefix="GAITFORGE_", extra="ignore")

    home: Path = Field(
        default=Path(".gaitforge"), description="state directory (database, artifacts, Ray, token)"
    )
    database_url: str | None = Field(
        default=None, description="SQLAlchemy URL (default: SQLite in home/gaitforge.db)"
    )
    artifact_root: Path | None = Field(
        default=None, description="job directories (default: home/artifacts)"
    )
    ray_address: str | None = Field(
        default=None, description="Ray cluster to run jobs on (None: a local head)"
    )
    tokens: str | None = Field(default=None, description="bearer tokens, 'owner:token,owner:token'")
    tokens_file: Path | None = Field(
        default=None, description="a file of 'owner:token' lines ('#' starts a comment)"
    )
    host: str = Field(default="127.0.0.1", min_length=1, description="address to listen on")
    port: int = Field(default=8765, ge=0, le=65535, description="TCP port to listen on")
    max_running_jobs: int = Field(default=1, ge=1, le=1024, description="jobs run at once")
    max_jobs_per_owner: int = Field(
        default=8, ge=1, le=100_000, description="queued and running jobs per owner"
    )
    max_body_bytes: int = Field(
        default=1_000_000, ge=1024, le=1_000_000_000, description="request body limit, bytes"
    )
    max_body_depth: int = Field(
        default=64,
        ge=8,
        le=500,
        description="how deeply a submitted job (JSON or YAML) may nest mappings and lists; "
        "deeper bodies are refused (422) as they are parsed (a real job nests under 10)",
    )
    max_number_chars: int = Field(
        default=100,
        ge=24,
        le=4000,
        description="the most characters one number of a submitted job may have (JSON or "
        "YAML, sign and digits); longer ones are refused (422) before they are converted",
    )
    body_timeout_s: float = Field(
        default=30.0,
        gt=0,
        le=3600,
        description="s a request's body may take to arrive, from when the service starts "
        "reading it; a slower or stalled body is answered 408 and its connection closed",
    )
    poll_interval_s: float = Field(
        default=1.0, gt=0, le=60, description="s between the runner's reconcile passes"
    )
    ray_probe_timeout_s: float = Field(
        default=5.0,
        gt=0,
        le=60,
        description="s the runner waits for Ray's answer to its health check before each pass "
        "(the GCS, asked through the dashboard's /api/gcs_healthz)",
    )
    ray_lost_after_s: float = Field(
        default=10.0,
        ge=0,
        le=3600,
        description="s Ray may stay unreachable before the running jobs are marked failed "
        "(resumable); a local head whose GCS or raylet died fails them at once",
    )

    @field_validator("tokens")
    @classmethod
    def _tokens_parse(cls, value: str | None) -> str | None:
        if value is not None:
            parse_tokens(value.split(","), "tokens")
        return value

    @property
    def db_url(self) -> str:
        """The database's SQLAlchemy URL."""
        return self.database_url or f"sqlite:///{self.home}/gaitforge.db"

    @property
    def artifacts(self) -> Path:
        """The root of the job directories (``<artifacts>/jobs/<id>``)."""
        return self.artifact_root or self.home / "artifacts"

    @property
    def token_file(self) -> Path:
        """Where a generated token is written (mode 0600) and the CLI looks for it."""
        return self.home / "token"

    def configured_tokens(self) -> bool:
        """Tokens come from ``tokens`` or ``tokens_file`` (not generated)."""
        return self.tokens is not None or self.tokens_file is not None

    def token_map(self) -> dict[str, str]:
        """token -> owner, from ``tokens`` and ``tokens_file`` (empty: none configured).

        Raises:
            ValueError: a malformed entry, naming ``tokens`` or the file and line.
        """
        found: dict[str, str] = {}
        if self.tokens:
            found.update(parse_tokens(self.tokens.split(","), "tokens"))
        if self.tokens_file is not None:
            try:
                lines = self.tokens_file.read_text().splitlines()
            except OSError as exc:
                raise ValueError(f"tokens_file: {self.tokens_file}: {exc.strerror}") from None
            found.update(parse_tokens(lines, f"tokens_file: {self.tokens_file}"))
        return found


def parse_tokens(entries: list[str], source: str) -> dict[str, str]:
    """``["owner:token", ...]`` -> {token: owner}; blank entries and '#' comments skipped.

    Raises:
        ValueError: an entry without an owner or a token (naming ``source`` and the entry).
    """
    found: dict[str, str] = {}
    for number, raw in enumerate(entries, start=1):
        entry = raw.split("#", 1)[0].strip()
        if not entry:
            continue
        owner, sep, token = (part.strip() for part in entry.partition(":"))
        if not sep or not owner or not token:
            raise ValueError(f"{source}: entry {number}: expected 'owner:token'")
        found[token] = owner
    return found
