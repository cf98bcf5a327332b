"""MuJoCo models from MyoSuite's MJCF files (the ``myo-sim`` package), as editable specs.

``myo-sim`` ships MyoLeg only as include fragments (assets, kinematic chain, tendons,
muscles) that its own composer attaches to a torso scaffold. :func:`myoleg_spec` wraps the
fragments in a small standalone model instead: a floor, a floating root, the legs and the
rigid torso that MyoSuite's own walking models carry, and nothing else. The wrapper is an
MJCF string whose ``<include>`` and ``meshdir`` entries are absolute paths into the
installed package, so nothing is written anywhere (the package is only read).

MyoLeg world frame (after our wrapper): Z up, gravity -Z (MuJoCo default), the body
faces +X, its left is +Y. (The fragments themselves are OpenSim-style Y-up; MyoSuite's
own models face -Y. We turn the root by +90 degrees about Z so that forward is +X.)
Lengths are metres, angles radians, masses kilograms. The torso (head, arms and trunk as
one rigid 37.4 kg body fixed to the pelvis, no joints, no muscles) brings the total mass to
75.2 kg, its centre of mass 0.93 m up when standing (the legs and pelvis alone: 37.8 kg,
0.62 m up).

Collision (as shipped by MyoSuite): leg and torso capsules/ellipsoids (classes
``myolegs_coll``, ``myotorso_coll``; the torso's unnamed ones named ``torso_col<k>``) have
``contype=1 conaffinity=0`` so they touch the floor (``contype=conaffinity=1``) but not
each other; bone meshes and wrap objects have ``contype=conaffinity=0`` (render only).
"""

from __future__ import annotations

import logging
import xml.etree.ElementTree as ET
from functools import cache
from importlib import resources
from pathlib import Path

import mujoco
import numpy as np
from gaitforge.workers.sim.mujoco.lock import coupled_qpos
from gaitforge.workers.sim.mujoco.warning_log import route_warnings

logger = logging.getLogger(__name__)
route_warnings()  # MuJoCo's warnings to logging, not to MUJOCO_LOG.TXT in the cwd

FLOOR = "floor"
ROOT_JOINT = "root"
ROOT_BODY = "root"
STAND_KEY = "stand"

MYOLEG_STAND_HEIGHT = 0.945402
"""Height (m) of the root body at which, in the ``stand`` pose, the lowest foot collision
geoms just touch the floor (signed distance 0; the geoms' 1 mm margin makes contact
active). Checked by the tests with ``mj_geomDistance``."""

MYOLEG_STAND_ANKLE = 0.0119593609
"""Ankle angle (rad) of MyoSuite's ``standing`` posture (myo_sim/build/data/postures.json):
foot flat on the floor with the knees straight."""

MYOLEG_FOOT_GEOMS: tuple[str, ...] = tuple(
    f"{name}_{side}"
    for side in ("r", "l")
    for name in ("foot_col1", "foot_col3", "foot_col4", "bofoot_col1", "bofoot_col2")
)
"""Collision geoms of the feet (calcaneus and toes), right then left."""

_LEG_FRAGMENTS = (
    "myolegs_assets.xml",
    "myolegs_chain.xml",
    "myolegs_tendon.xml",
    "myolegs_muscle.xml",
)
_TORSO_FRAGMENTS = ("myotorso_rigid_assets.xml", "myotorso_rigid_chain.xml")
"""MyoSuite's rigid torso (head, arms and trunk as one 37.4 kg body on the pelvis), which its
own MyoLeg walking models carry. Its fragment turns it by -90 degrees about Z, which our
root's +90 undoes (MyoSuite's unturned root needs a frame for it)."""
_ROOT_QUAT = (np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5))
"""+90 degrees about Z: MyoLeg's forward (-Y as shipped) becomes +X."""


@cache
def myosim_models_dir() -> Path:
    """Absolute path of ``myo_sim/models`` in the installed ``myo-sim`` package.

    Raises:
        FileNotFoundError: If the package is not installed as plain files (e.g. zipped).
    """
    path = Path(str(resources.files("myo_sim") / "models")).resolve()
    if not (path / "leg" / "assets" / "myolegs_chain.xml").is_file():
        raise FileNotFoundError(f"myo-sim models not found as files under {path}")
    return path


