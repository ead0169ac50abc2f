"""Manipulability ellipsoids: paper A's values, SVD vs eigen-decomposition vs 2x2 closed form."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.errors import InvalidInputError
from kinematics.generic.manipulability import SINGULAR_RTOL, ellipses_2x2, ellipsoid
from kinematics.generic.serial import task_jacobian
from kinematics.mechanisms.scara import closed_form as sc


@pytest.fixture(scope="module")
def params(scara):
    return sc.ScaraParams.from_robot(scara)


def test_paper_a_stretched_singular_point(scara, params):
    # Paper A, eqs. 14-15: at the tip position (0.7, 0), J J^T = [[0, 0], [0, 0.58]], radii 0 and 0.7616 m.
    ans = sc.solve_ik(params, (0.7, 0.0))
    q = np.array(ans.solutions[0].q)
    J = task_jacobian(scara, scara.configuration(q))
    np.testing.assert_allclose(J @ J.T, [[0.0, 0.0], [0.0, 0.58]], atol=1e-15)
    e = ellipsoid(J)
    assert e.radii[0] == pytest.approx(0.0, abs=1e-15)
    assert round(e.radii[1], 4) == 0.7616
    assert e.singular and e.yoshikawa == pytest.approx(0.0, abs=1e-15)
    assert e.condition_number == np.inf
    np.testing.assert_allclose(np.abs(e.directions), [[1, 0], [0, 1]], atol=1e-15)  # collapses along x


@pytest.mark.parametrize("shape", [(2, 2), (3, 6), (6, 6), (3, 2), (2, 5)])
def test_ellipsoid_matches_eigendecomposition(shape, rng):
    for _ in range(20):
        J = rng.normal(size=shape)
        e = ellipsoid(J)
        lam, vec = np.linalg.eigh(J @ J.T)  # ascending
        np.testing.assert_allclose(e.radii**2, lam, atol=1e-12)  # sqrt would amplify eigh's 1e-16 noise
        assert np.all(np.diff(e.radii) >= 0)
        for k in range(shape[0]):
            if e.radii[k] > 1e-9:  # directions of zero radii are any basis of the null space
                assert abs(abs(e.directions[k] @ vec[:, k]) - 1) < 1e-9
        np.testing.assert_allclose(e.directions @ e.directions.T, np.eye(shape[0]), atol=1e-12)
        np.testing.assert_allclose(e.yoshikawa**2, np.linalg.det(J @ J.T), rtol=1e-9, atol=1e-12)
        if shape[0] > shape[1]:
            assert e.radii[0] == 0.0 and e.singular


def test_direction_sign_convention(rng):
    e = ellipsoid(rng.normal(size=(3, 4)))
    for d in e.directions:
        assert d[np.argmax(np.abs(d))] > 0


def test_2x2_closed_form_matches_svd(rng):
    J = rng.normal(size=(500, 2, 2))
    batch = ellipses_2x2(J)
    for k in range(len(J)):
        e = ellipsoid(J[k])
        np.testing.assert_allclose(batch.radii[k], e.radii, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(batch.directions[k], e.directions, atol=1e-9)
        assert batch.singular[k] == e.singular
        assert batch.yoshikawa[k] == pytest.approx(e.yoshikawa, rel=1e-12)


def test_scara_closed_form_matches_pinocchio(scara, params, rng):
    qs = rng.uniform(params.lower, params.upper, (300, 2))
    batch = sc.manipulability(params, qs)
    for q, radii, dirs in zip(qs, batch.radii, batch.directions, strict=True):
        e = ellipsoid(task_jacobian(scara, scara.configuration(q)))
        np.testing.assert_allclose(radii, e.radii, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(dirs, e.directions, atol=1e-10)


def test_radii_depend_on_theta2_only(params, rng):
    # r^2 = (T -/+ sqrt(T^2 - 4D)) / 2 with T = l1^2 + 2 l2^2 + 2 l1 l2 c2, D = (l1 l2 s2)^2:
    # the simple closed form that paper A's garbled appendix (eqs. 23-24) should read.
    t2 = rng.uniform(*np.array([params.lower[1], params.upper[1]]), 1000)
    t1 = rng.uniform(params.lower[0], params.upper[0], 1000)
    radii = sc.manipulability(params, np.stack([t1, t2], -1)).radii
    l1, l2 = params.l1, params.l2
    T = l1**2 + 2 * l2**2 + 2 * l1 * l2 * np.cos(t2)
    D = (l1 * l2 * np.sin(t2)) ** 2
    root = np.sqrt(T**2 - 4 * D)
    np.testing.assert_allclose(radii[:, 1], np.sqrt((T + root) / 2), rtol=1e-12)
    np.testing.assert_allclose(radii[:, 0], np.sqrt(2 * D / (T + root)), rtol=1e-10)


def test_singular_flag_is_scale_free(params):
    near = sc.jacobian(params, np.array([0.2, 1e-3]))
    sing = sc.jacobian(params, np.array([0.2, 0.0]))
    for scale in (1e-3, 1.0, 1e3):
        assert not ellipsoid(near * scale).singular
        assert ellipsoid(sing * scale).singular
    tiny = sc.jacobian(params, np.array([0.2, SINGULAR_RTOL / 10]))
    assert sc.manipulability(params, np.array([0.2, SINGULAR_RTOL / 10])).singular
    assert ellipsoid(tiny).singular


def test_vectorised_over_a_grid_of_stretched_poses(params):
    """A (4, 5) grid of stretched poses (theta2 = 0, theta1 anywhere), derived by hand: with
    x = l1 c1 + l2 c12, y = l1 s1 + l2 s12, at theta2 = 0 J = (-s1, c1)^T (l1 + l2, l2), rank one:
    radii 0 and sqrt((l1 + l2)^2 + l2^2), the long axis +/-(-s1, c1), the collapsed one +/-(c1, s1).

    Tolerances: the closed form takes a square root of sums of the same O(1) products and the
    cosine and sine of theta1 + pi/2 (|theta1| <= 3): a few roundings of 1.1e-16 each, so 1e-15.
    """
    l1, l2 = params.l1, params.l2
    assert (l1, l2) == (0.4, 0.3)  # urdf/scara.urdf
    t1 = np.linspace(-3.0, 3.0, 20).reshape(4, 5)
    grid = np.stack([t1, np.zeros_like(t1)], axis=-1)
    e = sc.manipulability(params, grid)
    assert e.radii.shape == (4, 5, 2) and e.directions.shape == (4, 5, 2, 2) and e.singular.shape == (4, 5)
    np.testing.assert_allclose(e.radii[..., 0], 0.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(e.radii[..., 1], np.hypot(l1 + l2, l2), rtol=1e-15)  # 0.7616 m
    long_axis = np.stack([-np.sin(t1), np.cos(t1)], axis=-1)
    collapsed = np.stack([np.cos(t1), np.sin(t1)], axis=-1)
    for d, want in ((e.directions[..., 1, :], long_axis), (e.directions[..., 0, :], collapsed)):
        # unit and parallel to the expected axis (either sign): the 2D cross product is the sine
        # of the angle between them, first order in any error (a dot product would be second)
        np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, rtol=0, atol=1e-15)
        np.testing.assert_allclose(d[..., 0] * want[..., 1] - d[..., 1] * want[..., 0], 0.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(e.yoshikawa, 0.0, rtol=0, atol=1e-15)
    assert e.singular.all() and np.all(e.condition_number == np.inf)


def test_rejects_bad_jacobians():
    with pytest.raises(InvalidInputError):
        ellipsoid(np.array([[np.nan, 0.0], [0.0, 1.0]]))
    with pytest.raises(InvalidInputError):
        ellipsoid(np.zeros(3))
    with pytest.raises(InvalidInputError):
        ellipses_2x2(np.zeros((4, 3, 2)))


@pytest.mark.parametrize("robot", ["delta", "p2us"])
def test_cli_closed_loop_is_sent_to_jacobian_with_how(capsys, robot):
    # the refusal points every closed loop (not only the p2us) to `jacobian`, with its argument
    from kinematics.cli import main

    assert main(["manipulability", robot, "--q", "0.3", "0.3", "0.3"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "`jacobian`" in err and "--position" in err
