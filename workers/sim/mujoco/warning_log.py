"""MuJoCo's warnings go to Python logging, never to a file in the working directory.

Without a handler of its own, MuJoCo prints each warning (a NaN or huge value in the state,
a full contact buffer) to stdout and appends it to ``MUJOCO_LOG.TXT`` in the current working
directory. The simulator already reads the warning counters into ``Health``, so the text
goes to the logger ``gaitforge.workers.sim.mujoco`` at DEBUG. MuJoCo's handler is
process-wide; the modules that build MuJoCo models (``simulator``, ``build``,
``mjcf_models``) install it when they are imported.
"""

from __future__ import annotations

import logging

import mujoco

logger = logging.getLogger("gaitforge.workers.sim.mujoco")


def log_warning(message: str) -> None:
    """MuJoCo's warning handler: one DEBUG record per warning MuJoCo issues."""
    logger.debug("mujoco: %s", message.strip())


def route_warnings() -> None:
    """Send MuJoCo's warnings to :func:`log_warning` (idempotent)."""
    if mujoco.get_mju_user_warning() is not log_warning:
        mujoco.set_mju_user_warning(log_warning)
