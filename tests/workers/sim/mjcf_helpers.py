"""Shared helpers of the MJCF tests (``test_mjcf_*.py``)."""

from __future__ import annotations

import mujoco


def object_names(model: mujoco.MjModel, obj: mujoco.mjtObj, n: int) -> list[str]:
    return [mujoco.mj_id2name(model, obj, i) for i in range(n)]


def warning_counts(data: mujoco.MjData) -> dict[str, int]:
    return {
        mujoco.mjtWarning(i).name: int(data.warning[i].number)
        for i in range(len(data.warning))
        if data.warning[i].number
    }
