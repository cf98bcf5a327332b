"""Env steps/s of the rollout pool on a multi-node Ray cluster on this machine, against one process.

Usage: python bench/cluster_throughput.py [--scene walk-2d] [--backend mujoco|opensim]
       [--actors 1,2] [--seconds S] [--envs-per-worker K] [--fragment-length T]
       [--out bench/results/cluster]
On a 16-core machine: python bench/cluster_throughput.py --actors 1,2,4,8,15 (and again
with --backend opensim).

The cluster is started as users start one, with Ray's CLI (``service/jobs/local_cluster.py``):
a head (``ray start --head --num-cpus 0``, token auth) and max(--actors) worker nodes
(``ray start --address ... --num-cpus 1 --resources '{"node_<i>": 1}'``), each a raylet of
its own with its own object store; this process is the driver. A row of n actors is a
``WorkerPool`` of n one-CPU actors, so each lands on a worker node of its own (the table
says on how many nodes they ran). Rows are measured as ``bench/throughput.py`` measures
them (its ``measure``: start-up excluded, S seconds per row), and so is the raw row: one
``MuscleEnv`` in this process, no Ray, once before the cluster starts and once after it
stops (mean reported). Efficiency = steps/s / (actors x raw), against linear scaling.

A machine with fewer cores than actors + 1 (the driver) measures contention, not the pool:
the table's caption says so. Results: a JSON and a Markdown table in --out.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import platform
import secrets
import time
from datetime import UTC, datetime
from pathlib import Path

# Ray reads its auth mode once per process: this driver joins the token-authenticated cluster
os.environ.setdefault("RAY_AUTH_TOKEN", secrets.token_hex(32))
os.environ["RAY_AUTH_MODE"] = "token"

import mujoco
import ray
import throughput as single  # bench/throughput.py (this script's folder is on sys.path)
from gaitforge.service.jobs.local_cluster import LocalCluster
from gaitforge.workers.env import MuscleEnv
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

console = single.console
TOKEN = os.environ["RAY_AUTH_TOKEN"]


def actor_counts(text: str) -> list[int]:
    """``"1,2,4"`` -> ``[1, 2, 4]`` (sorted, distinct, each >= 1)."""
    try:
        counts = sorted({int(part) for part in text.split(",") if part.strip()})
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected counts like 1,2,4,8,15") from None
    if not counts or counts[0] < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: every count must be 1 or more")
    return counts


def pool_row(
    args: argparse.Namespace, actors: int, act_dim: int, progress: Progress
) -> tuple[float, int]:
    """Env steps/s of a pool of ``actors`` actors, and on how many nodes they ran."""
    node_ids: set[str] = set()
    rate = single.pool_rate(
        args, actors, act_dim, progress, inspect=lambda pool: node_ids.update(pool.node_ids())
    )
    return rate, len(node_ids)


def run_cluster(args: argparse.Namespace, act_dim: int, progress: Progress) -> list[dict]:
    """Start the cluster, measure every row, stop it (whatever happens)."""
    rows = []
    with LocalCluster(token=TOKEN) as cluster:
        cluster.start_head(num_cpus=0)
        for i in range(max(args.actors)):
            cluster.add_node(f"node_{i}", num_cpus=1)
        cluster.wait_for_nodes()
        ray.init(address=cluster.address, logging_level=logging.ERROR, log_to_driver=False)
        try:
            for actors in args.actors:
                rate, nodes = pool_row(args, actors, act_dim, progress)
                rows.append({"actors": actors, "nodes": nodes, "steps_per_s": rate})
        finally:
            ray.shutdown()
    return rows


HEADER = ("row", "actors", "nodes", "env steps/s", "efficiency", "vs 1 actor")


def table_rows(results: dict) -> tuple[list[tuple[str, ...]], str]:
    """The table's rows (raw, then one per actor count: efficiency against linear, and
    against n x the 1-actor row) and its caption."""
    raw, cores = results["raw_steps_per_s"], results["cores"]
    caption = (
        f"{results['seconds']:g} s per row, {results['envs_per_worker']} envs per actor, "
        f"{results['fragment_length']}-step fragments; raw = mean of "
        f"{results['raw_first']:.1f} (first) and {results['raw_last']:.1f} (last); "
        "one worker node (--num-cpus 1) per actor, a head with no CPUs; load average "
        f"{results['load_1min']['before']:.2f} before, {results['load_1min']['after']:.2f} after"
    )
    if max(r["actors"] for r in results["rows"]) + 1 > cores:
        caption += (
            f". Only {cores} cores here: the driver, Ray's daemons and the actors share "
            "them, so rows past cores - 1 actors measure contention, not the pool"
        )
    rows = [("raw, one process", "1", "-", f"{raw:.1f}", "1.00", "-")]
    one = next((r["steps_per_s"] for r in results["rows"] if r["actors"] == 1), None)
    for row in results["rows"]:
        n, rate = row["actors"], row["steps_per_s"]
        versus = f"{rate / (n * one):.2f}" if one else "-"
        rows.append(
            ("pool", str(n), str(row["nodes"]), f"{rate:.1f}", f"{rate / (n * raw):.2f}", versus)
        )
    return rows, caption


def title(results: dict) -> str:
    return f"{results['scene']} on {results['backend']}: multi-node Ray on one machine"


def render(results: dict) -> Table:
    """The table for the terminal."""
    rows, caption = table_rows(results)
    table = Table(*HEADER, title=title(results), caption=caption)
    for row in rows:
        table.add_row(*row)
    return table


def write(results: dict, out: Path) -> Path:
    """``<scene>-<backend>-<cores>cores.json`` and ``.md`` (the table) in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    stem = out / f"{results['scene']}-{results['backend']}-{results['cores']}cores"
    stem.with_suffix(".json").write_text(json.dumps(results, indent=2) + "\n")
    rows, caption = table_rows(results)
    lines = [
        f"## {title(results)}",
        "",
        "| " + " | ".join(HEADER) + " |",
        "|" + "---|" * len(HEADER),
    ]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    lines += ["", caption + f" (measured {results['measured_at']}, {results['platform']})", ""]
    stem.with_suffix(".md").write_text("\n".join(lines))
    return stem.with_suffix(".json")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="walk-2d")
    parser.add_argument("--backend", default="mujoco", choices=["mujoco", "opensim"])
    parser.add_argument(
        "--actors",
        type=actor_counts,
        default=[1, 2],
        help="actor counts, one row each (default 1,2); as many worker nodes as the largest",
    )
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--envs-per-worker", type=int, default=4)
    parser.add_argument("--fragment-length", type=int, default=256)
    parser.add_argument("--out", type=Path, default=Path("bench/results/cluster"))
    args = parser.parse_args()
    cores = os.cpu_count() or 1
    console.print(
        f"machine: {platform.machine()}, {cores} cores; python "
        f"{platform.python_version()}, ray {ray.__version__}, mujoco "
        f"{mujoco.__version__}\nplatform: {platform.platform()}"
    )
    act_dim = MuscleEnv(args.scene, args.backend).action_space.shape[0]
    load_before = os.getloadavg()[0]
    columns = (TextColumn("{task.description}"), BarColumn(), TimeElapsedColumn())
    with Progress(*columns, console=console, transient=True) as progress:
        raws = [single.raw_rate(args.scene, args.backend, args.seconds, progress)]
        rows = run_cluster(args, act_dim, progress)
        time.sleep(2.0)  # let Ray's processes exit before the last raw run
        raws.append(single.raw_rate(args.scene, args.backend, args.seconds, progress))
    results = {
        "scene": args.scene,
        "backend": args.backend,
        "cores": cores,
        "seconds": args.seconds,
        "envs_per_worker": args.envs_per_worker,
        "fragment_length": args.fragment_length,
        "raw_first": raws[0],
        "raw_last": raws[1],
        "raw_steps_per_s": sum(raws) / 2,
        "rows": rows,
        "load_1min": {"before": load_before, "after": os.getloadavg()[0]},
        "measured_at": datetime.now(UTC).isoformat(timespec="seconds"),
        "machine": platform.machine(),
        "platform": platform.platform(),
        "versions": {"ray": ray.__version__, "mujoco": mujoco.__version__},
    }
    console.print(render(results))
    console.print(f"results: {write(results, args.out)}")


if __name__ == "__main__":
    main()
