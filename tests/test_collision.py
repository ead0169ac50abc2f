"""Collision geometry and signed distances (kinematics.generic.collision), against hand-derived
distances on a hermetic model and against Pinocchio's own mesh collision test on the UR5."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from kinematics.errors import UnknownNameError
from kinematics.generic.collision import CollisionModel, ExcludedPair
from kinematics.model.geometry import GeometryError
from kinematics.model.robot import load_robot

MODEL = Path(__file__).parent / "models" / "collide3.urdf"


def _by_hand(q: np.ndarray) -> dict[tuple[str, str], np.ndarray]:
    """Signed distances of collide3's pairs from its URDF numbers: the arm's sphere (r 0.05) at
    (0.5 + q0 + 0.2 cos q1, 0.2 sin q1, 0), its cylinder (r 0.03, z from -0.05 to 0.05) on the
    turn axis at (0.5 + q0, 0, 0); the base's sphere (r 0.1) at the origin, its box (0.4 x 0.2 x 0.2)
    centred at (0.6, 0.3, 0)."""
    c = np.column_stack([0.5 + q[:, 0] + 0.2 * np.cos(q[:, 1]), 0.2 * np.sin(q[:, 1]), np.zeros(len(q))])
    b = np.abs(c - [0.6, 0.3, 0.0]) - [0.2, 0.1, 0.1]
    box = np.linalg.norm(np.maximum(b, 0.0), axis=1) + np.minimum(b.max(axis=1), 0.0)  # point to box
    return {
        ("base_0", "arm_0"): np.linalg.norm(c, axis=1) - 0.15,
        ("base_0", "arm_1"): np.abs(0.5 + q[:, 0]) - 0.13,  # the sphere's centre is level with the cylinder
        ("base_1", "arm_0"): box - 0.05,
        # the box's nearest face y = 0.2 against the cylinder's side whenever they overlap in x
    }


def test_signed_distances_match_the_hand_derived_ones(rng):
    robot = load_robot(MODEL)
    cm = CollisionModel.from_robot(robot, reference=np.array([0.3, 0.0]))
    q = np.column_stack([rng.uniform(-1.0, 0.5, 3000), rng.uniform(-3.2, 3.2, 3000)])
    d = cm.distances(q)
    hand = _by_hand(q)
    for name, expected in hand.items():
        got = d[:, cm.pair_names.index(name)]
        # coal's sphere-sphere, sphere-cylinder and sphere-box distances are closed forms: a few
        # ulps of the 1 m scale, penetration (negative) included
        assert np.abs(got - expected).max() < 1e-12, name
        assert (expected < 0).sum() > 100, name  # penetrations were exercised
    margin, which = cm.margin(q)
    expected_margin = np.min(np.column_stack([*hand.values(), d[:, cm.pair_names.index(("base_1", "arm_1"))]]), axis=1)
    assert np.abs(margin - expected_margin).max() < 1e-12
    assert set(which) <= set(range(len(cm.pairs)))


def test_pairs_exclude_adjacent_touching_and_disabled_bodies(tmp_path):
    # a chain base -> a -> b -> c of boxes: a and c touch b by design (adjacent), a and c overlap at
    # the reference pose (touching), base and c are disabled by name; base-b is the only pair left
    text = """<robot name="chain">
  <link name="base"><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <link name="a"><collision><origin xyz="0.25 0 0"/><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <link name="b"><collision><origin xyz="0.25 0 0"/><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <link name="c"><collision><origin xyz="-0.75 0 0"/><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0.5 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="j3" type="revolute"><parent link="b"/><child link="c"/><origin xyz="0.5 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>"""
    path = tmp_path / "chain.urdf"
    path.write_text(text)
    robot = load_robot(path)
    cm = CollisionModel.from_robot(robot, disabled=[("c", "base")])
    assert cm.pair_links == (("base", "b"),)
    assert set(cm.excluded) == {
        ExcludedPair("base", "a", "adjacent"), ExcludedPair("a", "b", "adjacent"),
        ExcludedPair("b", "c", "adjacent"), ExcludedPair("a", "c", "touching"),
        ExcludedPair("base", "c", "disabled"),
    }
    # base's box spans x in [-0.05, 0.05], b's box [0.7, 0.8] at q = 0: 0.65 apart (box-box goes
    # through GJK's iterations, not a closed form: 1e-9 m, well above its observed 5e-12)
    assert cm.distances(np.zeros((1, 3)))[0, 0] == pytest.approx(0.65, abs=1e-9)
    kept = CollisionModel.from_robot(robot, exclude_touching=False)
    assert ("a", "c") in kept.pair_links
    with pytest.raises(UnknownNameError, match=r"'d'.*valid: a, b, base, c"):
        CollisionModel.from_robot(robot, disabled=[("a", "d")])


def test_geometry_pinocchio_cannot_read_is_refused_not_dropped(tmp_path):
    text = MODEL.read_text().replace('<sphere radius="0.1"/>', '<capsule radius="0.1" length="0.2"/>')
    (tmp_path / "capsule.urdf").write_text(text)
    with pytest.raises(GeometryError, match=r"link base: shape capsule not read.*box, cylinder, sphere, mesh"):
        CollisionModel.from_robot(load_robot(tmp_path / "capsule.urdf"))
    text = MODEL.read_text().replace('<sphere radius="0.1"/>', '<mesh filename="missing.stl"/>')
    (tmp_path / "mesh.urdf").write_text(text)
    with pytest.raises(GeometryError, match=r"link base: mesh missing.stl not found"):
        CollisionModel.from_robot(load_robot(tmp_path / "mesh.urdf"))


def test_ur5_mesh_signs_match_pinocchios_mesh_collision_test(ur5):
    import pinocchio as pin

    from kinematics.model.geometry import geometry_model

    cm = CollisionModel.from_robot(ur5)
    assert len(cm.pairs) > 10 and all(e.reason == "adjacent" for e in cm.excluded)
    rng = np.random.default_rng(7)
    lo, hi = ur5.model.lowerPositionLimit, ur5.model.upperPositionLimit
    q = rng.uniform(lo, hi, size=(400, ur5.model.nq))
    d = cm.distances(q)
    # the independent path: Pinocchio's collision test on the meshes themselves (BVH, no hulls)
    meshes, _ = geometry_model(ur5, "collision")
    for a, b in cm.pairs:
        meshes.addCollisionPair(pin.CollisionPair(a, b))
    data, gdata = ur5.model.createData(), pin.GeometryData(meshes)
    colliding = np.zeros_like(d, dtype=bool)
    for n, qn in enumerate(q):
        pin.computeCollisions(ur5.model, data, meshes, gdata, qn, False)
        colliding[n] = [r.isCollision() for r in gdata.collisionResults]
    assert (colliding == (d < 0)).all()
    assert 20 < colliding.any(axis=1).sum() < 380  # both kinds of configuration were drawn
    # where the meshes are apart the value never exceeds their own distance (hulls contain them)
    for n in range(40):
        pin.computeDistances(ur5.model, data, meshes, gdata, q[n])
        exact = np.array([r.min_distance for r in gdata.distanceResults])
        free = ~colliding[n]
        assert (d[n, free] <= exact[free] + 1e-9).all()  # 1e-9: GJK's stopping tolerance on 1 m shapes
