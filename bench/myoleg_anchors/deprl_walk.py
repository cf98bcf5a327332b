"""Anchor 2: DEP-RL's published myoLegWalk configuration for a fixed training time.

    python bench/myoleg_anchors/deprl_walk.py --minutes M --seed S --out DIR [--resume]
        [--parallel P] [--sequential Q] [--eval-episodes 10]

Runs deprl 0.5.0 (DEP exploration switched stochastically with MPO, as in the paper) with
``myoLegWalk.deprl.yaml`` beside this file, the configuration deprl's authors published, on
MyoSuite 3 through ``adapters.py``. The file is read as is; these overrides are applied and
recorded in ``DIR/run.json`` and in the run's ``config.yaml``:

- ``tonic.seed``: ``--seed``.
- ``tonic.parallel`` x ``tonic.sequential``: worker processes x envs per process. Published:
  20 x 10; default here: one process per core x 10 (``--parallel 20`` restores it: about
  40 MB per env and 0.4 GB per process of memory).
- ``tonic.header``: ``; import adapters; adapters.install()`` appended, so each worker
  process installs the adapters before it builds envs.
- ``working_dir``/``tonic.name``: the run lives in ``DIR/deprl/<date.time>/`` (deprl's layout).
- ``tonic.resume``: ``--resume``.
- The trainer keeps the published ``steps``, ``epoch_steps``, ``save_steps`` but also stops
  when the run's training seconds reach ``--minutes`` and checkpoints every 10 min of
  training (``full_save``: weights, optimisers, replay buffer, normalisers).

Training seconds sum over ``--resume`` restarts; checkpoint writes and start-up are left out.
``DIR/progress.csv`` every 30 s; at the end ``evaluate.py``'s JSON in ``DIR/eval.json`` and
its table on stdout. deprl's own log (``log.csv``, one row per 2e5-step epoch with its 10 test
episodes) is in the experiment folder.
"""

from __future__ import annotations

import argparse
import copy
import logging
import os
import sys
from pathlib import Path
from typing import Any

import adapters
import numpy as np
import torch
import yaml
from common import (
    CHECKPOINT_INTERVAL_S,
    ENV_ID,
    PROGRESS_FILE,
    STATE_FILE,
    ProgressLog,
    TrainClock,
    machine_cores,
    package_versions,
    prepare_run_dir,
    run_arguments,
    setup_logging,
    write_json,
)
from evaluate import evaluate_run, format_table

adapters.install()
from deprl import custom_distributed  # noqa: E402  (after the adapters)
from deprl.custom_trainer import Trainer  # noqa: E402
from deprl.utils import load_checkpoint  # noqa: E402
from deprl.vendor.tonic import logger as tonic_logger  # noqa: E402

log = logging.getLogger("deprl_walk")

CONFIG_FILE = Path(__file__).resolve().with_name("myoLegWalk.deprl.yaml")
HEADER_SUFFIX = "; import adapters; adapters.install()"
EXPERIMENT_NAME = "deprl"


class _TrackedEnvironment:
    """Proxy for deprl's training ``Parallel``/``Sequential`` that feeds the progress CSV.

    Args:
        environment: deprl's distributed training environment.
        trainer: the trainer (for the clock, the progress log and the step count).
    """

    def __init__(self, environment: Any, trainer: WallClockTrainer) -> None:
        self.__dict__.update(_env=environment, _trainer=trainer)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.__dict__["_env"], name)

    def start(self) -> tuple[np.ndarray, np.ndarray]:
        """Start the envs; returns observations and DEP inputs (muscle states)."""
        observations, muscle_states = self._env.start()
        n = len(observations)
        self.__dict__.update(_returns=np.zeros(n), _lengths=np.zeros(n, int), _steps=0)
        return observations, muscle_states

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
        """Step all envs; records the episodes that ended."""
        observations, muscle_states, infos = self._env.step(actions)
        self._returns += infos["rewards"]
        self._lengths += 1
        self.__dict__["_steps"] += len(actions)
        progress = self._trainer.progress
        for i in np.flatnonzero(infos["resets"]):
            progress.episode(float(self._returns[i]), int(self._lengths[i]))
            self._returns[i] = 0.0
            self._lengths[i] = 0
        progress.maybe_write(self._trainer.clock.elapsed(), self._trainer.base_steps + self._steps)
        return observations, muscle_states, infos


