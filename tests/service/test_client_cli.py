"""The client's parts that need no service: job files sent inline and scaled, server-sent
events, problem+json errors as one line, token lookup, checkpoint zips unpacked safely, and
a CLI command against a port where nothing listens (the round trip with a real service is
in test_round_trip.py)."""

from __future__ import annotations

import json
import socket
import zipfile
from pathlib import Path

import httpx
import pytest
from gaitforge.service.cli import app
from gaitforge.service.client.download import unzip_checkpoint
from gaitforge.service.client.http import ApiError, ClientError, parse_sse, resolve_token
from gaitforge.service.client.spec import read_job_file
from typer.testing import CliRunner

runner = CliRunner()

JOB = """name: two-stages
stages:
  - scene: stand-2d
    env_steps: 20000
  - scene: scenes/mine.yaml
    env_steps: 30000
    transition: blend
    network: {hidden: [8]}
"""


def test_a_job_file_goes_with_its_scene_files_inline_and_scaled(tmp_path: Path) -> None:
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "mine.yaml").write_text("name: mine\nbody: gait2d\nepisode_s: 2\n")
    (tmp_path / "job.yaml").write_text(JOB)
    spec = read_job_file(tmp_path / "job.yaml", budget_scale=0.01)
    first, second = spec["stages"]
    assert first["scene"] == "stand-2d", "catalogue names stay names"
    assert second["scene"] == {"name": "mine", "body": "gait2d", "episode_s": 2}
    assert (first["env_steps"], second["env_steps"]) == (200, 300)
    assert second["blend"]["ramp_env_steps"] == 2000, "the default ramp (200000) is scaled too"
    assert json.loads(json.dumps(spec)) == spec, "JSON-able"


def test_a_missing_scene_file_is_one_line_naming_the_stage(tmp_path: Path) -> None:
    (tmp_path / "job.yaml").write_text(JOB)
    with pytest.raises(ClientError, match=r"job.yaml: stages.1.scene: .*mine.yaml: file not found"):
        read_job_file(tmp_path / "job.yaml")


def test_server_sent_events_parse() -> None:
    lines = [
        ": ping",
        "",
        "event: progress",
        'data: {"state": "running",',
        'data: "id": "j-1"}',
        "",
        "data: plain text",
        "",
        "event: end",
        "",
    ]
    assert list(parse_sse(iter(lines))) == [
        ("progress", {"state": "running", "id": "j-1"}),
        ("message", "plain text"),
        ("end", None),
    ]


def test_a_problem_is_one_line_with_its_field_errors() -> None:
    problem = {
        "type": "about:blank",
        "title": "Unprocessable Content",
        "status": 422,
        "detail": "the job spec is invalid",
        "errors": [{"field": "stages.0.scene", "message": "paths are not accepted"}],
    }
    response = httpx.Response(
        422, json=problem, headers={"content-type": "application/problem+json"}
    )
    error = ApiError.from_response(response)
    assert str(error) == (
        "422 Unprocessable Content: the job spec is invalid "
        "(stages.0.scene: paths are not accepted)"
    )
    assert str(ApiError.from_response(httpx.Response(502, text="<html>bad\n gateway</html>"))) == (
        "HTTP 502: <html>bad gateway</html>"
    )


def test_the_token_comes_from_the_option_the_environment_or_the_service_home(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    for name in ("GAITFORGE_TOKEN", "GAITFORGE_TOKEN_FILE", "GAITFORGE_HOME"):
        monkeypatch.delenv(name, raising=False)
    home = tmp_path / "home"
    assert resolve_token(home=home) is None
    home.mkdir()
    (home / "token").write_text("from-home\n")
    assert resolve_token(home=home) == "from-home"
    monkeypatch.setenv("GAITFORGE_HOME", str(home))
    assert resolve_token() == "from-home", "GAITFORGE_HOME is where the service wrote it"
    (tmp_path / "t").write_text("# mine\nfrom-file\n")
    monkeypatch.setenv("GAITFORGE_TOKEN_FILE", str(tmp_path / "t"))
    assert resolve_token() == "from-file"
    monkeypatch.setenv("GAITFORGE_TOKEN", "from-env")
    assert resolve_token() == "from-env"
    assert resolve_token("given") == "given"
    monkeypatch.delenv("GAITFORGE_TOKEN")
    with pytest.raises(ClientError, match=r"token file .*nowhere"):
        resolve_token(token_file=tmp_path / "nowhere")


@pytest.mark.parametrize("prefix", ["", "ckpt-000000000512/"])
def test_a_checkpoint_zip_unpacks_into_its_folder(tmp_path: Path, prefix: str) -> None:
    archive = tmp_path / "c.zip"
    with zipfile.ZipFile(archive, "w") as zf:
        zf.writestr(f"{prefix}meta.json", "{}")
        zf.writestr(f"{prefix}sub/policy.safetensors", "x")
    target = unzip_checkpoint(archive, tmp_path / "out" / "ckpt-000000000512")
    assert sorted(p.relative_to(target).as_posix() for p in target.rglob("*") if p.is_file()) == [
        "meta.json",
        "sub/policy.safetensors",
    ]


def test_a_zip_member_outside_its_folder_is_refused(tmp_path: Path) -> None:
    archive = tmp_path / "evil.zip"
    with zipfile.ZipFile(archive, "w") as zf:
        zf.writestr("meta.json", "{}")
        zf.writestr("../../escaped.txt", "x")
    with pytest.raises(ClientError, match="leaves its folder"):
        unzip_checkpoint(archive, tmp_path / "out" / "ckpt")
    assert not (tmp_path / "escaped.txt").exists() and not (tmp_path / "out" / "ckpt").exists()


def test_no_service_is_one_line_naming_the_server() -> None:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]  # bound, not listening: connections are refused
        server = f"http://127.0.0.1:{port}"
        result = runner.invoke(
            app, ["jobs", "--server", server, "--token", "t"], env={"COLUMNS": "300"}
        )
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and f"no gaitforge service at {server}" in lines[0], result.output
