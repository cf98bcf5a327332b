"""CMA-ES on a reflex gait controller's parameters, one simulation per candidate on the
rollout actors.

The search runs in the unit cube: each parameter's ``[low, high]``
(``workers.scenes.reflex_parameters``) is mapped onto ``[0, 1]`` and the ``cma`` package
keeps candidates inside it, so that one ``sigma`` means the same share of every range. It
starts at the scene's parameters (``action.parameters``, the rest at their defaults). Each
generation draws fresh reset seeds shared by all its candidates (they are compared on the
same starts); each candidate is scored over ``episodes`` episodes of the scene with its
reset noise by the named measure (``workers.gait_measure``), by a scorer: a ``WorkerPool``
(whose dead or hung actors cost their candidate a re-run, not the generation) or a
``RolloutWorker`` in this process.

Its folder holds ``state.pkl`` (the optimiser, written after every generation: a stopped
search resumes from it), ``progress.csv`` (one row a generation: best, mean and sigma, and
the best candidate's parts), TensorBoard scalars under ``tb/`` (unless a job's run logs
them) and ``tuned.yaml``, the scene with the distribution's mean as its parameters (the
optimiser's estimate of the optimum: on a noisy measure, steadier than the best sample). In
a job, an ``optimize`` stage's folder is ``<run>/cmaes/stage-<i>`` (``Trainer``).
"""

from __future__ import annotations

import csv
import logging
import pickle
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import cma
import numpy as np
import yaml
from gaitforge.learner.stage_spec import StageOptimize
from gaitforge.workers.gait_measure import CandidateScorer
from gaitforge.workers.scenes import Scene
from gaitforge.workers.scenes.reflex_parameters import (
    LOWER,
    UPPER,
    parameter_values,
    parameter_vector,
)

logger = logging.getLogger(__name__)

STATE_FILE = "state.pkl"
PROGRESS_FILE = "progress.csv"
TUNED_FILE = "tuned.yaml"


@dataclass
class Generation:
    """One generation's summary."""

    generation: int
    best: float
    mean: float
    sigma: float
    best_parts: dict[str, float]
    env_steps: int
    """the search's, so far"""
    wall_s: float
    """s of wall clock the search has taken, so far"""
    steps: int
    """env steps of this generation"""

    def row(self) -> dict[str, float]:
        parts = {f"best_{k}": v for k, v in self.best_parts.items() if k != "cost"}
        return {
            "generation": self.generation,
            "best": self.best,
            "mean": self.mean,
            "sigma": self.sigma,
            **parts,
            "env_steps": self.env_steps,
            "wall_s": self.wall_s,
        }


@dataclass
class _Saved:
    """What ``state.pkl`` holds."""

    strategy: cma.CMAEvolutionStrategy
    generation: int = 0
    env_steps: int = 0
    wall_s: float = 0.0
    best_cost: float = float("inf")
    best_parameters: np.ndarray | None = None
    last: Generation | None = None
    """the latest generation's summary (``progress.csv`` holds them all)"""

    def mean_parameters(self) -> dict[str, float]:
        """The distribution's mean, by name (in the unit cube: cma's own ``mean`` lies in its
        unbounded genotype space, which its bounds fold onto the cube)."""
        return parameter_values(from_unit(np.asarray(self.strategy.result.xfavorite)))


def _read_state(folder: Path) -> _Saved | None:
    """The search saved in ``folder``, None if it holds none."""
    path = folder / STATE_FILE
    if not path.exists():
        return None
    with path.open("rb") as f:
        return pickle.load(f)  # written by CmaesTuning into the run's own directory


def to_unit(parameters: np.ndarray) -> np.ndarray:
    """Parameters [n] -> the unit cube [n]."""
    return (parameters - LOWER) / (UPPER - LOWER)


def from_unit(x: np.ndarray) -> np.ndarray:
    """The unit cube [n] -> parameters [n] (clipped to the bounds)."""
    return LOWER + np.clip(x, 0.0, 1.0) * (UPPER - LOWER)


