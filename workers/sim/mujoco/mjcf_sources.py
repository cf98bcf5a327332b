"""MyoSuite bodies by the name a scene gives them, as shipped (MyoLeg with its leg-on-leg
contact pairs): the "nothing removed" model that pruning reports against."""

from __future__ import annotations

from collections.abc import Callable

import mujoco
from gaitforge.workers.sim.mujoco.mjcf_models import elbow_spec, myoleg_spec

MJCF_SOURCES: dict[str, Callable[[], mujoco.MjSpec]] = {
    "myoleg": lambda: myoleg_spec(self_contacts=True),
    "myoelbow": elbow_spec,
}
