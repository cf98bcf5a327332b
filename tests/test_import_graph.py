"""The package reads in one direction: its imports, read from the source with ``ast``.

Nothing is imported or run to build the graph. Every ``.py`` under ``workers/``,
``learner/`` and ``service/`` is a module ``gaitforge.<folder>.<...>`` (``__init__.py`` is
its package), but for ``service/top/``, which is the package ``gaitforge`` itself. Every
import of a gaitforge module counts: at the top of a file, inside a function, under ``if
TYPE_CHECKING:``, in a ``try``. Relative imports are resolved.
``from gaitforge.x import y`` where ``y`` is a module counts as importing ``gaitforge.x.y``,
otherwise as importing ``gaitforge.x`` (its ``__init__``). The package ``__init__`` files
that importing a submodule runs implicitly are not edges: a package that re-exports its own
submodules would otherwise read as a cycle with each of them.

Rules (each failure names the file, the line and the import):

1. **No cycle** among modules (the cycle's path is printed).
2. **Packages one way**: ``gaitforge`` (its top: the Python face) -> ``service`` ->
   ``learner`` -> ``workers``. ``workers`` imports neither of the others, ``learner`` does
   not import ``service``, and none imports the top.
3. **Layers inside workers**, by rank. A module may import a module of lower rank, or of
   the same rank in the same package (a sub-package of workers with the folders below it,
   or the modules directly in ``workers/``); never one of higher rank, nor a same-rank
   module of another package:

   ===  ==========  =================================================================
   0    base        ``gaitforge.workers`` itself, ``spec_io``, ``policy_api``, and any
                    other module directly in ``workers/`` that imports no gaitforge
                    module (plain data, e.g. the fragment dataclass)
   1    bodies      ``workers/bodies/``: neutral bodies and body topology, as data
   1.5  motions     ``workers/motions/``: reference motions (gait cycles), as data
   2    scenes      ``workers/scenes/``: the spec, catalogue, pruning, fidelity profiles
                    and the saved profiles a scene names
   3    sim         ``workers/sim/``: the simulator protocol and backend-neutral modules;
                    the backends in its sub-packages ``mujoco/`` and ``opensim/``
   4    env         ``workers/rewards.py``, ``workers/env.py``
   5    env users   ``workers/probe.py``, the episode loop, ``workers/fidelity/``
   6    actors      ``workers/rollout.py``, ``workers/pool.py``
   ===  ==========  =================================================================

   A new module directly in ``workers/`` that imports gaitforge modules must be given a
   rank in ``TOP_LEVEL_RANKS``; a new sub-package in ``PACKAGE_RANKS``. Inside sim, the
   backend-neutral modules directly in ``workers/sim/`` import no backend (``SIM_BACKENDS``),
   but for its package file, whose ``make_simulator`` picks one.
4. **Evaluation apart in learner**: ``learner/evaluation/`` (evaluations, recordings,
   videos, shipping, stage judging) may import the rest of the learner but not the trainer;
   the rest of the learner imports none of it, but for the trainer, which imports only its
   hooks (``EVALUATION_ENTRIES``): the training loop reaches evaluations, recordings and
   videos through hooks alone. The modules that record or render (``EVALUATION_ONLY``) are
   in the package.

Also checked: every folder with an ``__init__.py`` is a package listed in pyproject's
``[tool.setuptools] packages``; every ``package-data`` glob matches files and every data
file in a package is shipped by one; in the installed venv, ``import workers`` (and
``learner``, ``service``) fails while ``import gaitforge.workers`` works.
"""

from __future__ import annotations

import ast
import itertools
import shutil
import subprocess
import sys
import textwrap
import tomllib
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("workers", "learner", "service")
TOP_FOLDER = ("service", "top")
"""The folder of the package ``gaitforge`` itself (its modules are ``gaitforge.<name>``)."""
PACKAGE_ORDER = {"workers": 0, "learner": 1, "service": 2, "top": 3}
"""Top packages: a higher one may import a lower one, never the reverse."""

PACKAGE_RANKS = {"bodies": 1, "motions": 1.5, "scenes": 2, "sim": 3, "fidelity": 5}
"""Sub-packages of workers and their rank (every module inside has it, sub-packages too)."""
SIM = "gaitforge.workers.sim"
SIM_BACKENDS = ("mujoco", "opensim")
"""The sub-packages of ``workers/sim/``: the backends (MuJoCo, OpenSim). The modules directly
in ``workers/sim/`` are backend-neutral."""
TOP_LEVEL_RANKS = {
    "spec_io": 0,
    "overrides": 0,
    "policy_api": 0,
    "rewards": 4,
    "gait_clock": 4,
    "imitation": 4,
    "reflex": 4,
    "gait_reflex": 4,
    "env": 4,
    "probe": 5,
    "gait_measure": 5,
    "episode": 5,
    "rollout": 6,
    "pool": 6,
}
"""Modules directly in workers/ and their rank; one not listed that imports no gaitforge
module is base (0)."""

