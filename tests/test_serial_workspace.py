"""Serial-arm workspaces: the guaranteed bounds against exact answers derived here."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from kinematics.analyses.serial_workspace import radii, serial_workspace
from kinematics.errors import InvalidInputError, KinematicsWarning, UnsupportedRobotError
from kinematics.generic.batched import batched_fk, configurations
from kinematics.generic.serial import forward_kinematics
from kinematics.mechanisms.scara.closed_form import ScaraParams, ik
from kinematics.model.robot import load_robot
from tests.test_workspace import scara_area_closed_form

MODELS = Path(__file__).parent / "models"
L2, L3 = 0.4, 0.25  # both test arms: upper arm and forearm [m] (tests/models/arm3r_*.urdf)


def _cells_of(w, y):
    return tuple(np.floor((y - w.grid.origin) / w.grid.cell).astype(int).T)


@pytest.fixture(scope="module")
def scara_ws(scara):
    return serial_workspace(scara, resolution=400)


def test_scara_area_within_error_estimate(scara, scara_ws):
    exact = scara_area_closed_form(ScaraParams.from_robot(scara))  # 0.97292658 m^2, quad at 1e-13
    w = scara_ws
    assert w.mode == "planar" and w.axes == (0, 1)
    pts = w.world_points("band")
    assert len(pts) == (w.touched & ~w.inside).sum() and np.all(pts[:, 2] == w.plane_offset)
    assert w.lower <= exact <= w.upper
    assert abs(w.measure - exact) <= w.error_estimate
    # The bound must also be useful: the half-gap at 400 cells across is ~3.5 % (docs).
    assert w.error_estimate <= 0.05 * exact


def test_scara_cells_agree_with_closed_form_ik(scara, scara_ws, rng):
    w, sp = scara_ws, ScaraParams.from_robot(scara)
    # Every reached point lies in a touched cell (the upper set covers W).
    values = rng.uniform(scara.lower, scara.upper, (20000, 2))
    p = batched_fk(scara, configurations(scara, values)).position[:, :2]
    assert w.touched[_cells_of(w, p)].all()
    # Every corner of every certified cell is reachable within the limits (closed-form IK).
    idx = np.argwhere(w.inside)
    corners = np.concatenate([w.grid.origin + (idx + np.array(c)) * w.grid.cell for c in [(0, 0), (0, 1), (1, 0), (1, 1)]])
    sol = ik(sp, corners)
    assert sol.within_limits.any(axis=-1).all()


def test_scara_dexterity_matches_radius(scara, scara_ws):
    """Yoshikawa's index of the 2R arm is l1 l2 |sin t2| with cos t2 = (r^2 - l1^2 - l2^2) / (2 l1 l2):
    a function of the radius only. The best over a cell lies within its range over the cell."""
    w, sp = scara_ws, ScaraParams.from_robot(scara)
    idx = np.argwhere(~np.isnan(w.yoshikawa))
    lo_c = w.grid.origin + idx * w.grid.cell
    hi_c = lo_c + w.grid.cell
    near = np.sqrt(np.maximum(0, np.maximum(lo_c, np.minimum(0, hi_c)) ** 2 * (lo_c > 0)
                              + np.minimum(hi_c, 0) ** 2 * (hi_c < 0)).sum(axis=1))
    far = np.sqrt(np.maximum(lo_c**2, hi_c**2).sum(axis=1))

    def yosh(r):
        c = np.clip((r**2 - sp.l1**2 - sp.l2**2) / (2 * sp.l1 * sp.l2), -1, 1)
        return sp.l1 * sp.l2 * np.sqrt(1 - c * c)

    # |sin t2| over [near, far] is unimodal in r (largest at r^2 = l1^2 + l2^2).
    r_peak = math.hypot(sp.l1, sp.l2)
    top = np.where((near <= r_peak) & (r_peak <= far), sp.l1 * sp.l2, np.maximum(yosh(near), yosh(far)))
    bottom = np.minimum(yosh(near), yosh(far))
    got = w.yoshikawa[tuple(idx.T)]
    assert np.all(got <= top + 1e-12) and np.all(got >= bottom - 1e-12)
    # Smallest radius and condition number are consistent with it: w = r_min r_max.
    k = w.condition_number[tuple(idx.T)]
    assert np.all(k >= 1)


def test_scara_singular_set_is_covered(scara, scara_ws, rng):
    """The stretched arm (t2 = 0) is singular; its image, the arc r = l1 + l2, must lie within
    the reported balls of the boxes that may hold a singular configuration."""
    w = scara_ws
    t1 = rng.uniform(scara.lower[0], scara.upper[0], 200)
    for a in t1:
        p = forward_kinematics(scara, scara.configuration([a, 0.0])).position[:2]
        gap = np.linalg.norm(w.singular_points - p, axis=1) - w.singular_radius
        assert gap.min() <= 1e-12
    # ... and the candidates are near t2 = 0 (the SCARA has no other singularity in its limits).
    assert np.abs(w.singular_configurations[:, 1]).max() < 0.3


def revolved_volume_closed_form(a1: float, a2: float, b1: float, b2: float) -> float:
    """Volume swept by the 2R arm (pitch t in [a1, a2], elbow e in [b1, b2] in (0, pi)) turning
    a full turn about the vertical axis through its shoulder, when the tip stays at x > 0.

    The map (t, e) -> (x, z) is one-to-one (the distance to the shoulder fixes e, then the angle
    fixes t), with |det| = L2 L3 sin e; Pappus: V = 2 pi int x dA with x = L2 cos t + L3 cos(t + e):
    V = 2 pi L2 L3 [L2 (sin a2 - sin a1)(cos b1 - cos b2) + L3 (G(a2) - G(a1))],
    G(a) = int_b1^b2 sin e sin(a + e) de = [e cos a / 2 - sin(a + 2e) / 4]_b1^b2.
    """
    def G(a: float) -> float:
        return (b2 * math.cos(a) / 2 - math.sin(a + 2 * b2) / 4) - (b1 * math.cos(a) / 2 - math.sin(a + 2 * b1) / 4)

    return 2 * math.pi * L2 * L3 * (L2 * (math.sin(a2) - math.sin(a1)) * (math.cos(b1) - math.cos(b2))
                                    + L3 * (G(a2) - G(a1)))


def test_revolved_volume_closed_form_vs_quadrature():
    from scipy.integrate import dblquad

    a1, a2, b1, b2 = -0.5, 0.8, 0.3, 1.5
    q, _ = dblquad(lambda e, t: 2 * math.pi * (L2 * math.cos(t) + L3 * math.cos(t + e)) * L2 * L3 * math.sin(e),
                   a1, a2, b1, b2, epsabs=1e-14, epsrel=1e-12)
    assert revolved_volume_closed_form(a1, a2, b1, b2) == pytest.approx(q, rel=1e-11)


def test_3r_solid_of_revolution_within_error_estimate():
    robot = load_robot(MODELS / "arm3r_revolved.urdf")
    exact = revolved_volume_closed_form(-0.5, 0.8, 0.3, 1.5)  # 0.331334 m^3
    w = serial_workspace(robot, "tip", resolution=400)
    assert w.mode == "revolved" and w.joints == ("pitch", "elbow") and w.fixed == ()
    np.testing.assert_allclose(w.axis_direction, [0, 0, 1], atol=1e-15)
    assert w.lower <= exact <= w.upper
    assert abs(w.measure - exact) <= w.error_estimate <= 0.05 * exact
    assert w.as_dict()["volume_m3"] == w.measure
    # Views: the swept certified cells are at the profile's (rho, z) about the z axis (through x = y = 0).
    pts = w.world_points("inside", turns=8)
    assert len(pts) == 8 * w.inside.sum()
    prof = np.stack([np.hypot(pts[:, 0], pts[:, 1]), pts[:, 2] - w.axis_origin[2]], axis=1)
    assert w.inside[_cells_of(w, prof)].all()


def test_3r_spherical_shell_segment_within_error_estimate(rng):
    """Limited yaw (width D = 1.2 rad < pi), full-turn pitch, elbow in [0.5, 2.0]: the tip is at
    r(e) = sqrt(L2^2 + L3^2 + 2 L2 L3 cos e) from the shoulder in any direction of the yawed arm
    planes, which cover azimuths [-0.6, 0.6] and the opposite wedge: V = (4 D / 3)(R^3 - r^3)
    with R = r(0.5), r = r(2.0) (two wedges of solid angle 2 D each)."""
    robot = load_robot(MODELS / "arm3r_wedge.urdf")

    def r(e: float) -> float:
        return math.sqrt(L2**2 + L3**2 + 2 * L2 * L3 * math.cos(e))

    exact = 4 * 1.2 / 3 * (r(0.5) ** 3 - r(2.0) ** 3)
    # The derived set holds every reached point (a check of the derivation, independent of it).
    values = rng.uniform([-0.6, -math.pi, 0.5], [0.6, math.pi, 2.0], (5000, 3))
    p = batched_fk(robot, configurations(robot, values), "tip").position - [0, 0, 0.3]
    dist = np.linalg.norm(p, axis=1)
    assert np.all((dist >= r(2.0) - 1e-12) & (dist <= r(0.5) + 1e-12))
    az = np.arctan2(p[:, 1], p[:, 0])
    assert np.all(np.minimum(np.abs(az), np.pi - np.abs(az)) <= 0.6 + 1e-12)

    w = serial_workspace(robot, "tip", resolution=32)
    assert w.mode == "spatial"
    assert w.touched[_cells_of(w, p + [0, 0, 0.3])].all()
    assert w.lower <= exact <= w.upper
    assert abs(w.measure - exact) <= w.error_estimate
    assert w.error_estimate <= 0.6 * exact  # 3D cells are coarse: the half-gap is ~52 % at 32 cells


def test_ur5_reduces_to_a_profile(rng):
    robot = load_robot("ur5")
    w = serial_workspace(robot, resolution=200, max_points=60_000)
    assert w.mode == "revolved"
    assert w.fixed == ("wrist_3_joint",)  # tool0 lies on the last joint's axis
    assert w.points_evaluated <= 60_000
    assert 0 < w.lower < w.upper
    # Random reached points, turned into the profile about the base axis, lie in touched cells
    # (the upper set covers W even when the budget is far too small to tighten it).
    values = rng.uniform(-2 * np.pi, 2 * np.pi, (20000, 6))
    values[:, 2] = rng.uniform(-np.pi, np.pi, 20000)
    p = batched_fk(robot, configurations(robot, values)).position - w.axis_origin
    z = p @ w.axis_direction
    rho = np.linalg.norm(p - z[:, None] * w.axis_direction, axis=1)
    assert w.touched[_cells_of(w, np.stack([rho, z], axis=1))].all()
    d = w.as_dict()
    for key in ("volume_m3", "error_estimate", "points_evaluated", "seconds"):
        assert key in d


def test_bad_inputs(scara):
    with pytest.raises(InvalidInputError, match="rtol"):
        serial_workspace(scara, rtol=0)
    with pytest.raises(InvalidInputError, match="cell"):
        serial_workspace(scara, cell=-1.0)
    with pytest.raises(InvalidInputError, match="max_points"):
        serial_workspace(scara, max_points=10)
    with pytest.raises(UnsupportedRobotError, match="closed-loop"):
        serial_workspace(load_robot("p2us"))


@pytest.mark.parametrize("m", [2, 3])
def test_radii_kernel_matches_svd(rng, m):
    """The kernel's closed-form singular values against LAPACK, including near-singular stacks
    (a row made nearly dependent: sigma_min down to ~1e-9 sigma_max)."""
    J = rng.normal(size=(400, m, 5))
    scale = np.logspace(-9, 0, 400)
    J[:, -1] = J[:, 0] + scale[:, None] * J[:, -1]
    s = np.linalg.svd(J, compute_uv=False)
    smin, smax, w = radii(J)
    np.testing.assert_allclose(smax, s[:, 0], rtol=1e-12)
    # LAPACK's sigma_min carries an absolute error of a few eps sigma_max: relative 1e-14 s0 / s_min.
    prod = np.prod(s, axis=1)
    assert np.all(np.abs(w - prod) <= (1e-11 + 1e-13 * s[:, 0] / s[:, -1]) * prod)
    # sigma_min: LAPACK's is good to ~eps s0 absolute, i.e. 1e-11 relative above 1e-4 s0.
    big = s[:, -1] > 1e-4 * s[:, 0]
    np.testing.assert_allclose(smin[big], s[big, -1], rtol=1e-10)
    assert np.all(smin <= s[:, -1] + 1e-14 * s[:, 0])  # never overstated beyond LAPACK's own error
    with pytest.raises(InvalidInputError):
        radii(np.zeros((3, 4, 4)))


# -- the reachability margin and the one volume engine (issue 29) ----------------------------------
def _profile_inside(rho: np.ndarray, h: np.ndarray) -> np.ndarray:
    """The revolved 3R arm's profile by closed-form 2R inverse kinematics (h: height above the
    shoulder): e = arccos((rho^2 + h^2 - L2^2 - L3^2) / 2 L2 L3), t from the tip's direction."""
    c = (rho**2 + h**2 - L2**2 - L3**2) / (2 * L2 * L3)
    e = np.arccos(np.clip(c, -1.0, 1.0))
    # pitch about +y turns x towards -z: rho = L2 cos t + L3 cos(t + e), h = -(L2 sin t + L3 sin(t + e))
    t = np.arctan2(-h, rho) - np.arctan2(L3 * np.sin(e), L2 + L3 * np.cos(e))
    return (np.abs(c) <= 1) & (e >= 0.3) & (e <= 1.5) & (t >= -0.5) & (t <= 0.8)


