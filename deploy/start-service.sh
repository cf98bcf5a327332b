#!/usr/bin/env bash
# gaitforge-start-service: (re)start `gaitforge serve` in the background beside the Ray head of
# this node, once Ray's jobs API answers; the head start commands of deploy/cluster.yaml and
# deploy/cluster-onprem.yaml run it. Exits 0 when the service answers /healthz.
#
# Environment (see gaitforge.service.settings): GAITFORGE_HOME (state, serve.log, serve.pid),
# GAITFORGE_TOKENS_FILE or GAITFORGE_TOKENS (required beyond loopback), GAITFORGE_HOST
# (default 0.0.0.0), GAITFORGE_PORT (8765), GAITFORGE_RAY_ADDRESS, GAITFORGE_RAY_DASHBOARD
# (default http://127.0.0.1:8265), GAITFORGE_START_WAIT_S (120); the Ray token as Ray finds it
# (RAY_AUTH_TOKEN, RAY_AUTH_TOKEN_PATH or ~/.ray/auth_token).
set -euo pipefail

home="${GAITFORGE_HOME:?GAITFORGE_HOME: set it to the service state directory}"
host="${GAITFORGE_HOST:-0.0.0.0}"
port="${GAITFORGE_PORT:-8765}"
dashboard="${GAITFORGE_RAY_DASHBOARD:-http://127.0.0.1:8265}"
wait_s="${GAITFORGE_START_WAIT_S:-120}"
log="$home/serve.log"
pidfile="$home/serve.pid"
mkdir -p "$home"

# answers URL [any]: the URL answers 200 (with "any": any HTTP status, e.g. 401 without a token)
answers() {
    python - "$@" <<'PY'
import sys, urllib.error, urllib.request
try:
    urllib.request.urlopen(sys.argv[1], timeout=2)
except urllib.error.HTTPError:
    sys.exit(0 if len(sys.argv) > 2 else 1)
except (OSError, ValueError):
    sys.exit(1)
PY
}

deadline=$((SECONDS + wait_s))
until answers "$dashboard/api/version" any; do
    if ((SECONDS > deadline)); then
        echo "gaitforge-start-service: Ray jobs API at $dashboard: no answer in ${wait_s} s" >&2
        exit 1
    fi
    sleep 2
done

# A service started earlier (an earlier `ray up`) stops first; its jobs are Ray jobs and the
# new service re-attaches to the ones that still run.
if [[ -f "$pidfile" ]] && kill -0 "$(cat "$pidfile")" 2>/dev/null; then
    old="$(cat "$pidfile")"
    kill -TERM "$old"
    for _ in $(seq 30); do kill -0 "$old" 2>/dev/null || break; sleep 1; done
    kill -KILL "$old" 2>/dev/null || true
fi

setsid nohup gaitforge serve --host "$host" --port "$port" >>"$log" 2>&1 </dev/null &
echo $! >"$pidfile"

deadline=$((SECONDS + wait_s))
until answers "http://127.0.0.1:$port/healthz"; do
    if ! kill -0 "$(cat "$pidfile")" 2>/dev/null || ((SECONDS > deadline)); then
        echo "gaitforge-start-service: the service did not come up; the end of $log:" >&2
        tail -n 20 "$log" >&2
        exit 1
    fi
    sleep 1
done
echo "gaitforge service on http://$host:$port (pid $(cat "$pidfile"), log $log)"
