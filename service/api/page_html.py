"""The HTML of the service's pages (``service.api.pages``): one layout, the sign-in form, the
jobs list and the job page with its script. Every value from a job or a person is escaped
here; the script and the style carry the response's CSP nonce; nothing is fetched from
outside the service.
"""

from __future__ import annotations

import json
from datetime import UTC, datetime
from html import escape

from gaitforge.learner.metrics import BY_NAME
from gaitforge.service.api.schemas import JobStatus

CURVES = [
    *([name, BY_NAME[name].label] for name in ("return", "speed", "fall_rate")),
    ["steps_per_s", "env steps/s"],
    *([f"cmaes_{key}", f"CMA-ES {key}"] for key in ("best", "mean", "sigma")),
]
"""the job page's curves against env steps: [metric key, label] (``learner.metrics``; the
CMA-ES ones, ``learner.run_log.search_metrics``, in a job with an ``optimize`` stage)"""

STYLE = """
body { font: 14px/1.4 system-ui, sans-serif; margin: 1.5em auto; max-width: 70em; color: #222; }
header { display: flex; justify-content: space-between; align-items: baseline; }
table { border-collapse: collapse; width: 100%; }
th, td { text-align: left; padding: 0.25em 0.6em; border-bottom: 1px solid #ddd; }
.state { font-weight: bold; }
.grid { display: grid; grid-template-columns: 1fr 1fr; gap: 1em; }
pre { background: #f6f6f6; padding: 0.6em; max-height: 20em; overflow: auto; }
canvas { width: 100%; border: 1px solid #ddd; }
video { width: 100%; background: #000; }
.error { color: #a00; }
.note { color: #666; font-size: 0.9em; }
"""