def test_reach_margin_sign_is_membership(rng):
    """The search's sign against membership derived in closed form, at random points: the
    revolved 3R arm (profile and 3-D margins) and the wedge arm (a spherical shell's wedges)."""
    from kinematics.mechanisms.serial.reach import Reach

    reach = Reach(load_robot(MODELS / "arm3r_revolved.urdf"), "tip")
    assert reach.setup.mode == "revolved"
    prof = rng.uniform([0.0, -0.5], [0.7, 0.5], (20000, 2))  # (rho, height above the shoulder)
    m = reach.profile_margin(prof + [0.0, 0.3 - reach.origin[2]])[:, 0]
    np.testing.assert_array_equal(m >= 0, _profile_inside(prof[:, 0], prof[:, 1]))
    p = rng.uniform([-0.7, -0.7, -0.2], [0.7, 0.7, 0.8], (20000, 3))
    rho, h = np.hypot(p[:, 0], p[:, 1]), p[:, 2] - 0.3
    np.testing.assert_array_equal(reach.margin(p)[:, 0] >= 0, _profile_inside(rho, h))

    wedge = Reach(load_robot(MODELS / "arm3r_wedge.urdf"), "tip")
    assert wedge.setup.mode == "spatial"

    def r(e: float) -> float:
        return math.sqrt(L2**2 + L3**2 + 2 * L2 * L3 * math.cos(e))

    p = rng.uniform(-0.7, 0.7, (20000, 3)) + [0, 0, 0.3]
    d = np.linalg.norm(p - [0, 0, 0.3], axis=1)
    az = np.arctan2(p[:, 1], p[:, 0])
    inside = (d >= r(2.0)) & (d <= r(0.5)) & (np.minimum(np.abs(az), np.pi - np.abs(az)) <= 0.6)
    np.testing.assert_array_equal(wedge.margin(p)[:, 0] >= 0, inside)


