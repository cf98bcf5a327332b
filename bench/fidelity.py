"""Speed for accuracy: the fidelity sweeps and stress runs behind docs/results/
speed-for-accuracy.md (walk-2d on MuJoCo and OpenSim, walk-3d on MuJoCo; about 15 minutes on
2 cores).

Usage: python bench/fidelity.py [--out bench/results/fidelity] [--only NAME ...]

Runs, one after the other, ``gaitforge fidelity sweep`` (CSV, JSON and a Pareto PNG per scene
and backend, written to ``--out``) and ``gaitforge fidelity stress`` (the stability map and the
largest stable steps), each with ``COLUMNS=200`` and one thread, and keeps what each printed,
its command first and its wall clock last, as ``--out/<name>.txt``. The recommended profiles
are saved under ``--out/profiles`` (``GAITFORGE_PROFILES_DIR``), not in ``~/.gaitforge``. A run
that fails is reported and the others go on. The tables of the docs come from the JSON files:
``python bench/fidelity_summary.py OUT``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path


def runs(out: Path) -> dict[str, list[str]]:
    """Each run's name (its output file's stem) and its ``gaitforge`` arguments."""
    sweeps = [("walk-2d", "mujoco"), ("walk-3d", "mujoco"), ("walk-2d", "opensim")]
    stresses = [
        ("walk-3d", "mujoco", []),
        ("walk-2d", "mujoco", []),
        ("walk-2d", "opensim", ["--seconds", "0.5"]),
    ]
    todo = {
        f"sweep-{scene}-{backend}": [
            "fidelity",
            "sweep",
            scene,
            "--backend",
            backend,
            "--out",
            str(out),
        ]
        for scene, backend in sweeps
    }
    for scene, backend, more in stresses:
        todo[f"stress-{scene}-{backend}"] = [
            "fidelity",
            "stress",
            scene,
            "--backend",
            backend,
            *more,
        ]
    return todo


def gaitforge() -> str:
    """The ``gaitforge`` command of this interpreter's environment, else the one on PATH."""
    beside = Path(sys.executable).parent / "gaitforge"
    found = str(beside) if beside.exists() else shutil.which("gaitforge")
    if found is None:
        raise SystemExit("no gaitforge command: install the project (pip install -e .)")
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("bench/results/fidelity"))
    parser.add_argument("--only", nargs="+", default=None, help="run only these (names above)")
    args = parser.parse_args()
    todo = runs(args.out)
    unknown = sorted(set(args.only or []) - set(todo))
    if unknown:
        raise SystemExit(f"--only: unknown {unknown}; known: {list(todo)}")
    args.out.mkdir(parents=True, exist_ok=True)
    env = {
        **os.environ,
        "GAITFORGE_PROFILES_DIR": str(args.out / "profiles"),
        "COLUMNS": "200",
        "OMP_NUM_THREADS": "1",
    }
    command, failed = gaitforge(), []
    for name, arguments in todo.items():
        if args.only and name not in args.only:
            continue
        start = time.perf_counter()
        done = subprocess.run(
            [command, *arguments],
            env=env,
            text=True,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
        )
        wall = time.perf_counter() - start
        text = f"$ gaitforge {' '.join(arguments)}\n{done.stdout}wall {wall:.2f} s\n"
        (args.out / f"{name}.txt").write_text(text)
        status = "ok" if done.returncode == 0 else f"failed (exit {done.returncode})"
        print(f"{name}: {status}, {wall:.0f} s -> {args.out / name}.txt")
        if done.returncode != 0:
            failed.append(name)
    if failed:
        raise SystemExit(f"failed: {', '.join(failed)}")


if __name__ == "__main__":
    main()
