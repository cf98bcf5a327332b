"""MyoSuite bodies by the name a scene gives them."""

from __future__ import annotations

from collections.abc import Callable

import mujoco

from workers.sim.mjcf_models import elbow_spec, myoleg_spec

MJCF_SOURCES: dict[str, Callable[[], mujoco.MjSpec]] = {
    "myoleg": myoleg_spec,
    "myoelbow": elbow_spec,
}