@pytest.mark.parametrize("bad", [np.zeros(3), np.zeros((1, 4)), np.zeros((1, 2)), np.array([[np.nan, 0.0, 0.3]])])
def test_a_serial_arms_margin_refuses_malformed_points(bad):
    """mechanism.margin()(points) on a serial arm checks the points before its search (numpy's
    AxisError, a broadcast ValueError or scipy's 'x must be finite' from the k-d tree, before);
    the profile margin of a solid of revolution takes (rho, z) pairs."""
    from kinematics.mechanisms import mechanism_of

    margin = mechanism_of(load_robot(MODELS / "arm3r_revolved.urdf", tool_frame="tip")).margin()
    with pytest.raises(InvalidInputError, match="points"):
        margin(bad)
    assert margin.profile is not None
    with pytest.raises(InvalidInputError, match=r"\(N, 2\)"):
        margin.profile.margin(np.zeros((1, 3)))


@pytest.fixture(scope="module")
def revolved_ws():
    from kinematics.analyses.workspace import measure_workspace
    from kinematics.mechanisms.serial.mechanism import SerialArm

    return measure_workspace(SerialArm(load_robot(MODELS / "arm3r_revolved.urdf")), step=0.01, rtol=1e-4,
                             check=True)


def test_revolved_volume_through_columns(revolved_ws):
    """Pappus on the profile (column weight 2 pi rho) against the closed form; the estimate holds."""
    exact = revolved_volume_closed_form(-0.5, 0.8, 0.3, 1.5)
    ws = revolved_ws
    assert ws.result.columns > 0 and not ws.planar
    assert abs(ws.total - exact) <= ws.error
    assert abs(ws.total - exact) <= 1e-4 * exact
    # converged means the reported error (with the check's difference) is within rtol, no less
    assert ws.result.converged == (ws.error <= 1e-4 * ws.total) == bool(ws.result.target_converged[-1])
    lo, hi = np.asarray(ws.as_dict()["bbox"])
    rmax = math.sqrt(L2**2 + L3**2 + 2 * L2 * L3 * math.cos(0.3))
    assert hi[0] <= rmax + 1e-9 and hi[0] >= rmax - 0.02  # the world box of the swept profile