class WallClockTrainer(Trainer):
    """deprl's ``Trainer`` that also stops at a training-time budget and checkpoints by time.

    deprl's loop stops when ``steps >= max_steps`` and saves when ``steps_since_save >=
    save_steps``; both are read each step, so they are properties here: ``max_steps`` is 0 once
    the budget is spent (the loop then saves a checkpoint and returns) and ``save_steps`` is 1
    when a checkpoint is due by time. The loop itself is deprl's, unchanged.

    Args:
        clock: the run's training clock.
        progress: the progress CSV.
        out: the run folder (``state.json`` is written there after each checkpoint).
        checkpoint_interval_s: training seconds between checkpoints, s.
        **published: the published ``Trainer`` arguments (steps, epoch_steps, save_steps...).
    """

    def __init__(
        self,
        clock: TrainClock,
        progress: ProgressLog,
        out: Path,
        checkpoint_interval_s: float = CHECKPOINT_INTERVAL_S,
        **published: Any,
    ) -> None:
        self.clock = clock
        self.progress = progress
        self.out = out
        self.checkpoint_interval_s = checkpoint_interval_s
        self.last_checkpoint_s = clock.elapsed()
        self.base_steps = 0
        super().__init__(**published)

    @property
    def max_steps(self) -> int:
        """Published step cap, or 0 once the training-time budget is spent."""
        return 0 if self.clock.expired() else self._max_steps

    @max_steps.setter
    def max_steps(self, value: int) -> None:
        self._max_steps = int(value)

    @property
    def save_steps(self) -> int:
        """Published save interval (steps), or 1 when a checkpoint is due by time."""
        due = self.clock.elapsed() - self.last_checkpoint_s >= self.checkpoint_interval_s
        return 1 if due else self._save_steps

    @save_steps.setter
    def save_steps(self, value: int) -> None:
        self._save_steps = int(value)

    def initialize(
        self,
        agent: Any,
        environment: Any,
        test_environment: Any = None,
        full_save: bool = False,
    ) -> None:
        """As deprl's, with the envs proxied and checkpoint writes left out of the clock."""
        if test_environment is not None:
            test_environment = adapters.TestEnvironment(test_environment)
        super().initialize(
            agent, _TrackedEnvironment(environment, self), test_environment, full_save
        )
        save = agent.save

        def timed_save(path: str, full_save: bool = True) -> None:
            # deprl's logger.save reads layout attributes that exist only after its first
            # epoch dump (2e5 steps); a time-based checkpoint can come earlier.
            current = tonic_logger.get_current_logger()
            for name in ("console_formats", "final_keys"):
                if not hasattr(current, name):
                    setattr(current, name, [])
            with self.clock.paused():
                save(path, full_save=full_save)

        agent.save = timed_save

    def run(
        self, params: dict[str, Any], steps: int = 0, epochs: int = 0, episodes: int = 0
    ) -> Any:
        """deprl's loop from ``steps``; the process's training clock starts here."""
        self.base_steps = int(steps)
        self.clock.start()
        self.last_checkpoint_s = self.clock.elapsed()
        return super().run(params, steps=steps, epochs=epochs, episodes=episodes)

    def save_time(self, path: str, epochs: int, episodes: int) -> None:
        """deprl's step counters, then ``state.json`` (the last thing a checkpoint writes)."""
        super().save_time(path, epochs, episodes)
        experiment = Path(path).parent.parent
        state = {
            "checkpoint": os.path.relpath(path, self.out),
            "experiment_dir": os.path.relpath(experiment, self.out),
            "env_steps": int(self.steps),
            "epochs": int(epochs),
            "episodes": int(episodes),
            "train_seconds": self.clock.elapsed(),
        }
        write_json(self.out / STATE_FILE, state)
        self.last_checkpoint_s = self.clock.elapsed()
        log.info("checkpoint %s at %.0f s of training", state["checkpoint"], state["train_seconds"])

    def close_mp_envs(self) -> None:
        """deprl's, which assumes worker processes; a one-process run has none."""
        if hasattr(self.environment, "processes"):
            super().close_mp_envs()


def build_config(args: argparse.Namespace) -> tuple[dict[str, Any], dict[str, Any]]:
    """The published config with this run's overrides, and the overrides alone."""
    published = yaml.safe_load(CONFIG_FILE.read_text())
    config = copy.deepcopy(published)
    tonic = config["tonic"]
    overrides = {
        "tonic.seed": args.seed,
        "tonic.parallel": args.parallel,
        "tonic.sequential": args.sequential,
        "tonic.header": published["tonic"]["header"] + HEADER_SUFFIX,
        "tonic.name": EXPERIMENT_NAME,
        "tonic.resume": int(args.resume),
        "working_dir": str(args.out.resolve()),
        "trainer": f"also stops after {args.minutes} min of training, checkpoints every "
        f"{args.checkpoint_minutes:g} min (WallClockTrainer)",
    }
    tonic.update(
        seed=args.seed,
        parallel=args.parallel,
        sequential=args.sequential,
        header=overrides["tonic.header"],
        name=EXPERIMENT_NAME,
        resume=int(args.resume),
    )
    config["working_dir"] = overrides["working_dir"]
    config["anchor_overrides"] = overrides
    return config, overrides