EVALUATION = "gaitforge.learner.evaluation"
"""The learner's sub-package for running policies outside training."""
RUNNER = "gaitforge.learner.trainer"
"""The training loop: evaluation modules may not import it."""
EVALUATION_ENTRIES = {RUNNER: {f"{EVALUATION}.training_hooks"}}
"""Learner modules outside the evaluation package that may import it, and what."""
EVALUATION_ONLY = ("evaluate", "recording", "video", "ship", "stage_judge", "training_hooks")
"""Modules that must be in the evaluation package."""


@dataclass(frozen=True)
class Edge:
    """``source`` imports ``target`` at ``path:line``."""

    source: str
    target: str
    path: Path
    line: int

    def where(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


def _modules() -> dict[str, Path]:
    """Module name -> file, for every .py under the three folders."""
    out: dict[str, Path] = {}
    for folder in FOLDERS:
        for path in sorted((ROOT / folder).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if tuple(parts[:2]) == TOP_FOLDER:
                parts = parts[2:]
            if parts[-1:] == ["__init__"]:
                parts = parts[:-1]
            out[".".join(["gaitforge", *parts])] = path
    return out


def _is_package(module: str, modules: dict[str, Path]) -> bool:
    return modules[module].name == "__init__.py"


def _targets(
    node: ast.Import | ast.ImportFrom, source: str, modules: dict[str, Path]
) -> Iterator[str]:
    """The gaitforge modules one import statement imports."""
    if isinstance(node, ast.Import):
        for alias in node.names:
            yield from _known(alias.name, modules)
        return
    if node.level:
        package = source if _is_package(source, modules) else source.rpartition(".")[0]
        for _ in range(node.level - 1):
            package = package.rpartition(".")[0]
        base = f"{package}.{node.module}" if node.module else package
    else:
        base = node.module or ""
    if not base.startswith("gaitforge"):
        return
    for alias in node.names:
        sub = f"{base}.{alias.name}"
        if sub in modules:
            yield sub
        else:
            yield from _known(base, modules)


def _known(name: str, modules: dict[str, Path]) -> Iterator[str]:
    """``name`` if it is one of ours; fails on a gaitforge name that is no module here."""
    if not name.startswith("gaitforge.") and name != "gaitforge":
        return
    if name not in modules:
        pytest.fail(f"import of {name!r}: no such module under {', '.join(FOLDERS)}/")
    yield name


def _edges() -> list[Edge]:
    modules = _modules()
    edges: list[Edge] = []
    for source, path in modules.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import | ast.ImportFrom):
                for target in _targets(node, source, modules):
                    if target != source:
                        edges.append(Edge(source, target, path, node.lineno))
    return edges


def _top(module: str) -> str:
    """The package ``module`` is in: one of ``FOLDERS``, or ``top`` (``gaitforge`` itself)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[1] in FOLDERS else "top"


def _layer_package(module: str) -> str:
    """The package of a workers module for the layers: its sub-package of workers (with
    everything below it), or ``gaitforge.workers`` for the modules directly in it."""
    parts = module.split(".")
    if len(parts) > 2 and parts[2] in PACKAGE_RANKS:
        return ".".join(parts[:3])
    return ".".join(parts[:2])


def _rank(module: str, imports_gaitforge: bool) -> int | None:
    """Rank of a workers module (see the module docstring); None if it has no place."""
    parts = module.split(".")[2:]
    if not parts:
        return 0
    if parts[0] in PACKAGE_RANKS:
        return PACKAGE_RANKS[parts[0]]
    if len(parts) == 1:
        if parts[0] in TOP_LEVEL_RANKS:
            return TOP_LEVEL_RANKS[parts[0]]
        return None if imports_gaitforge else 0
    return None


def _find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle as a path ``[a, b, ..., a]``, or None (iterative depth-first search)."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    for start in sorted(graph):
        if state.get(start):
            continue
        path = [start]
        stack = [iter(sorted(graph[start]))]
        state[start] = 1
        while stack:
            nxt = next(stack[-1], None)
            if nxt is None:
                state[path.pop()] = 2
                stack.pop()
            elif state.get(nxt) == 1:
                return [*path[path.index(nxt) :], nxt]
            elif not state.get(nxt):
                state[nxt] = 1
                path.append(nxt)
                stack.append(iter(sorted(graph.get(nxt, ()))))
    return None


def test_no_cycles() -> None:
    edges = _edges()
    graph: dict[str, set[str]] = {m: set() for m in _modules()}
    for e in edges:
        graph[e.source].add(e.target)
    cycles = []
    while (cycle := _find_cycle(graph)) is not None:
        lines = []
        for a, b in itertools.pairwise(cycle):
            where = next(e.where() for e in edges if e.source == a and e.target == b)
            lines.append(f"  {a} -> {b}  ({where})")
        cycles.append("\n".join(lines))
        graph[cycle[0]].discard(cycle[1])  # break it and look for the next one
    assert not cycles, "import cycles:\n" + "\n\n".join(cycles)


def test_packages_one_way() -> None:
    wrong = [
        f"{e.where()}: {e.source} imports {e.target} ({_top(e.source)} may not import "
        f"{_top(e.target)}: service -> learner -> workers)"
        for e in _edges()
        if PACKAGE_ORDER[_top(e.target)] > PACKAGE_ORDER[_top(e.source)]
    ]
    assert not wrong, "imports against the package direction:\n" + "\n".join(wrong)


def test_workers_layers() -> None:
    modules = _modules()
    edges = [e for e in _edges() if _top(e.source) == _top(e.target) == "workers"]
    importing = {e.source for e in edges}
    ranks = {m: _rank(m, m in importing) for m in modules if _top(m) == "workers"}
    unplaced = [m for m, r in ranks.items() if r is None]
    assert not unplaced, (
        f"workers modules without a layer: {unplaced}; give each a rank in "
        "TOP_LEVEL_RANKS or PACKAGE_RANKS (tests/test_import_graph.py)"
    )
    wrong = []
    for e in edges:
        src, dst = ranks[e.source], ranks[e.target]
        assert src is not None and dst is not None
        same_package = _layer_package(e.source) == _layer_package(e.target)
        if dst > src or (dst == src and not same_package):
            wrong.append(f"{e.where()}: {e.source} (rank {src}) imports {e.target} (rank {dst})")
    assert not wrong, (
        "imports against the workers layers (rank 0 base < 1 bodies < 1.5 motions < 2 scenes < "
        "3 sim < 4 env < 5 probe/episode/fidelity < 6 rollout/pool):\n" + "\n".join(wrong)
    )


def test_sim_neutral_modules_import_no_backend() -> None:
    modules = _modules()
    found = {
        m.removeprefix(SIM + ".")
        for m, path in modules.items()
        if m.rpartition(".")[0] == SIM and path.name == "__init__.py"
    }
    assert found == set(SIM_BACKENDS), (
        f"sub-packages of workers/sim/: {sorted(found)}; SIM_BACKENDS lists "
        f"{sorted(SIM_BACKENDS)} (tests/test_import_graph.py)"
    )
    backends = tuple(f"{SIM}.{name}" for name in SIM_BACKENDS)

    def in_backend(module: str) -> bool:
        return any(module == b or module.startswith(b + ".") for b in backends)

    wrong = [
        f"{e.where()}: {e.source} imports {e.target}"
        for e in _edges()
        if e.source.rpartition(".")[0] == SIM and not in_backend(e.source) and in_backend(e.target)
    ]
    assert not wrong, (
        "backend-neutral modules of workers/sim/ importing a backend (only the package file's "
        "make_simulator may):\n" + "\n".join(wrong)
    )


def _in_evaluation(module: str) -> bool:
    return module == EVALUATION or module.startswith(EVALUATION + ".")


def test_evaluation_apart_in_learner() -> None:
    modules = _modules()
    placed = [f"{EVALUATION}.{name}" for name in EVALUATION_ONLY]
    assert all(m in modules for m in placed), (
        f"missing from learner/evaluation/: {[m for m in placed if m not in modules]}"
    )
    wrong = []
    for e in _edges():
        if _top(e.source) != "learner" or _top(e.target) != "learner":
            continue
        if _in_evaluation(e.source) and e.target == RUNNER:
            wrong.append(f"{e.where()}: {e.source} imports the trainer {e.target}")
        entries = EVALUATION_ENTRIES.get(e.source, set())
        if not _in_evaluation(e.source) and _in_evaluation(e.target) and e.target not in entries:
            wrong.append(f"{e.where()}: {e.source} imports {e.target}")
    assert not wrong, (
        "imports against the evaluation package's place (it may import the learner but the "
        "trainer; of the learner only the trainer imports it, its training_hooks only):\n"
        + "\n".join(wrong)
    )


def test_graph_sees_every_kind_of_import(tmp_path: Path) -> None:
    """The reader finds imports in functions, under TYPE_CHECKING, relative and submodule."""
    modules = _modules()
    source = textwrap.dedent(
        """
        from typing import TYPE_CHECKING
        from . import env
        from .scenes import spec
        if TYPE_CHECKING:
            from gaitforge.workers.sim.base import Health
        def f():
            import gaitforge.workers.bodies
            from ..learner import ppo
        """
    )
    found: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import | ast.ImportFrom):
            found.update(_targets(node, "gaitforge.workers.rollout", modules))
    assert found == {
        "gaitforge.workers.env",
        "gaitforge.workers.scenes.spec",
        "gaitforge.workers.sim.base",
        "gaitforge.workers.bodies",
        "gaitforge.learner.ppo",
    }
    assert _find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]


# ---- packaging ---------------------------------------------------------------------------


def test_every_package_is_listed() -> None:
    listed = set(_setuptools()["packages"])
    found = {m for m, p in _modules().items() if p.name == "__init__.py"}
    assert found - listed == set(), (
        f"folders with an __init__.py missing from pyproject's [tool.setuptools] packages: "
        f"{sorted(found - listed)}"
    )
    assert listed - found == set(), f"listed packages with no folder: {sorted(listed - found)}"


def _setuptools() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]


def _folder(package: str) -> Path:
    """The source folder of ``package`` (through ``package-dir``)."""
    top = ".".join(package.split(".")[:2])
    return ROOT / _setuptools()["package-dir"][top] / Path(*package.split(".")[2:])


def _source_files() -> list[Path]:
    """Files of the three folders (tracked ones where git is at hand: no stray outputs)."""
    try:
        listed = subprocess.run(
            ["git", "ls-files", "-z", *FOLDERS], cwd=ROOT, capture_output=True, check=True
        ).stdout.decode()
        files = [ROOT / f for f in listed.split("\0") if f]
    except (OSError, subprocess.CalledProcessError):
        files = [p for folder in FOLDERS for p in (ROOT / folder).rglob("*") if p.is_file()]
    return [p for p in files if p.exists() and "__pycache__" not in p.parts]


def _data_files() -> set[Path]:
    """Non-Python files inside a listed package's folder (sub-packages own theirs)."""
    packages = {_folder(package) for package in _setuptools()["packages"]}
    return {
        p
        for p in _source_files()
        if p.suffix != ".py" and any(parent in packages for parent in p.parents)
    }


def test_package_data_globs_match() -> None:
    """Every ``package-data`` glob matches a file, and every data file matches a glob."""
    shipped: set[Path] = set()
    for package, globs in _setuptools().get("package-data", {}).items():
        for pattern in globs:
            matched = {p for p in _folder(package).glob(pattern) if p.is_file()}
            assert matched, f"package-data {package}: {pattern!r} matches no file"
            shipped |= matched
    missing = sorted(str(p.relative_to(ROOT)) for p in _data_files() - shipped)
    assert not missing, f"data files no package-data glob ships: {missing}"


def test_wheel_holds_every_module_and_data_file(tmp_path: Path) -> None:
    """A wheel built from the source (about 2 s) holds every module and data file under
    ``gaitforge/``, and nothing at the generic top-level names."""
    src = tmp_path / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md", *FOLDERS):
        path = ROOT / name
        if path.is_dir():
            shutil.copytree(path, src / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy(path, src / name)
    build = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            str(tmp_path / "dist"),
            str(src),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert build.returncode == 0, build.stdout + build.stderr
    (wheel,) = (tmp_path / "dist").glob("*.whl")
    with zipfile.ZipFile(wheel) as zf:
        names = {n for n in zf.namelist() if ".dist-info/" not in n}
    expected = {f"gaitforge/{p.relative_to(ROOT)}" for p in _data_files()} | {
        module.replace(".", "/") + ("/__init__.py" if path.name == "__init__.py" else ".py")
        for module, path in _modules().items()
    }
    assert expected - names == set(), f"missing from the wheel: {sorted(expected - names)}"
    outside = sorted(n for n in names if not n.startswith("gaitforge/"))
    assert not outside, f"the wheel installs outside gaitforge/: {outside}"


def test_only_the_namespace_imports(tmp_path: Path) -> None:
    """From a directory that holds no gaitforge source, the generic names are not there."""
    code = (
        "import importlib\n"
        "for name in ('workers', 'learner', 'service'):\n"
        "    try:\n"
        "        importlib.import_module(name)\n"
        "    except ModuleNotFoundError:\n"
        "        continue\n"
        "    raise SystemExit(f'import {name} works')\n"
        "import gaitforge.workers, gaitforge.learner, gaitforge.service\n"
    )
    run = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=60
    )
    assert run.returncode == 0, run.stdout + run.stderr
