"""The pages a person follows jobs on, in a real browser: headless Chromium (Debian's) driven
by Playwright against a real uvicorn with the real runner and Ray. Sign in with a token, submit
a small job from the page, submit a long one and cancel it (queued behind the small one),
watch the small one's curve grow and its state change to succeeded, play the video of its
final evaluation, download a checkpoint. Another owner's job is neither listed nor reachable;
signed out, the pages ask for a token; the cookie is HttpOnly and SameSite=Strict, and a
cookie request that changes something needs the CSRF token."""

from __future__ import annotations

import json
import shutil
import time
import zipfile
from collections.abc import Callable, Iterator
from pathlib import Path

import httpx
import pytest
from gaitforge.service.api.app import create_app
from gaitforge.service.jobs.runner import JobRunner
from gaitforge.service.settings import ServiceSettings
from playwright.sync_api import expect, sync_playwright

from tests.service.api_support import ALICE, BOB, TOKENS, auth, serve
from tests.service.conftest import make_tiny_job

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--disable-quic",
]
"""Chromium on a machine with no network beyond loopback: no calls home"""
WAIT_MS = 120_000


@pytest.fixture
def site(service_home: Path, store, ray_connection) -> Iterator[str]:
    """The service (tokens for alice and bob) on a real uvicorn: its base URL."""
    settings = ServiceSettings(home=service_home, tokens=TOKENS, poll_interval_s=0.2)
    runner = JobRunner(settings, store, ray_connection, evaluate_episodes=1)
    runner.start()
    try:
        with serve(create_app(settings, runner)) as port:
            yield f"http://127.0.0.1:{port}"
    finally:
        runner.stop()


def wait_until(what: str, done: Callable[[], bool], timeout_s: float = WAIT_MS / 1000) -> None:
    """Poll ``done`` (reading the page, not evaluating script in it: the pages' policy
    forbids string evaluation) until it holds; fail naming ``what`` after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not done():
        assert time.monotonic() < deadline, f"{what}: not within {timeout_s:.0f} s"
        time.sleep(0.2)


@pytest.fixture(scope="module")
def browser() -> Iterator:
    """Headless Chromium (Debian's, which make installs where apt-get exists; skipped only on
    a machine without apt-get), one for the module's page tests (each takes a new context)."""
    if not Path(CHROMIUM).exists():
        if shutil.which("apt-get"):
            pytest.fail(f"no Chromium at {CHROMIUM}: make installs Debian's chromium")
        pytest.skip("no Chromium and no apt-get to install Debian's")
    with sync_playwright() as p:
        launched = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield launched
        launched.close()


def test_sign_in_submit_watch_download_and_cancel(site: str, browser, tmp_path: Path) -> None:
    """One job trains (a trainer process: seconds); bob's job and the long one are submitted
    while it runs, so that they wait in the queue (one job at a time), and are cancelled
    there: neither starts a trainer of its own."""
    context = browser.new_context(accept_downloads=True)
    page = context.new_page()
    page.goto(site + "/")
    page.fill("input[name=token]", ALICE)
    page.click("button[type=submit]")
    page.wait_for_selector("#jobs")
    cookie = next(c for c in context.cookies() if c["name"] == "gaitforge_session")
    assert cookie["httpOnly"] and cookie["sameSite"] == "Strict"

    page.fill("#spec", json.dumps(make_tiny_job("page-job", env_steps=1024, every_iters=1)))
    page.click("#submit button[type=submit]")
    page.wait_for_url("**/jobs/j-*")
    job_page = page.url
    with httpx.Client(base_url=site, headers=auth(BOB), timeout=30) as bob:
        bobs = bob.post("/v1/jobs", json=make_tiny_job("bobs-job")).json()["id"]
        assert bob.post(f"/v1/jobs/{bobs}/cancel").status_code == 200

    page.goto(site + "/")
    assert "page-job" in page.content() and "bobs-job" not in page.content()
    page.fill("#spec", json.dumps(make_tiny_job("long-job", env_steps=10**8, every_iters=10**6)))
    page.click("#submit button[type=submit]")
    page.wait_for_url("**/jobs/j-*")
    page.wait_for_selector("#cancel:not([hidden])", timeout=WAIT_MS)
    page.click("#cancel")
    expect(page.locator("#state")).to_have_text("cancelled", timeout=WAIT_MS)

    page.goto(job_page)
    wait_until("a first point", lambda: int(page.get_attribute("#curve", "data-points") or 0) >= 1)
    expect(page.locator("#state")).to_have_text("succeeded", timeout=WAIT_MS)
    wait_until("more points", lambda: int(page.get_attribute("#curve", "data-points") or 0) >= 4)
    wait_until("the video", lambda: (page.get_attribute("#video", "src") or "").endswith(".mp4"))
    played = page.evaluate(
        "async () => { const v = document.getElementById('video'); await v.play(); "
        "await new Promise((r) => setTimeout(r, 300)); return v.currentTime; }"
    )
    assert played > 0
    page.screenshot(path=str(tmp_path / "job-page.png"), full_page=True)
    link = page.locator("#downloads a", has_text="checkpoints: ").first
    with page.expect_download() as download:
        link.click()
    saved = tmp_path / "checkpoint.zip"
    download.value.save_as(saved)
    assert any(n.endswith("/policy.safetensors") for n in zipfile.ZipFile(saved).namelist())

    answer = page.goto(f"{site}/jobs/{bobs}")
    assert answer.status == 404 and "bobs-job" not in page.content()
    assert page.request.get(f"{site}/v1/jobs/{bobs}").status == 404
    forged = page.request.post(f"{site}/v1/jobs/{bobs}/cancel")
    assert forged.status in (403, 404)
    mine = page.request.post(f"{site}/v1/jobs", data=make_tiny_job("no-csrf"))
    assert mine.status == 403, "a cookie request that changes something needs the CSRF token"
    page.goto(site + "/")
    page.click("header button[type=submit]")  # sign out
    page.wait_for_selector("input[name=token]")
    assert page.goto(f"{site}/v1/jobs").status == 401
    context.close()


def test_pages_carry_a_strict_policy_and_no_outside_assets(site: str) -> None:
    with httpx.Client(base_url=site, timeout=30) as client:
        answer = client.get("/")
        wrong = client.post("/signin", data={"token": "nope"})
        forged = client.post(
            "/signin", data={"token": ALICE}, headers={"Origin": "http://evil.example"}
        )
        signed_out = client.get("/jobs/j-000000000000", follow_redirects=False)
        slash = client.get("/jobs/j-000000000000/", follow_redirects=False)
        signed = client.post("/signin", data={"token": ALICE}, follow_redirects=False)
        missing = client.get("/jobs/j-000000000000")
    policy = answer.headers["content-security-policy"]
    assert "default-src 'self'" in policy and "script-src 'nonce-" in policy
    assert "frame-ancestors 'none'" in policy
    assert "http" not in answer.text.replace(site, ""), "nothing fetched from outside"
    assert wrong.status_code == 401 and "unknown token" in wrong.text
    assert forged.status_code == 403 and "set-cookie" not in forged.headers
    assert signed.status_code == 303
    assert "httponly" in signed.headers["set-cookie"].lower()
    assert "samesite=strict" in signed.headers["set-cookie"].lower()
    assert signed_out.status_code == 303 and signed_out.headers["location"] == "/"
    assert slash.status_code == 404 and "location" not in slash.headers
    assert missing.status_code == 404 and "No job j-000000000000" in missing.text
