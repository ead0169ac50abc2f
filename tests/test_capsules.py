"""Closed-form capsule/sphere/plate distances (kinematics.generic.capsules) against hand-derived
ones and against coal (through CollisionModel) on random configurations."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.generic.capsules import CAPSULE, PLATE, AnalyticDistances
from kinematics.generic.collision import CollisionModel
from kinematics.model.robot import load_robot

TWO = """<robot name="two">
  <link name="a">
    <collision><origin xyz="0 0 0" rpy="0 1.5707963267948966 0"/><geometry><cylinder radius="0.1" length="0.6"/></geometry></collision>
    <collision><origin xyz="-0.3 0 0"/><geometry><sphere radius="0.1"/></geometry></collision>
    <collision><origin xyz="0.3 0 0"/><geometry><sphere radius="0.1"/></geometry></collision>
  </link>
  <link name="m"/>
  <link name="b">
    <collision><origin xyz="0.4 0 0" rpy="1.5707963267948966 0 0"/><geometry><cylinder radius="0.05" length="0.4"/></geometry></collision>
    <collision><origin xyz="0.4 -0.2 0"/><geometry><sphere radius="0.05"/></geometry></collision>
    <collision><origin xyz="0.4 0.2 0"/><geometry><sphere radius="0.05"/></geometry></collision>
  </link>
  <joint name="z" type="prismatic"><parent link="a"/><child link="m"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="y" type="prismatic"><parent link="m"/><child link="b"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>"""


def test_two_capsules_by_hand_and_by_coal(tmp_path, rng):
    """Capsule a: x in [-0.3, 0.3] on the x axis, r 0.1; capsule b: y in [q_y - 0.2, q_y + 0.2] at
    x = 0.4, z = q_z, r 0.05. Their axes' distance is sqrt(0.1^2 + max(|q_y| - 0.2, 0)^2 + q_z^2)
    (0.1: the x gap between a's end and b's line), so the signed distance is that less 0.15,
    negative (the penetration depth) when they overlap."""
    (tmp_path / "two.urdf").write_text(TWO)
    cm = CollisionModel.from_robot(load_robot(tmp_path / "two.urdf"), exclude_touching=False)
    ad = AnalyticDistances(cm)
    assert list(ad.kinds) == [CAPSULE]
    q = rng.uniform(-0.5, 0.5, (4000, 2))
    q[:500] *= 0.1  # overlapping
    hand = np.sqrt(0.01 + np.maximum(np.abs(q[:, 1]) - 0.2, 0) ** 2 + q[:, 0] ** 2) - 0.15
    d, ok = ad.closed_form(q)
    assert ok.all() and (hand < 0).sum() > 300
    # the closed form is a few roundings of the inputs: 1e-15 m; coal's GJK/EPA stops at 1e-10
    assert np.abs(d[:, 0] - hand).max() < 1e-14
    assert np.abs(cm.distances(q)[:, 0] - hand).max() < 1e-9


@pytest.mark.parametrize("robot", ["p2us-results", "delta"])
def test_closed_forms_agree_with_coal_on_random_configurations(robot, rng):
    """Random joint values (loops not closed: every placement counts) within the limits: every
    closed-form distance is coal's to 1e-9 m (coal's GJK/EPA tolerance is 1e-10) except one
    documented case, a sphere overlapping a plate, where coal's sphere-cylinder routine reports a
    deeper penetration (measured to the side) than the shortest separating translation; there the
    signs agree. Pairs the closed forms cannot take (a rod beside the plate) go to coal."""
    rb = load_robot(robot)
    cm = CollisionModel.from_robot(rb)
    ad = AnalyticDistances(cm)
    m = rb.model
    q = rng.uniform(np.maximum(m.lowerPositionLimit, -np.pi), np.minimum(m.upperPositionLimit, np.pi), (3000, m.nq))
    coal = cm.distances(q)
    d, ok = ad.closed_form(q)
    assert (ad.kinds == CAPSULE).sum() > 30 and (ad.kinds == PLATE).sum() >= 6
    assert ok.mean() > 0.8 and (ok & (coal < 0)).sum() > 500
    sphere_plate = np.array([{cm.links[a], cm.links[b]} == {"base", "platform"} for a, b in cm.pairs])
    exact = ok & ~(sphere_plate & (coal < 0))
    assert np.abs(d - coal)[exact].max() < 1e-9
    assert (np.sign(d[ok]) == np.sign(coal[ok])).all()
    # beside a plate: where a bound is found it is positive and below coal's distance
    bound = ~ok & (ad.kinds == PLATE) & np.isfinite(d)
    assert bound.sum() > 100 and (d[bound] > 0).all() and (d[bound] <= coal[bound] + 1e-9).all()
    signs = ad.distances(q, signs=True)
    assert (np.sign(signs) == np.sign(coal)).all()
    full = ad.distances(q)
    # coal again on the configurations that need it: apart, the same to GJK's tolerance; its EPA
    # depths of a rod deep in the plate depend on the warm start (up to 0.1 m apart), signs do not
    apart = ~ok & (coal > 0)
    assert np.abs(full[apart] - coal[apart]).max() < 1e-9 and (np.sign(full[~ok]) == np.sign(coal[~ok])).all()
    assert np.array_equal(full[ok], d[ok])


@pytest.mark.parametrize("robot", ["p2us-results", "delta"])
def test_one_pair_per_configuration_is_the_full_evaluation(robot, rng):
    """`pair_distances(q, pair)` (only pair[n]'s two shapes placed, on the chains of their joints)
    is entry [n, pair[n]] of `distances(q)`: bit for bit where the closed form holds (the same
    operations on the same joints), and, with `signs`, of the same sign everywhere (coal's EPA
    depths of a rod deep in a plate depend on its warm start); in batches on one core and on every
    core."""
    from kinematics.generic import capsules

    rb = load_robot(robot)
    ad = AnalyticDistances(CollisionModel.from_robot(rb))
    m = rb.model
    q = rng.uniform(np.maximum(m.lowerPositionLimit, -np.pi), np.minimum(m.upperPositionLimit, np.pi), (3000, m.nq))
    d, ok = ad.closed_form(q)
    # half the rows ask for their smallest pair (overlaps), half for any
    smallest = np.nanargmin(np.where(ok, d, np.inf), axis=1)
    pair = np.where(rng.random(len(q)) < 0.5, smallest, rng.integers(0, len(ad.kinds), len(q)))
    rows = np.arange(len(q))
    for n in (len(q), capsules.PARALLEL_MIN - 1):  # every core, one core
        one = ad.pair_distances(q[:n], pair[:n])
        good = ok[rows[:n], pair[:n]]
        assert good.mean() > 0.8 and np.array_equal(one[good], d[rows[:n], pair[:n]][good])
        signs = ad.pair_distances(q[:n], pair[:n], signs=True)
        full = ad.distances(q[:n], signs=True)[rows[:n], pair[:n]]
        assert (full < 0).sum() > 50 and (np.sign(signs) == np.sign(full)).all()


@pytest.mark.parametrize("robot", ["p2us-results", "delta"])
def test_closed_form_in_one_pass_is_the_two_passes(robot, rng):
    """`closed_form` (the tree posed and every pair evaluated per configuration in one compiled
    pass) gives the same values and flags, bit for bit, as its two passes (every placement, then
    every pair: `closed_form_in_two`), on one thread and on every core."""
    from kinematics.generic import capsules

    rb = load_robot(robot)
    ad = AnalyticDistances(CollisionModel.from_robot(rb))
    m = rb.model
    q = rng.uniform(np.maximum(m.lowerPositionLimit, -np.pi), np.minimum(m.upperPositionLimit, np.pi),
                    (3 * capsules.PARALLEL_MIN, m.nq))
    for n in (capsules.PARALLEL_MIN - 1, len(q)):
        one, two = ad.closed_form(q[:n]), ad.closed_form_in_two(q[:n])
        assert np.array_equal(one[0], two[0], equal_nan=True) and np.array_equal(one[1], two[1])
        assert one[1].mean() > 0.5