def test_scara_area_through_the_serial_path(scara):
    """The SCARA as a generic open chain: its area through the same engine, against the closed form."""
    from kinematics.analyses.workspace import measure_workspace
    from kinematics.mechanisms.serial.mechanism import SerialArm

    exact = scara_area_closed_form(ScaraParams.from_robot(scara))  # 0.9729265761857 m^2
    ws = measure_workspace(SerialArm(scara), step=0.01, rtol=1e-5, check=True)
    assert ws.planar and abs(ws.total - exact) <= ws.error
    assert abs(ws.total - exact) <= 1e-4 * exact


def test_3d_search_budget_stops_honestly(monkeypatch):
    """The 3-D path (the wedge arm: base range 1.2 rad < pi) with the check run, at the CLI's
    rtol, on a search budget far below what it needs: it stops in the first run, not converged,
    the budget named as the reason, within about twice its budget, and its error estimate still
    covers the exact volume V = (4 D / 3)(r(0.5)^3 - r(2.0)^3) of the shell test. At 2 cm the
    usual start (8 cm intervals: 132 x 132 columns of 87 samples, ~1.5e6 searches) alone is 7x
    the budget: the start must be coarsened (engine.START_SHARE), and no check run follow; a
    warning says so at the start."""
    from kinematics.analyses.workspace import measure_workspace
    from kinematics.mechanisms.serial import reach as reach_module
    from kinematics.mechanisms.serial.mechanism import SerialArm

    def r(e: float) -> float:
        return math.sqrt(L2**2 + L3**2 + 2 * L2 * L3 * math.cos(e))

    exact = 4 * 1.2 / 3 * (r(0.5) ** 3 - r(2.0) ** 3)
    budget = 200_000
    monkeypatch.setattr(reach_module, "SEARCHES", budget)
    # the start's searches: 3 x 4 Gauss columns per 16 cm interval, 11 intervals over the 1.7 m box
    # each way, 87 samples per column (ceil(1.7 / 0.02) + 1, 1.7 / 0.02 rounding up): 132^2 x 87
    with pytest.warns(KinematicsWarning, match=r"needs 1,515,888 searches to start.*likely stop on its search budget"):
        ws = measure_workspace(SerialArm(load_robot(MODELS / "arm3r_wedge.urdf")), step=0.02, rtol=1e-3, check=True)
    res = ws.result
    assert not res.converged and res.out_of_budget is not None and res.out_of_budget[-1]
    why = ws.unconverged()["union"]
    assert "search budget" in why and "no check run" in why
    # the slices may finish a round begun: up to twice the budget (engine's `_run_sampled`), plus
    # one round of the roots' refinement; a check run would add up to 4x the budget
    assert res.points_evaluated <= 2.2 * budget
    assert abs(ws.total - exact) <= float(res.error[-1])