class CmaesTuning:
    """Tunes ``scene``'s reflex gait controller into ``out_dir`` (see the module docstring).

    Args:
        scene: a resolved scene with ``action.kind: reflex_gait``.
        settings: the search's settings (a job stage's ``optimize``).
        out_dir: the search's folder; an existing state there is resumed.
        scorer: what scores the candidates (its envs must be of ``scene``).
        tensorboard: write TensorBoard scalars.
        seed: the search's seed and the episodes' reset seeds' base.
        stop: set to stop scoring: the generation being scored is dropped and the state
            stays as it was (a trainer shares its own).
        written: the scene ``tuned.yaml`` sets the parameters in; default ``scene``. A
            scene as loaded for every backend it runs on, its fidelity not resolved, gives
            a ``tuned.yaml`` that runs on each of them (``scene`` is resolved for one).
    """

    def __init__(
        self,
        scene: Scene,
        settings: StageOptimize,
        out_dir: Path,
        scorer: CandidateScorer,
        tensorboard: bool = True,
        seed: int = 0,
        stop: threading.Event | None = None,
        written: Scene | None = None,
    ) -> None:
        if not scene.action.gait:
            raise ValueError(f"scene {scene.name!r}: action.kind is not reflex_gait")
        self.scene = scene
        self._written = written or scene
        self.settings = settings
        self.seed = seed
        self.dir = out_dir
        self.dir.mkdir(parents=True, exist_ok=True)
        self.scorer = scorer
        self._stop = stop or threading.Event()
        self._writer = None
        if tensorboard:
            from torch.utils.tensorboard import SummaryWriter  # lazy: imports tensorboard

            self._writer = SummaryWriter(str(out_dir / "tb"))
        self.saved = self._load() or self._start()

    def _start(self) -> _Saved:
        x0 = to_unit(parameter_vector(self.scene.action.parameters))
        options = {
            "popsize": self.settings.population,
            "bounds": [0.0, 1.0],
            "seed": self.seed + 1,  # cma reads 0 as "from the clock"
            "verbose": -9,
        }
        return _Saved(strategy=cma.CMAEvolutionStrategy(x0, self.settings.sigma, options))

    def _load(self) -> _Saved | None:
        saved = _read_state(self.dir)
        if saved is not None:
            logger.info("cmaes: resuming at generation %d", saved.generation)
        return saved

    @property
    def done(self) -> bool:
        return self.saved.generation >= self.settings.generations

    def run(self) -> list[Generation]:
        """Generations until ``generations`` are done, ``minutes`` have passed (counting
        the time before a resume) or a stop is requested; returns those run now."""
        ran: list[Generation] = []
        while not self.done and not self._stop.is_set():
            minutes = self.settings.minutes
            if minutes is not None and self.saved.wall_s >= 60.0 * minutes:
                break
            generation = self.step()
            if generation is None:
                break
            ran.append(generation)
        self.write_tuned()
        if self._writer is not None:
            self._writer.flush()
        return ran

    def step(self) -> Generation | None:
        """One generation: ask, score, tell, save. None if stopped while scoring."""
        from gaitforge.workers.fragment import StopRequested

        saved, start = self.saved, time.perf_counter()
        strategy = saved.strategy
        candidates = [np.asarray(x) for x in strategy.ask()]
        parameters = [from_unit(x) for x in candidates]
        seeds = [
            self.seed * 1_000_003 + saved.generation * self.settings.episodes + i
            for i in range(self.settings.episodes)
        ]
        try:
            scores = self.scorer.score_candidates(
                parameters, seeds, self.settings.measure, stop=self._stop
            )
        except StopRequested:
            return None
        costs = [s.cost for s in scores]
        strategy.tell(candidates, costs)
        best = int(np.argmin(costs))
        if costs[best] < saved.best_cost:
            saved.best_cost, saved.best_parameters = costs[best], parameters[best]
        saved.generation += 1
        steps = sum(s.env_steps for s in scores)
        saved.env_steps += steps
        saved.wall_s += time.perf_counter() - start
        generation = Generation(
            generation=saved.generation,
            best=costs[best],
            mean=float(np.mean(costs)),
            sigma=float(strategy.sigma),
            best_parts=scores[best].as_dict(),
            env_steps=saved.env_steps,
            wall_s=saved.wall_s,
            steps=steps,
        )
        saved.last = generation
        self._save(generation)
        logger.info(
            "cmaes generation %d: best %.3f mean %.3f sigma %.3f (alive %.2f, %.2f m/s)",
            generation.generation,
            generation.best,
            generation.mean,
            generation.sigma,
            scores[best].alive,
            scores[best].speed,
        )
        return generation

    def _save(self, generation: Generation) -> None:
        path = self.dir / STATE_FILE
        partial = path.with_suffix(".partial")
        with partial.open("wb") as f:
            pickle.dump(self.saved, f)
        partial.replace(path)  # a kill mid-write leaves the previous state
        progress = self.dir / PROGRESS_FILE
        row = generation.row()
        new = not progress.exists()
        with progress.open("a", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(row))
            if new:
                writer.writeheader()
            writer.writerow(row)
        if self._writer is not None:
            step = generation.env_steps
            for key in ("best", "mean", "sigma"):
                self._writer.add_scalar(f"cmaes/{key}", row[key], step)
            for key, value in generation.best_parts.items():
                self._writer.add_scalar(f"cmaes/best_{key}", value, step)

    def tuned_parameters(self) -> dict[str, float]:
        """The distribution's mean, by name (the tuned controller)."""
        return self.saved.mean_parameters()

    def write_tuned(self) -> Path:
        """``tuned.yaml``: the ``written`` scene with the tuned parameters, as a scene file."""
        tuned = with_parameters(self._written, self.tuned_parameters())
        data = tuned.model_dump(mode="json", exclude_defaults=True)
        path = self.dir / TUNED_FILE
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        return path


def saved_parameters(folder: Path) -> dict[str, float] | None:
    """The tuned parameters (the distribution's mean) of the search saved in ``folder``;
    None if it holds none."""
    saved = _read_state(folder)
    return None if saved is None else saved.mean_parameters()


def with_parameters(scene: Scene, parameters: dict[str, float]) -> Scene:
    """``scene`` with its reflex gait controller's ``parameters`` (all of them, by name)."""
    action = scene.action.model_copy(update={"parameters": dict(parameters)})
    return scene.model_copy(update={"action": action})


def carries(tuned: Scene, scene: Scene) -> bool:
    """Whether a controller tuned on ``tuned`` goes on to ``scene``: the same controller
    (``reflex_gait``) on the same body and wiring."""
    return (
        scene.action.gait
        and scene.body == tuned.body
        and scene.action.wiring == tuned.action.wiring
    )
