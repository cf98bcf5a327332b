"""The REST API's client (:class:`GaitforgeClient`) and the CLI commands that use it: submit,
jobs, status, logs, cancel, resume, download."""

from gaitforge.service.client.http import (
    ApiError,
    ClientError,
    DigestMismatch,
    GaitforgeClient,
    ServerUnreachable,
    resolve_token,
)

__all__ = [
    "ApiError",
    "ClientError",
    "DigestMismatch",
    "GaitforgeClient",
    "ServerUnreachable",
    "resolve_token",
]