def published_trainer_kwargs(trainer: str) -> dict[str, Any]:
    """The published ``Trainer(...)`` string's arguments, read from the instance it builds."""
    import deprl

    built = eval(trainer, {"deprl": deprl})  # the config's own trainer string
    return {
        "steps": built.max_steps,
        "epoch_steps": built.epoch_steps,
        "save_steps": built.save_steps,
        "test_episodes": built.test_episodes,
        "show_progress": built.show_progress,
        "replace_checkpoint": built.replace_checkpoint,
    }


def resume_agent(agent: Any, checkpoint: str) -> None:
    """deprl's full load, then a strict weight load (deprl's own swallows a mismatch)."""
    agent.load(checkpoint)
    weights = torch.load(checkpoint + ".pt", map_location="cpu", weights_only=True)
    agent.model.load_state_dict(weights)
    size = agent.replay.size if agent.replay.buffers is not None else 0
    log.info("resumed %s; replay holds %d steps per env", checkpoint, size)


def train(args: argparse.Namespace) -> None:
    """Train (or resume) for the budget, checkpoint, then evaluate."""
    out: Path = args.out
    if "step" in str(out.resolve()):
        # deprl finds a checkpoint's side files with path.split("step")[0].
        raise SystemExit(f"--out {out}: deprl cannot handle 'step' in the path")
    config, overrides = build_config(args)
    run_info = {
        "runner": "deprl",
        "env_id": ENV_ID,
        "seed": args.seed,
        "config_file": CONFIG_FILE.name,
        "overrides": overrides,
        "action_map": "MyoSuite 2 sigmoid: activation = 1 / (1 + exp(-5 (a - 0.5))), a in [-1, 1]",
        "versions": package_versions("deprl", "myosuite", "torch", "gymnasium", "numpy"),
        "argv": sys.argv,
    }
    state = prepare_run_dir(out, args.resume, run_info)
    clock = TrainClock(args.minutes * 60.0, state.get("train_seconds", 0.0))
    if clock.expired():
        log.info("budget already spent (%.0f s); evaluating", clock.elapsed())
    else:
        torch.set_default_device("cpu")
        tonic = config["tonic"]
        namespace: dict[str, Any] = {}
        exec(tonic["header"], namespace)  # the config's header, as deprl runs it
        environment = custom_distributed.distribute(
            environment=tonic["environment"], tonic_conf=tonic, env_args=config["env_args"]
        )
        environment.initialize(seed=tonic["seed"])
        test_environment = custom_distributed.distribute(
            environment=tonic["environment"],
            tonic_conf=tonic,
            env_args=config["env_args"],
            parallel=1,
            sequential=1,
        )
        test_environment.initialize(seed=tonic["seed"] + 1000000)
        agent = eval(tonic["agent"], namespace)
        agent.set_params(**config["mpo_args"])
        agent.initialize(
            observation_space=environment.observation_space,
            action_space=environment.action_space,
            seed=tonic["seed"],
        )
        agent.expl.set_params(config["DEP"])
        tonic_logger.initialize(
            script_path=None, config=config, test_env=test_environment, resume=tonic["resume"]
        )
        time_dict = {"steps": 0, "epochs": 0, "episodes": 0}
        if state.get("checkpoint"):
            experiment = Path(tonic_logger.get_path()).resolve()
            if experiment != (out / state["experiment_dir"]).resolve():
                raise SystemExit(f"deprl resumed {experiment}, state.json names another run")
            _, checkpoint, loaded = load_checkpoint(str(experiment / "checkpoints"), "last")
            time_dict = loaded or time_dict
            tonic_logger.load(checkpoint, time_dict)
            resume_agent(agent, checkpoint)
        trainer = WallClockTrainer(
            clock,
            ProgressLog(out / PROGRESS_FILE),
            out,
            checkpoint_interval_s=args.checkpoint_minutes * 60.0,
            **published_trainer_kwargs(tonic["trainer"]),
        )
        trainer.initialize(
            agent=agent,
            environment=environment,
            test_environment=test_environment,
            full_save=tonic["full_save"],
        )
        log.info(
            "training for %.0f s more: %d x %d envs, from %d steps",
            clock.budget_s - clock.already_s,
            tonic["parallel"],
            tonic["sequential"],
            time_dict["steps"],
        )
        trainer.run(config, **time_dict)
        trainer.progress.maybe_write(clock.elapsed(), int(trainer.steps), force=True)
    report = evaluate_run(out, episodes=args.eval_episodes, seed=args.eval_seed)
    print(format_table(report))


def main(argv: list[str] | None = None) -> None:
    """Command line: see the module docstring."""
    p = run_arguments(__doc__)
    p.add_argument("--parallel", type=int, default=machine_cores(), help="worker processes")
    p.add_argument("--sequential", type=int, default=10, help="envs per worker process")
    setup_logging()
    args = p.parse_args(argv)
    torch.set_num_threads(args.torch_threads)
    train(args)


if __name__ == "__main__":
    main()
