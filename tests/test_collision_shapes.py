"""Collision shapes of the built-ins' URDFs (issue 30 item 1): the generators' sizes, the capsules
they write as cylinder + end spheres merged back into one, and the sidecar's disabled pairs."""

from __future__ import annotations

import shutil
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest

from kinematics.errors import UnknownFrameError
from kinematics.generic.collision import CollisionModel, reference_configuration
from kinematics.mechanisms.delta import urdf as delta_urdf
from kinematics.mechanisms.delta.closed_form import DeltaParams
from kinematics.mechanisms.p2us import urdf as p2us_urdf
from kinematics.mechanisms.three_limb.urdf import CollisionSizes, read_collision_sizes
from kinematics.model.robot import load_robot

URDF_DIR = Path(__file__).resolve().parents[1] / "urdf"

SIZES = CollisionSizes(rod_radius=0.009, arm_radius=0.012, plate_thickness=0.03, plate_overhang=0.04,
                       platform_overhang=0.025)


def _shapes(cm: CollisionModel) -> dict[str, object]:
    return {cm.links[k]: g.geometry for k, g in enumerate(cm.geometry.geometryObjects)}


@pytest.mark.parametrize("family", ["p2us", "delta"])
def test_generated_shapes_have_the_sizes_asked_for(family, tmp_path):
    """Every shape's size follows from the design and the sizes: rods are capsules of length L
    (lb) and the rod radius, the plate a cylinder of radius b + overhang (R + overhang) and the
    plate thickness, the platform a sphere of radius d + overhang (r + overhang); the sidecar
    records the sizes."""
    module, params = (p2us_urdf, p2us_urdf.DESIGNS["results"]) if family == "p2us" else (delta_urdf, DeltaParams())
    urdf, side = module.write(params, tmp_path / "m.urdf", sizes=SIZES)
    shapes = _shapes(CollisionModel.from_robot(load_robot(urdf)))
    rod_length, base, plate = (params.L, params.b, params.d) if family == "p2us" else (params.lb, params.R, params.r)
    arms = [f"limb_{i}" for i in (1, 2, 3)] if family == "p2us" else [f"upper_arm_{i}" for i in (1, 2, 3)]
    for i in (1, 2, 3):
        for k in (1, 2):
            rod = shapes[f"rod_{i}_{k}"]
            assert isinstance(rod, coal.Capsule)
            assert rod.radius == pytest.approx(0.009, abs=1e-15) and 2 * rod.halfLength == pytest.approx(rod_length, abs=1e-15)
    for name in arms:
        assert isinstance(shapes[name], coal.Capsule) and shapes[name].radius == pytest.approx(0.012, abs=1e-15)
    assert isinstance(shapes["base"], coal.Cylinder)
    assert shapes["base"].radius == pytest.approx(base + 0.04, abs=1e-15)
    assert 2 * shapes["base"].halfLength == pytest.approx(0.03, abs=1e-15)
    assert isinstance(shapes["platform"], coal.Sphere) and shapes["platform"].radius == pytest.approx(plate + 0.025, abs=1e-15)
    assert read_collision_sizes(side, module.SIZES) == SIZES
    assert read_collision_sizes(tmp_path / "none.loops.yaml", module.SIZES) == module.SIZES


@pytest.mark.parametrize("robot", ["p2us-results", "delta"])
def test_rod_capsules_run_between_the_joint_centres(robot):
    """At the reference pose each rod's capsule axis starts at its universal joint's centre and
    ends at its tip frame (the ball joint's centre), to 1e-12 m."""
    rb = load_robot(robot)
    cm = CollisionModel.from_robot(rb)
    model, data = rb.model, rb.model.createData()
    q = reference_configuration(rb)
    pin.framesForwardKinematics(model, data, q)
    for k, g in enumerate(cm.geometry.geometryObjects):
        if not cm.links[k].startswith("rod_"):
            continue
        M = data.oMf[g.parentFrame] * g.placement
        ends = [M.translation + s * g.geometry.halfLength * M.rotation[:, 2] for s in (-1, 1)]
        i_k = cm.links[k].removeprefix("rod_")
        joint = data.oMi[model.getJointId(f"u_phi_{i_k}")].translation
        tip = data.oMf[model.getFrameId(f"tip_{i_k}")].translation
        assert min(np.linalg.norm(ends[0] - joint), np.linalg.norm(ends[1] - joint)) < 1e-12
        assert min(np.linalg.norm(ends[0] - tip), np.linalg.norm(ends[1] - tip)) < 1e-12


def test_sidecar_disabled_pairs_are_left_out(tmp_path):
    for suffix in (".urdf", ".loops.yaml"):
        shutil.copy(URDF_DIR / f"p2us-results{suffix}", tmp_path / f"m{suffix}")
    side = tmp_path / "m.loops.yaml"
    text = side.read_text()
    side.write_text(text.replace("disabled: []", "disabled: [[rod_2_1, rod_1_1], [base, platform]]"))
    cm = CollisionModel.from_robot(load_robot(tmp_path / "m.urdf"))
    assert {(e.first, e.second) for e in cm.excluded if e.reason == "disabled"} == {("rod_1_1", "rod_2_1"), ("base", "platform")}
    pairs = {frozenset(p) for p in cm.pair_links}
    assert frozenset(("rod_1_1", "rod_2_1")) not in pairs and frozenset(("base", "platform")) not in pairs
    assert frozenset(("rod_1_2", "rod_2_1")) in pairs
    side.write_text(text.replace("disabled: []", "disabled: [[rod_1_1, rod_9_9]]"))
    with pytest.raises(UnknownFrameError):
        load_robot(tmp_path / "m.urdf")


CAPSULE_URDF = """<robot name="caps">
  <link name="a">
    <collision><origin xyz="0 0 0.5" rpy="0 1.5707963267948966 0"/><geometry><cylinder radius="0.1" length="0.6"/></geometry></collision>
    <collision><origin xyz="-0.3 0 0.5"/><geometry><sphere radius="0.1"/></geometry></collision>
    <collision><origin xyz="0.3 0 0.5"/><geometry><sphere radius="{r}"/></geometry></collision>
  </link>
  <link name="b"><collision><origin xyz="0 0 0"/><geometry><sphere radius="0.05"/></geometry></collision></link>
  <link name="m"/>
  <joint name="j" type="prismatic"><parent link="a"/><child link="m"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="k" type="prismatic"><parent link="m"/><child link="b"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>"""


@pytest.mark.parametrize(("r", "merged"), [("0.1", True), ("0.1000001", False)])
def test_a_cylinder_with_both_end_spheres_is_one_capsule(r, merged, tmp_path):
    """The capsule's distance to a sphere at (x, 0, 0) beyond its end: |(x, 0, -0.5) - (0.3, 0, 0)|
    - 0.15 (by hand); a sphere of another radius on one end is left as it is."""
    (tmp_path / "c.urdf").write_text(CAPSULE_URDF.format(r=r))
    cm = CollisionModel.from_robot(load_robot(tmp_path / "c.urdf"), exclude_touching=False)
    kinds = sorted(type(g.geometry).__name__ for g in cm.geometry.geometryObjects)
    assert kinds == (["Capsule", "Sphere"] if merged else ["Cylinder", "Sphere", "Sphere", "Sphere"])
    if merged:
        x = np.array([0.5, 0.8, 1.0])
        assert np.allclose(cm.distances(np.column_stack([x, 0 * x]))[:, 0], np.hypot(x - 0.3, 0.5) - 0.15, atol=1e-9)
