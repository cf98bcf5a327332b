"""Removing muscles from an MjSpec, and their moment arms, with real MuJoCo."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from gaitforge.workers.sim.mujoco.mjcf_models import ROOT_JOINT, myoleg_spec
from gaitforge.workers.sim.mujoco.moment_arms import muscle_spans
from gaitforge.workers.sim.mujoco.removal import remove_muscles
from mjcf_helpers import object_names


def test_remove_muscles_exactly_the_named() -> None:
    spec = myoleg_spec()
    model0 = spec.compile()
    spec.add_key(
        name="busy",
        qpos=model0.qpos0.tolist(),
        ctrl=np.linspace(0, 1, 80).tolist(),
        act=np.linspace(0, 1, model0.na).tolist(),
    )
    gone = ["glmin1_r", "piri_l", "soleus_r"]
    remove_muscles(spec, gone)
    model = spec.compile()
    act0 = set(object_names(model0, mujoco.mjtObj.mjOBJ_ACTUATOR, model0.nu))
    act1 = set(object_names(model, mujoco.mjtObj.mjOBJ_ACTUATOR, model.nu))
    ten0 = set(object_names(model0, mujoco.mjtObj.mjOBJ_TENDON, model0.ntendon))
    ten1 = set(object_names(model, mujoco.mjtObj.mjOBJ_TENDON, model.ntendon))
    assert act0 - act1 == set(gone) and act1 <= act0
    assert ten0 - ten1 == {f"{n}_tendon" for n in gone} and ten1 <= ten0
    assert model.nsite < model0.nsite
    # collision geoms untouched
    assert (model.geom_contype > 0).sum() == (model0.geom_contype > 0).sum()
    kept = np.delete(np.linspace(0, 1, 80), [model0.actuator(n).id for n in gone])
    np.testing.assert_allclose(model.key("busy").ctrl, kept)
    assert model.key("busy").act.shape == (model.na,)
    with pytest.raises(KeyError):
        remove_muscles(spec, ["glmin1_r"])


def test_remove_muscles_keeps_shared_path_points() -> None:
    xml = """
    <mujoco><worldbody>
      <site name="o"/><body pos="0 0 -0.5"><joint name="h" axis="0 1 0"/>
      <geom size="0.05" mass="1"/><geom name="wrap" type="cylinder" size="0.03 0.05"
            contype="0" conaffinity="0" mass="0" pos="0 0 0.5"/>
      <geom name="solid" size="0.03" pos="0.05 0 0.4"/>
      <site name="shared" pos="0.03 0 0.1"/><site name="only_a" pos="0.03 0 0.2"/>
      <site name="mid_a" pos="0.04 0 0.45"/>
      <site name="side" pos="0.1 0 0.5"/></body></worldbody>
    <tendon>
      <spatial name="ta"><site site="o"/><geom geom="wrap" sidesite="side"/>
        <site site="mid_a"/><geom geom="solid"/><site site="only_a"/></spatial>
      <spatial name="tb"><site site="o"/><site site="shared"/></spatial>
    </tendon>
    <actuator><muscle name="a" tendon="ta"/><muscle name="b" tendon="tb"/></actuator>
    </mujoco>"""
    spec = mujoco.MjSpec.from_string(xml)
    remove_muscles(spec, ["a"])
    model = spec.compile()
    assert object_names(model, mujoco.mjtObj.mjOBJ_SITE, model.nsite) == ["o", "shared"]
    geoms = object_names(model, mujoco.mjtObj.mjOBJ_GEOM, model.ngeom)
    assert "wrap" not in geoms and "solid" in geoms  # "solid" collides and has mass


# ------------------------------------------------------------------ spans


def test_muscle_spans_myoleg(myoleg_model: mujoco.MjModel) -> None:
    spans = muscle_spans(myoleg_model)
    assert len(spans) == 80
    for side in "rl":
        for vastus in ("vasmed", "vaslat", "vasint"):
            assert spans[f"{vastus}_{side}"] == [f"knee_angle_{side}"]
        assert f"ankle_angle_{side}" in spans[f"soleus_{side}"]
        assert f"knee_angle_{side}" not in spans[f"soleus_{side}"]
        assert {f"knee_angle_{side}", f"ankle_angle_{side}"} <= set(spans[f"gasmed_{side}"])
        assert spans[f"bfsh_{side}"] == [f"knee_angle_{side}"]
        assert f"hip_flexion_{side}" in spans[f"recfem_{side}"]
    assert all(ROOT_JOINT not in v for v in spans.values())
    driven = {"knee_angle_beta_rotation1_r", "knee_angle_translation1_l"}
    assert all(not driven & set(v) for v in spans.values())
    assert spans == muscle_spans(myoleg_model)  # seeded