def _myoleg_xml() -> str:
    models = myosim_models_dir()
    assets, chain, tendon, muscle = (models / "leg" / "assets" / f for f in _LEG_FRAGMENTS)
    torso_dir = models / "legacy" / "torso" / "assets"
    torso_assets, torso_chain = (torso_dir / f for f in _TORSO_FRAGMENTS)
    quat = " ".join(f"{q:.17g}" for q in _ROOT_QUAT)
    # The fragments reference meshes as "meshes/<name>.stl", relative to models/.
    return f"""<mujoco model="myoleg">
  <compiler meshdir="{models}" texturedir="{models / "textures"}"/>
  <include file="{assets}"/>
  <include file="{torso_assets}"/>
  <asset>
    <texture name="floor_tex" type="2d" builtin="checker" rgb1=".82 .84 .86"
             rgb2=".72 .74 .76" width="256" height="256"/>
    <material name="floor_mat" texture="floor_tex" texrepeat="2 2" texuniform="true"/>
  </asset>
  <worldbody>
    <light name="sun" pos="0 0 4" dir="0 0 -1" directional="true"/>
    <geom name="{FLOOR}" type="plane" size="0 0 0.05" material="floor_mat"
          contype="1" conaffinity="1" condim="3"/>
    <body name="{ROOT_BODY}" pos="0 0 {MYOLEG_STAND_HEIGHT}" quat="{quat}">
      <freejoint name="{ROOT_JOINT}"/>
      <include file="{torso_chain}"/>
      <include file="{chain}"/>
    </body>
  </worldbody>
  <include file="{tendon}"/>
  <include file="{muscle}"/>
</mujoco>
"""


def leg_contact_pairs() -> list[tuple[str, str, int]]:
    """MyoSuite's leg-on-leg contact pairs of MyoLeg (thighs, shanks, feet): 26 (geom, geom,
    condim)."""
    path = myosim_models_dir() / "contacts" / "myolegs_contacts.xml"
    return [
        (pair.attrib["geom1"], pair.attrib["geom2"], int(pair.attrib.get("condim", "3")))
        for pair in ET.parse(path).getroot().iter("pair")
    ]


def _add_self_contacts(spec: mujoco.MjSpec) -> None:
    """:func:`leg_contact_pairs` added to ``spec``."""
    for first, second, condim in leg_contact_pairs():
        spec.add_pair(geomname1=first, geomname2=second, condim=condim)


def _add_stand_key(spec: mujoco.MjSpec) -> None:
    model = spec.compile()
    qpos = model.qpos0.copy()
    for side in ("r", "l"):
        qpos[model.jnt_qposadr[model.joint(f"ankle_angle_{side}").id]] = MYOLEG_STAND_ANKLE
    spec.add_key(name=STAND_KEY, qpos=coupled_qpos(model, qpos).tolist())


def myoleg_spec(self_contacts: bool = False) -> mujoco.MjSpec:
    """MyoLeg (80 muscles, 3-D) on a floor, as a fresh editable spec.

    Contents: floor plane ``floor``; body ``root`` with free joint ``root`` at
    :data:`MYOLEG_STAND_HEIGHT`, holding MyoSuite's rigid ``torso`` and its pelvis and legs
    (28 hinge/slide joints, 14 knee/patella ``<equality><joint>`` couplings to
    ``knee_angle_*``); 80 spatial tendons with 80 muscles; bone meshes for rendering
    (non-colliding); one keyframe ``stand`` (knees straight, feet flat on the floor,
    couplings satisfied; ``qpos0`` itself violates the patella couplings by ~1 cm). The
    pruning functions of :mod:`workers.sim.mujoco.lock`, :mod:`workers.sim.mujoco.removal` and
    :mod:`workers.sim.mujoco.contacts` keep the keyframe consistent.

    Args:
        self_contacts: Also add MyoSuite's explicit leg-on-leg contact pairs (26 pairs).

    Returns:
        A new ``mujoco.MjSpec`` (each call parses the files again).
    """
    spec = mujoco.MjSpec.from_string(_myoleg_xml())
    torso_mesh = spec.mesh("torso")  # named bare in its fragment, it lies in models/meshes
    torso_mesh.file = str(myosim_models_dir() / "meshes" / Path(torso_mesh.file).name)
    unnamed = [g for g in spec.body("torso").geoms if not g.name]
    for k, geom in enumerate(unnamed, start=1):  # the trunk's capsules, named to be pruned
        geom.name = f"torso_col{k}"
    spec.nkey = 0  # the assets' <size nkey="1"> would add an unnamed blank keyframe
    for geom in spec.geoms:
        if geom.type == mujoco.mjtGeom.mjGEOM_MESH:
            geom.contype = 0
            geom.conaffinity = 0
    if self_contacts:
        _add_self_contacts(spec)
    _add_stand_key(spec)
    return spec


def elbow_spec() -> mujoco.MjSpec:
    """MyoSuite's elbow: one hinge (``r_elbow_flex``), 6 muscles, fixed to the world.

    Returns:
        A new ``mujoco.MjSpec`` parsed from
        ``myo_sim/models/legacy/elbow/myoelbow_1dof6muscles.xml``.
    """
    path = myosim_models_dir() / "legacy" / "elbow" / "myoelbow_1dof6muscles.xml"
    return mujoco.MjSpec.from_file(str(path))