def layout(title: str, body: str, nonce: str, signed_in_as: str | None, csrf: str = "") -> str:
    """A whole page: ``body`` (HTML, already escaped) under a header naming the owner."""
    signed_in = ""
    if signed_in_as is not None:
        signed_in = (
            f'<form method="post" action="/signout">signed in as {escape(signed_in_as)} '
            f'<input type="hidden" name="csrf" value="{escape(csrf)}">'
            '<button type="submit">sign out</button></form>'
        )
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>{escape(title)} - gaitforge</title>
<meta name="viewport" content="width=device-width, initial-scale=1">
<style nonce="{nonce}">{STYLE}</style></head>
<body><header><h1><a href="/">gaitforge</a></h1>{signed_in}</header>
{body}
</body></html>
"""


def sign_in_body(problem: str | None = None) -> str:
    """The sign-in form (the owner's token), with ``problem`` above it if the last try
    failed."""
    failed = f'<p class="error">{escape(problem)}</p>' if problem else ""
    return f"""<h2>Sign in</h2>{failed}
<form method="post" action="/signin">
<label>token <input type="password" name="token" autocomplete="current-password" required>
</label> <button type="submit">sign in</button></form>
<p class="note">The token is the one the CLI uses (<code>~/.gaitforge/token</code> on a local
service, or the one your administrator gave you).</p>"""


def jobs_body(jobs: list[JobStatus], csrf: str, nonce: str, now: datetime | None = None) -> str:
    """The jobs list (state, stage, progress and age of each, newest first) and a form to
    submit a job as JSON (its script)."""
    now = now or datetime.now(UTC)
    rows = "".join(
        f'<tr><td><a href="/jobs/{escape(job.id)}">{escape(job.name)}</a></td>'
        f'<td class="state">{escape(job.state)}</td><td>{escape(_stage_text(job))}</td>'
        f"<td>{job.env_steps:,} env steps</td><td>{_age(job.created_at, now)}</td></tr>"
        for job in jobs
    )
    if not rows:
        rows = '<tr><td colspan="5">no jobs yet</td></tr>'
    data = _json_for_script({"csrf": csrf})
    return f"""<h2>Jobs</h2><table id="jobs"><thead><tr><th>job</th><th>state</th>
<th>stage</th><th>progress</th><th>age</th></tr></thead><tbody>{rows}</tbody></table>
<h3>Submit a job</h3>
<form id="submit"><textarea id="spec" rows="8" cols="90" required
placeholder='{{"name": "walk", "stages": [{{"scene": "walk-2d+clock", "env_steps": 100000}}]}}'
></textarea><br><button type="submit">submit</button></form>
<p id="submit-error" class="error"></p>
<p class="note">A job spec as JSON, as the REST API takes it (<code>gaitforge submit JOB.yaml
</code> takes a job file).</p>
<script id="page-data" type="application/json">{data}</script>
<script nonce="{nonce}">{SUBMIT_SCRIPT}</script>"""


def job_body(job: JobStatus, csrf: str, nonce: str) -> str:
    """One job's page: its status (updated live from the event stream), curves, health, log
    tail, latest video and downloads, and cancel and resume buttons (its script)."""
    data = _json_for_script({"id": job.id, "csrf": csrf, "series": CURVES})
    return f"""<h2>{escape(job.name)} <small>{escape(job.id)}</small></h2>
<p>state <span id="state" class="state">{escape(job.state)}</span>
<span id="phase"></span>; <span id="stage">{escape(_stage_text(job))}</span>;
<span id="progress">{job.env_steps:,} env steps</span>
<button id="cancel" hidden>cancel</button> <button id="resume" hidden>resume</button></p>
<p id="error" class="error"></p>
<table id="rules"></table>
<h3>Curves</h3>
<canvas id="curve" width="1000" height="420" data-points="0"></canvas>
<p class="note">return, speed (m/s), falls and env steps/s against env steps; dashed lines
mark stage boundaries.</p>
<div class="grid"><div><h3>Latest video</h3><video id="video" controls muted></video>
<p id="no-video" class="note">no video yet (the job films its final evaluation)</p></div>
<div><h3>Health</h3><table id="health"></table><h3>Downloads</h3><ul id="downloads"></ul>
<p class="note">MCAP recordings open in Foxglove (app.foxglove.dev or the desktop app: Open
local file); checkpoints load with <code>gaitforge evaluate</code> or
<code>gaitforge.load_policy</code>.</p></div></div>
<h3>Log</h3><pre id="log"></pre>
<script id="job-data" type="application/json">{data}</script>
<script nonce="{nonce}">{JOB_SCRIPT}</script>"""


def _json_for_script(data: dict) -> str:
    """``data`` as JSON that cannot end the ``<script>`` element it sits in."""
    return json.dumps(data).replace("<", "\\u003c")


def _stage_text(job: JobStatus) -> str:
    """The job's stage as a phrase: index, name and env steps of its budget."""
    stage = job.stage
    if stage is None:
        return "not started"
    return (
        f"stage {stage.index + 1} of {stage.count} ({stage.name}): {stage.env_steps:,} of "
        f"{stage.budget_env_steps:,} env steps"
    )


def _age(then: datetime, now: datetime) -> str:
    """How long ago ``then`` was, in the largest whole unit."""
    if then.tzinfo is None:
        then = then.replace(tzinfo=UTC)
    seconds = max(0, int((now - then).total_seconds()))
    for unit, size in (("d", 86400), ("h", 3600), ("min", 60)):
        if seconds >= size:
            return f"{seconds // size} {unit} ago"
    return f"{seconds} s ago"


SUBMIT_SCRIPT = """
"use strict";
const page = JSON.parse(document.getElementById("page-data").textContent);
document.getElementById("submit").addEventListener("submit", async (event) => {
  event.preventDefault();
  const error = document.getElementById("submit-error");
  let spec;
  try { spec = JSON.parse(document.getElementById("spec").value); }
  catch (e) { error.textContent = "not JSON: " + e.message; return; }
  const r = await fetch("/v1/jobs", {method: "POST", credentials: "same-origin",
    headers: {"Content-Type": "application/json", "X-CSRF-Token": page.csrf},
    body: JSON.stringify(spec)});
  const answer = await r.json();
  if (r.ok) window.location.href = "/jobs/" + answer.id;
  else error.textContent = answer.detail || r.statusText;
});
"""

JOB_SCRIPT = """
"use strict";
const job = JSON.parse(document.getElementById("job-data").textContent);
const api = "/v1/jobs/" + job.id;
const $ = (id) => document.getElementById(id);
const points = [];
let since = null, logOffset = 0, ended = false;

function text(node, value) { node.textContent = value; }

function cell(row, value, tag) {
  const c = document.createElement(tag || "td"); c.textContent = value; row.appendChild(c);
}

function showStatus(s) {
  text($("state"), s.state);
  text($("phase"), s.phase ? "(" + s.phase + ")" : "");
  const st = s.stage;
  text($("stage"), st ? "stage " + (st.index + 1) + " of " + st.count + " (" + st.name + "): "
    + st.env_steps.toLocaleString() + " of " + st.budget_env_steps.toLocaleString()
    + " env steps" : "not started");
  text($("progress"), s.env_steps.toLocaleString() + " env steps"
    + (s.steps_per_s ? ", " + Math.round(s.steps_per_s) + " steps/s" : ""));
  text($("error"), s.error || "");
  const rules = $("rules"); rules.replaceChildren();
  for (const r of (st && st.promote) || []) {
    const row = document.createElement("tr");
    cell(row, r.rule); cell(row, r.value === null ? "-" : Number(r.value).toFixed(3));
    cell(row, r.passing ? "passing" : "not yet"); rules.appendChild(row);
  }
  const health = $("health"); health.replaceChildren();
  for (const [cause, n] of Object.entries(s.health || {})) {
    const row = document.createElement("tr");
    cell(row, cause); cell(row, n); health.appendChild(row);
  }
  const names = (s.actions || []).map((a) => a.name);
  $("cancel").hidden = !names.includes("cancel");
  $("resume").hidden = !names.includes("resume");
}

const SERIES = job.series;

function draw() {
  const canvas = $("curve"), g = canvas.getContext("2d");
  const w = canvas.width, h = canvas.height / SERIES.length;
  g.clearRect(0, 0, canvas.width, canvas.height);
  canvas.dataset.points = String(points.length);
  if (!points.length) return;
  const x0 = points[0].env_steps, x1 = Math.max(points[points.length - 1].env_steps, x0 + 1);
  const xs = (p) => 50 + (w - 60) * (p.env_steps - x0) / (x1 - x0);
  SERIES.forEach(([key, label], k) => {
    const top = k * h, values = points.map((p) => p[key]).filter((v) => typeof v === "number");
    g.fillStyle = "#444"; g.font = "12px sans-serif"; g.fillText(label, 4, top + 14);
    if (!values.length) return;
    const lo = Math.min(...values), hi = Math.max(...values, lo + 1e-9);
    const ys = (v) => top + h - 8 - (h - 24) * (v - lo) / (hi - lo);
    g.strokeStyle = "#bbb"; g.setLineDash([4, 4]);
    for (let i = 1; i < points.length; i++) {
      if (points[i].stage !== points[i - 1].stage) {
        g.beginPath(); g.moveTo(xs(points[i]), top); g.lineTo(xs(points[i]), top + h); g.stroke();
      }
    }
    g.setLineDash([]); g.strokeStyle = "#1f77b4"; g.beginPath();
    points.forEach((p, i) => {
      if (typeof p[key] !== "number") return;
      if (i === 0) g.moveTo(xs(p), ys(p[key])); else g.lineTo(xs(p), ys(p[key]));
    });
    g.stroke();
    g.fillText(hi.toPrecision(3), 4, top + 28); g.fillText(lo.toPrecision(3), 4, top + h - 8);
  });
}

async function getJson(path) {
  const r = await fetch(api + path, {credentials: "same-origin"});
  return r.ok ? r.json() : null;
}

async function pollMetrics() {
  const m = await getJson("/metrics" + (since === null ? "" : "?since=" + since));
  if (m && m.points.length) { points.push(...m.points); since = m.last_iteration; draw(); }
}

async function pollLog() {
  const chunk = await getJson("/logs?offset=" + logOffset);
  if (!chunk) return;
  if (chunk.text) {
    const log = $("log"); log.textContent = (log.textContent + chunk.text).slice(-20000);
    log.scrollTop = log.scrollHeight;
  }
  logOffset = chunk.next_offset;
}

let seenVideo = "";

async function refreshFiles() {
  const list = $("downloads"); list.replaceChildren();
  let video = null;
  for (const kind of ["checkpoints", "recordings", "reports"]) {
    const files = await getJson("/" + kind);
    for (const f of (files && files.items) || []) {
      const item = document.createElement("li"), link = document.createElement("a");
      link.href = f.href; link.textContent = kind + ": " + f.name; link.download = "";
      item.appendChild(link); list.appendChild(item);
      if (f.media_type === "video/mp4") video = f;
    }
  }
  if (!video) return;
  // a video being written grows: shown once the job has ended or its size held still
  const seen = video.href + " " + video.size_bytes, stable = seen === seenVideo;
  seenVideo = seen;
  if ((ended || stable) && !$("video").src.endsWith(video.href)) {
    $("video").src = video.href; $("no-video").hidden = true;
  }
}

async function act(name) {
  const r = await fetch(api + "/" + name, {method: "POST", credentials: "same-origin",
                                           headers: {"X-CSRF-Token": job.csrf}});
  if (r.ok) showStatus(await r.json());
  else text($("error"), (await r.json()).detail || r.statusText);
}

$("cancel").addEventListener("click", () => act("cancel"));
$("resume").addEventListener("click", () => act("resume"));
const events = new EventSource(api + "/events");
events.addEventListener("progress", (e) => showStatus(JSON.parse(e.data)));
events.addEventListener("end", (e) => {
  showStatus(JSON.parse(e.data)); events.close(); ended = true; pollMetrics(); refreshFiles();
});
pollMetrics(); pollLog(); refreshFiles();
setInterval(pollMetrics, 2000);
setInterval(pollLog, 3000);
setInterval(() => { if (!ended) refreshFiles(); }, 5000);
"""
