"""Simulators leave no log files in the working directory: MuJoCo's warnings become log
records (``workers.sim.mujoco.warning_log``), OpenSim's file sink is removed."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import opensim
import pytest
from gaitforge.workers.fidelity.held import with_profile
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.scenes.profiles import FidelityProfile
from gaitforge.workers.sim.mujoco.simulator import MujocoSimulator
from gaitforge.workers.sim.opensim.build import quiet_opensim_log

EULER_10MS = FidelityProfile(integrator="euler", timestep=0.01)


def test_a_mujoco_warning_is_a_log_record_not_a_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.chdir(tmp_path)
    # walk-2d under Euler at 10 ms, every muscle fully on: diverges within 0.2 s
    sim = MujocoSimulator(with_profile(load_scene("walk-2d"), "mujoco", EULER_10MS))
    sim.reset(0)
    causes = []
    with caplog.at_level(logging.DEBUG, logger="gaitforge.workers.sim.mujoco"):
        for _ in range(50):
            causes.append(sim.step(np.ones(len(sim.muscle_names)), 0.02).cause)
            if causes[-1].startswith("mujoco_"):
                break
    assert causes[-1].startswith("mujoco_"), f"no MuJoCo warning provoked: {causes}"
    records = [r for r in caplog.records if r.name == "gaitforge.workers.sim.mujoco"]
    assert records and "simulation is unstable" in records[0].getMessage()
    assert records[0].levelno == logging.DEBUG  # Health carries it; the text is detail
    assert list(tmp_path.iterdir()) == [], "nothing written to the working directory"


def test_opensim_writes_no_log_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    opensim.Logger.setLevelString("info")  # as a user who wants OpenSim's messages might
    try:
        model = opensim.Model()
        model.initSystem()
        model.printToXML(str(tmp_path / "empty.osim"))
        opensim.Model(str(tmp_path / "empty.osim"))  # logs "Loaded model ..." at INFO
    finally:
        quiet_opensim_log()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty.osim"]
