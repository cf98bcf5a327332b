"""Restricting contacts and measuring model size, with real MuJoCo."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from gaitforge.workers.sim.mujoco.contacts import contact_pair_mask, model_size, restrict_contacts
from gaitforge.workers.sim.mujoco.mjcf_models import (
    FLOOR,
    MYOLEG_FOOT_GEOMS,
    STAND_KEY,
    myoleg_spec,
)


def test_restrict_contacts_feet_floor() -> None:
    spec = myoleg_spec(self_contacts=True)
    restrict_contacts(spec, list(MYOLEG_FOOT_GEOMS), [FLOOR])
    model = spec.compile()
    assert model.npair == 0
    assert model_size(model)["contact_pairs"] == len(MYOLEG_FOOT_GEOMS) * 1
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(STAND_KEY).id)
    data.qpos[2] -= 0.02  # sink into the floor
    mujoco.mj_forward(model, data)
    assert data.ncon > 0
    feet = {model.geom(g).id for g in MYOLEG_FOOT_GEOMS}
    floor = model.geom(FLOOR).id
    for c in data.contact[: data.ncon]:
        assert {int(c.geom1), int(c.geom2)} & feet and floor in (c.geom1, c.geom2)
    with pytest.raises(KeyError):
        restrict_contacts(spec, ["nope"], [FLOOR])


_OVERLAP = """
<mujoco>
  <option><flag {flag}/></option>
  <worldbody>
    <geom name="w0" type="sphere" size="1"/>
    <geom name="w1" type="sphere" size="1"/>
    <body name="A"><joint type="hinge"/><geom name="a0" size="1"/><geom name="a1" size="1"/>
      <body name="B"><joint type="hinge"/><geom name="b0" size="1"/>
        <geom name="b_off" size="1" contype="2" conaffinity="2"/>
        <body name="B_welded"><geom name="bw" size="1"/>
          <body name="C"><joint type="slide"/><geom name="c0" size="1"/></body>
        </body>
      </body>
    </body>
    <body name="D"><freejoint/><geom name="d0" size="1"/>
      <geom name="d_mesh_like" type="box" size="1 1 1" contype="2" conaffinity="1"/></body>
    <body name="E"><freejoint/><geom name="e0" size="1" contype="0" conaffinity="0"/></body>
  </worldbody>
  <contact>
    <exclude body1="A" body2="D"/>
    <pair geom1="a0" geom2="b0"/>
    <pair geom1="e0" geom2="w0"/>
    <pair geom1="w0" geom2="d0"/>
  </contact>
</mujoco>
"""


@pytest.mark.parametrize("flag", ['filterparent="enable"', 'filterparent="disable"'])
def test_contact_pairs_match_mujoco(flag: str) -> None:
    """Every geom overlaps every other: MuJoCo's contacts enumerate the allowed pairs."""
    model = mujoco.MjSpec.from_string(_OVERLAP.format(flag=flag)).compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    seen = {tuple(sorted((int(c.geom1), int(c.geom2)))) for c in data.contact[: data.ncon]}
    assert model_size(model)["contact_pairs"] == len(seen)
    mask = contact_pair_mask(model)
    dynamic = {(int(i), int(j)) for i, j in zip(*np.nonzero(mask), strict=True)}
    explicit = {
        tuple(sorted((int(a), int(b))))
        for a, b in zip(model.pair_geom1, model.pair_geom2, strict=True)
    }
    assert dynamic | explicit == seen


def test_model_size_consistent(myoleg_model: mujoco.MjModel) -> None:
    size = model_size(myoleg_model)
    m = myoleg_model
    assert size["dofs"] == m.nv and size["joints"] == m.njnt and size["bodies"] == m.nbody
    assert size["tendons"] == m.ntendon and size["geoms"] == m.ngeom
    assert size["sites"] == m.nsite and size["muscles"] == 80
    assert 0 < size["wrap_objects"] <= m.ngeom
    wrap_geoms = {
        int(o)
        for t, o in zip(m.wrap_type, m.wrap_objid, strict=True)
        if t in (int(mujoco.mjtWrap.mjWRAP_SPHERE), int(mujoco.mjtWrap.mjWRAP_CYLINDER))
    }
    assert size["wrap_objects"] == len(wrap_geoms)
    # 20 leg and 8 torso-and-arm collision geoms (contype 1, conaffinity 0) against the
    # floor only
    assert size["contact_pairs"] == 28
