"""Turn envelopes (kinematics.generic.turn_envelope) and the collision-aware volume of a serial
arm whose base turns a full turn beside a body fixed in the world (issue 30).

The envelope's bands are held to radii by hand (a box about the axis, an off-axis sphere) and to
random convex polytopes' points; the bracketed volume to the 3R arm of test_serial_collisions on a
square pedestal fixed below its base (the base link's box, 0.1 x 0.1 m, z -0.4 to -0.1 m):

* the upper bound leaves the pedestal's pairs out: the reach shell's volume 4/3 pi (0.7^3 - 0.1^3);
* the lower bound replaces the pedestal by the cylinder of its corners' radius 0.05 sqrt(2) m about
  the yaw axis (measured as the 64-gon prism around it): in the arm's plane (which holds the axis) its section is the rectangle |u| <= that
  radius, -0.4 <= z <= -0.1, and the arm is clear of it iff both links' segments are more than the
  capsules' radius R from the rectangle, for one of the two elbows: a profile integral by hand;
* the volume in 3-D (the search at the pedestal's every azimuth, another path) lies between them.
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinematics.analyses.collision_volume import measure_collision_workspace
from kinematics.analyses.collisions import collision_model_of
from kinematics.analyses.serial_collisions import turn_invariant
from kinematics.generic.capsules import AnalyticDistances
from kinematics.generic.turn_envelope import SIDES, axial, envelope_bands
from kinematics.mechanisms import mechanism_of
from kinematics.model.robot import load_robot

from .test_cli import run, run_json
from .test_serial_collisions import POST, RP, R, _arm3, _post_volume, _profile, _segment_distance

TALL = (0.05, -0.1, -0.4)
"""A pedestal's half side and its top and bottom heights [m] (the tall one binds link 1 too)."""
LOW = (0.04, -0.5, -0.7)
"""A low pedestal: only link 2's far end comes down to it."""
SHELL = 4 / 3 * math.pi * (0.7**3 - 0.1**3)
"""The 3R arm's kinematic volume [m^3]."""


def _pedestal_urdf(half: float, top: float, bottom: float, tilt: float = 0.0) -> str:
    """The 3R arm on a square pedestal (the base link's box), turned by `tilt` [rad] about x."""
    box = (f'<collision><origin xyz="0 0 {(top + bottom) / 2}" rpy="{tilt} 0 0"/><geometry><box size="{2 * half} {2 * half} '
           f'{top - bottom}"/></geometry></collision>')
    return _arm3(False).replace('<link name="base"/>', f'<link name="base">{box}</link>')


def _post_urdf() -> str:
    """The 3R arm with test_serial_collisions' post on its base link (fixed, not on the turret)."""
    arm = _arm3(True)
    start = arm.index('<link name="turret">') + len('<link name="turret">')
    post = arm[start:arm.index("</link>", start)]
    return arm.replace(f'<link name="turret">{post}</link>', '<link name="turret"/>').replace(
        '<link name="base"/>', f'<link name="base">{post}</link>')


def _rectangle_distance(a: np.ndarray, b: np.ndarray, half: float, top: float, bottom: float) -> np.ndarray:
    """Distances of 2-D segments ab (N, 2) from the rectangle |u| <= half, bottom <= z <= top:
    0 where an end is inside, else the least over its four edges (0 where one is crossed)."""
    def inside(p: np.ndarray) -> np.ndarray:
        return (np.abs(p[:, 0]) <= half) & (p[:, 1] >= bottom) & (p[:, 1] <= top)

    corners = [(-half, bottom), (half, bottom), (half, top), (-half, top)]
    d = np.full(len(a), np.inf)
    for k in range(4):
        c1 = np.tile(corners[k], (len(a), 1))
        c2 = np.tile(corners[(k + 1) % 4], (len(a), 1))
        d = np.minimum(d, _segment_distance(a, b, c1, c2))
    return np.where(inside(a) | inside(b), 0.0, d)


def _lower_volume(h: float, radius: float, top: float, bottom: float) -> float:
    """The 3R arm's volume clear of a coaxial cylinder of `radius` [m] between heights `bottom`
    and `top` by hand [m^3] (module docstring; midpoint rule over the profile: for the tall
    pedestal's corners h = 2e-3, 1e-3 and 5e-4 give 1.38662, 1.38646 and 1.38655 m^3)."""
    rho, z, e1, e2 = _profile(h)
    tool = np.stack([rho, z], axis=1)
    origin = np.zeros_like(tool)
    free = np.zeros(len(rho), dtype=bool)
    for e in (e1, e2):
        elbow = 0.4 * np.stack([np.cos(e), np.sin(e)], axis=1)
        free |= ((_rectangle_distance(origin, elbow, radius, top, bottom) > R)
                 & (_rectangle_distance(elbow, tool, radius, top, bottom) > R))
    return float(2 * math.pi * (rho * free).sum() * h * h)


def _check_lower(t: dict[str, Any], pedestal: tuple[float, float, float]) -> None:
    """The lower bound lies between the volumes by hand clear of the band's cylinder (the
    pedestal's corners' radius) and of the cylinder through its prism's corners (`SIDES`; a band
    against a capsule is its cylinder, the upper end), each with the bound's error estimate and the by-hand rule's
    spread (2e-4 m^3) added."""
    half, top, bottom = pedestal
    inner = half * math.sqrt(2)
    outer = inner / math.cos(math.pi / SIDES)
    slack = t["lower_error_estimate"] + 2e-4
    assert _lower_volume(1e-3, outer, top, bottom) - slack <= t["lower"]
    assert t["lower"] <= _lower_volume(1e-3, inner, top, bottom) + slack


def test_box_and_sphere_bands_by_hand():
    """A box about the axis, turned about it and placed anywhere along it: one band over its
    height, radius its corners' (sqrt(a^2 + b^2)); a sphere off the axis (a capsule of half length
    0 to the envelope): radius its centre's distance plus its radius, over its height."""
    import coal

    o, u = np.array([0.1, -0.2, 0.3]), np.array([0.0, 0.0, 1.0])
    box = coal.Box(0.2, 0.6, 0.4)  # full sides
    turn = pin.SE3(pin.utils.rotate("z", 0.7), np.array([0.1, -0.2, 1.0]))
    (band,) = envelope_bands(box, turn, o, u)
    assert band.radius == pytest.approx(math.hypot(0.1, 0.3), rel=1e-11)
    assert (band.lo, band.hi) == pytest.approx((0.5, 0.9), abs=1e-12)
    sphere = pin.SE3(np.eye(3), np.array([0.1 + 0.3, -0.2 + 0.4, 0.5]))
    (band,) = envelope_bands(coal.Sphere(0.05), sphere, o, u)
    assert band.radius == pytest.approx(0.5 + 0.05, rel=1e-11)
    assert (band.lo, band.hi) == pytest.approx((0.15, 0.25), abs=1e-12)


def test_a_stepped_mesh_is_bounded_by_its_own_triangles():
    """A flange and a shaft (coaxial cylinders of radius 0.1 m, z 0-0.02 m, and 0.05 m, z 0.02-0.12
    m, as triangle meshes, their vertices on the circles): bounded through the mesh, two bands, the
    flange's radius up to the slice holding z = 0.02 m (64 slices of 0.12 m: to 0.020625 m) and the
    shaft's above; through the mesh's convex hull (a cone between them) every band above the flange
    is wider."""
    import coal
    import trimesh

    flange = trimesh.creation.cylinder(radius=0.1, height=0.02)
    flange.apply_translation([0, 0, 0.01])
    shaft = trimesh.creation.cylinder(radius=0.05, height=0.1)
    shaft.apply_translation([0, 0, 0.07])
    both = trimesh.util.concatenate([flange, shaft])
    mesh = coal.BVHModelOBBRSS()
    mesh.beginModel(len(both.faces), len(both.vertices))
    tris, verts = coal.StdVec_Triangle(), coal.StdVec_Vec3s()
    for f in both.faces:
        tris.append(coal.Triangle(int(f[0]), int(f[1]), int(f[2])))
    for v in np.asarray(both.vertices):
        verts.append(v)
    mesh.addSubModel(verts, tris)
    mesh.endModel()
    mesh.buildConvexHull(True, "Qt")
    o, u = np.zeros(3), np.array([0.0, 0.0, 1.0])
    low, high = envelope_bands(mesh.convex, pin.SE3.Identity(), o, u, mesh=mesh)
    assert (low.lo, low.hi, high.hi) == pytest.approx((0.0, 0.12 * 11 / 64, 0.12), abs=1e-12)
    assert (low.radius, high.radius) == pytest.approx((0.1, 0.05), abs=2e-12)
    hull = envelope_bands(mesh.convex, pin.SE3.Identity(), o, u)
    assert all(b.radius > 0.06 for b in hull)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_bands_of_a_convex_polytope_hold_it_tightly(seed):
    """A random convex polytope (coal's hull of 12 random points) at a random placement: every
    point of it (its vertices and random convex combinations) lies inside some band, and each
    band's radius is the largest distance from the axis of the polytope's part between the band's
    two planes, found another way: trimesh cuts the hull by the two planes (capped) and the cut
    solid's vertices give it (rho is convex, so its largest value is at a vertex)."""
    import coal
    import trimesh

    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(12, 3)) * rng.uniform(0.05, 0.3, size=3)
    mesh = coal.BVHModelOBBRSS()
    mesh.beginModel(0, len(pts))
    mesh.addVertices(pts)
    mesh.endModel()
    mesh.buildConvexHull(True, "Qt")
    place = pin.SE3(pin.utils.rpyToMatrix(*rng.uniform(-math.pi, math.pi, 3)), rng.normal(size=3) * 0.3)
    o, u = rng.normal(size=3) * 0.1, np.array([0.0, 0.0, 1.0])
    bands = envelope_bands(mesh.convex, place, o, u)
    assert bands is not None and 1 <= len(bands) <= 4
    w = rng.dirichlet(np.ones(len(pts)), size=4000)
    world = np.vstack([pts, w @ pts]) @ place.rotation.T + place.translation
    z, rho = axial(world, o, u)
    held = np.zeros(len(world), dtype=bool)
    for b in bands:
        held |= (z >= b.lo - 1e-12) & (z <= b.hi + 1e-12) & (rho <= b.radius)
    assert held.all()
    hull = trimesh.convex.convex_hull(pts @ place.rotation.T + place.translation)
    for b in bands:
        part = hull.slice_plane(o + b.lo * u, u, cap=True).slice_plane(o + b.hi * u, -u, cap=True)
        # the radius is inflated by 1e-12 relative + 1e-12 m; trimesh's cut points carry ~1e-15 m
        assert axial(part.vertices, o, u)[1].max() == pytest.approx(b.radius, rel=1e-10, abs=1e-11)


def test_a_fixed_post_on_the_axis_keeps_the_profile(tmp_path):
    """test_serial_collisions' post on the base link instead of the turret: the post is a capsule
    on the yaw axis, unchanged by the yaw, so its pairs count as turn-invariant and the volume is
    measured on the profile, equal to the turret post's by hand (the same shape at every yaw)."""
    path = tmp_path / "post.urdf"
    path.write_text(_post_urdf())
    robot = load_robot(path)
    mech = mechanism_of(robot)
    dist = AnalyticDistances(collision_model_of(robot))
    assert dist.model.pair_links and all("base" in p for p in dist.model.pair_links)
    assert turn_invariant(robot, dist, mech.reach)
    cw = measure_collision_workspace(mech, robot, step=0.05, rtol=1e-3)
    assert cw.collision["turn"]["route"] == "profile"
    assert cw.workspace.result.converged
    assert abs(cw.workspace.total - _post_volume(1e-3)) <= cw.workspace.error + 2e-6
    assert (RP, POST) == (0.1, (-0.6, -0.05))  # the shape `_post_volume` integrates


@pytest.fixture
def few_restarts(monkeypatch):
    """No escalation past the first restarts where every configuration found collides: the 3R
    arm has two configurations per point (elbow up and down), which the first restarts find; the
    escalation's descents would only cost coal's cylinder-capsule distances."""
    import kinematics.analyses.serial_collisions as sc

    monkeypatch.setattr(sc, "ESCALATE", 1)


def test_low_pedestal_bracket_by_hand(tmp_path, capsys, few_restarts):
    """`workspace-volume --collisions --json` of the 3R arm on the low pedestal (turn "auto"):
    the bracket's half-width (~0.002 m^3) meets rtol 1e-2, so the answer is its midpoint,
    converged, on the profile: the lower bound is the volume clear of the corners' cylinder by
    hand (`_check_lower`), the upper the reach shell's (the pedestal's pairs left out: none other
    can collide), each within its error estimate; the error is the half-width plus the larger
    estimate."""
    path = tmp_path / "low.urdf"
    path.write_text(_pedestal_urdf(*LOW))
    code, d, err = run_json(capsys, "workspace-volume", str(path), "--collisions", "--step", "0.12", "--rtol", "1e-2")
    assert code == 0, err
    t = d["collisions"]["turn"]
    assert t["route"] == "envelope" and [e["link"] for e in t["enveloped"]] == ["base"]
    assert d["collisions"]["search"]["mode"] == "revolved"
    (band,) = t["enveloped"][0]["bands"]  # one band: the box's corners at every height
    assert band["radius_m"] == pytest.approx(LOW[0] * math.sqrt(2), abs=1e-11)  # inflated by ~1e-12 m
    assert (band["from_m"], band["to_m"]) == pytest.approx((LOW[2], LOW[1]), abs=1e-12)
    _check_lower(t, LOW)
    assert abs(t["upper"] - SHELL) <= t["upper_error_estimate"]
    assert d["volume_m3"] == pytest.approx(0.5 * (t["lower"] + t["upper"]), rel=1e-15)
    half = 0.5 * (t["upper"] - t["lower"])
    assert half == pytest.approx(t["half_width"], rel=1e-12) and 0.001 < half < 0.003
    assert d["error_estimate"] == pytest.approx(half + max(t["lower_error_estimate"], t["upper_error_estimate"]))
    assert d["converged"]
    assert [p["links"] for p in d["collisions"]["binding_pairs"]] == [["base", "link2"]]  # link 1 never reaches it


def test_a_banded_pedestal_pair_binds_once_with_all_its_bands(tmp_path, capsys, few_restarts):
    """The low pedestal tilted by 0.4 rad about x: its envelope has several bands (a tilted box's
    radius changes with height), each paired with link 1 and link 2, yet the report speaks of the
    robot's own pairs: 2 checked (base - link1, base - link2; link1 - link2 are adjacent), the band
    pairs counted apart, and base - link2 binds once under its own geometries. Its removal is
    measured with all its bands: link 1 (0.4 m from the shoulder, capsule radius 0.02 m) stays
    above z = -0.42 m, 0.07 m above the envelope's top (-0.49 m), so the union with base - link2
    alone is the lower bound; and every pair being the base's, the upper bound (its pairs left out)
    keeps none: it is the kinematic union. So removed = upper - lower, the two targets' root brackets (1e-3 rtol step
    = 1.2e-6 m, at most 4 ends per column, weighed by 2 pi rho over the profile's 1.54 m^2)
    differing by less than 1e-5 m^3. One band's removal alone (today's band pairs measured one by
    one) falls 1.3e-3 m^3 short or more."""
    path = tmp_path / "tilted.urdf"
    path.write_text(_pedestal_urdf(*LOW, tilt=0.4))
    code, d, err = run_json(capsys, "workspace-volume", str(path), "--collisions", "--step", "0.12", "--rtol", "1e-2",
                            "--turn", "envelope")
    assert code == 0, err
    c = d["collisions"]
    t = c["turn"]
    (body,) = t["enveloped"]
    bands = len(body["bands"])
    assert bands > 1
    assert c["pairs_checked"] == len(collision_model_of(load_robot(path)).pairs) == 2
    assert t["enveloped_pairs_checked"] == 2 * bands
    assert [(p["links"], p["geometries"]) for p in c["binding_pairs"]] == [(["base", "link2"], ["base_0", "link2_0"])]
    assert c["binding_not_measured_alone"] == [] and c["pairs_that_can_bind"] <= 2  # per pair (8 band columns)
    assert c["kinematic_volume"] == pytest.approx(t["upper"], abs=1e-12)
    assert c["binding_pairs"][0]["removed"] == pytest.approx(t["upper"] - t["lower"], abs=1e-5)


def test_prescan_counts_a_point_once_per_pair_of_band_columns():
    """`Prescan(pair_of=...)`: distance columns x - 0.5 and y - 0.5 standing for one pair, a third
    column (+1) for another, on a 4 x 4 grid over [0, 1]^2 all inside: the pair is negative where
    x or y < 0.5 (2 of the 4 values each): 16 - 2 x 2 = 12 points, not 8 + 8; the other pair never.
    Without `pair_of` the columns count apart."""
    from types import SimpleNamespace

    from kinematics.analyses.collision_prescan import Prescan

    margin = SimpleNamespace(
        branches=("all",), distances=SimpleNamespace(kinds=np.zeros(3)),
        kinematic=lambda pts: np.ones((len(pts), 1)),
        branch_distances=lambda pts, b, inside, signs=True: np.column_stack(
            [pts[inside, 0] - 0.5, pts[inside, 1] - 0.5, np.ones(int(inside.sum()))]))
    lo, hi = np.zeros(2), np.ones(2)
    grouped = Prescan(margin, lo, hi, 4, pair_of=np.array([0, 0, 1]))  # type: ignore[arg-type]
    np.testing.assert_array_equal(grouped.counts, [12, 0])
    assert grouped.active.tolist() == [True, False]
    np.testing.assert_array_equal(Prescan(margin, lo, hi, 4).counts, [8, 8, 0])  # type: ignore[arg-type]


def _number(text: str, before: str) -> tuple[float, float]:
    """The value and error printed as `V +/- E` right after `before` in `text`."""
    m = re.search(re.escape(before) + r"\s*([0-9.e+-]+) \+/- ([0-9.e+-]+)", text)
    assert m, (before, text)
    return float(m.group(1)), float(m.group(2))


def test_tall_pedestal_bracket_too_wide(tmp_path, capsys, few_restarts):
    """`--turn envelope --json` on the tall pedestal: the bracket is the answer, its lower bound by
    hand (`_check_lower`), its upper the shell's, half-width 0.023 of 1.41 m^3, wider than rtol
    1e-2: not converged (a finer step cannot narrow it)."""
    path = tmp_path / "tall.urdf"
    path.write_text(_pedestal_urdf(*TALL))
    code, d, err = run_json(capsys, "workspace-volume", str(path), "--collisions", "--step", "0.12", "--rtol", "1e-2",
                            "--turn", "envelope")
    assert code == 0, err
    t = d["collisions"]["turn"]
    assert t["route"] == "envelope"
    _check_lower(t, TALL)
    assert abs(t["upper"] - SHELL) <= t["upper_error_estimate"]
    assert 0.02 < t["half_width"] < 0.027
    assert not d["converged"] and "a smaller --step cannot help" in err


def test_tall_pedestal_auto_goes_3d_inside_the_bracket(tmp_path, capsys, monkeypatch, few_restarts):
    """`workspace-volume --collisions` (turn "auto", the human report) on the tall pedestal: the
    bracket estimated on the pre-scan's grid is wider than rtol 1e-2, so the volume is measured in
    3-D at once (the search at the pedestal's every azimuth, another path to the same set), and
    lies inside the bracket by hand (the lower bound clear of the prism's corners' cylinder, the
    upper the shell's) within its error estimate. The 3-D run is held to 20,000 searches (its cost
    is test_serial_collisions' business): it stops on that budget, its error estimate covering."""
    import kinematics.analyses.serial_collisions as sc

    monkeypatch.setattr(sc, "SEARCHES", 20_000)
    path = tmp_path / "tall.urdf"
    path.write_text(_pedestal_urdf(*TALL))
    code, out, err = run(capsys, "workspace-volume", str(path), "--collisions", "--step", "0.12", "--rtol", "1e-2")
    assert code == 0, err
    assert "search                      : in 3-D" in out
    found = re.search(r"fixed bodies +: the turn envelope's bracket, estimated on the pre-scan's grid \(half-width "
                      r"([0-9.]+) m\^3\), is wider than the tolerance: measured in 3-D", out)
    assert found and 0.01 < float(found.group(1)) < 0.04  # the grid's estimate of 0.023 (48 x 48 points)
    volume, error = _number(out, "volume [m^3]                :")
    half, top, bottom = TALL
    lower = _lower_volume(1e-3, half * math.sqrt(2) / math.cos(math.pi / SIDES), top, bottom)
    assert lower - 2e-4 - error <= volume <= SHELL + error


def test_turn_flag_only_for_a_serial_arm_with_collisions(capsys):
    """`--turn` other than auto without --collisions, or on a robot that is not a serial arm: one
    line naming the flag, exit 2."""
    for argv in (["workspace-volume", "ur5", "--turn", "spatial"],
                 ["workspace-volume", "p2us", "--collisions", "--turn", "envelope"]):
        code, out, err = run(capsys, *argv)
        assert code == 2 and out == "" and err.count("\n") == 1 and "--turn" in err, (argv, err)


def test_envelope_asked_where_it_cannot_apply_warns(tmp_path):
    """`turn="envelope"` where no envelope can be built, the arm then measured in 3-D: one
    `KinematicsWarning` saying why (a half-space wall beside the 3R arm: its normal is not along
    the base axis; the 3R arm with its base limited to +-2 rad: no full turn, searched in 3-D); none with "auto",
    which chooses the route itself."""
    import warnings

    from kinematics.analyses.serial_collisions import serial_margin
    from kinematics.errors import KinematicsWarning
    from kinematics.generic.obstacles import load_obstacles

    (tmp_path / "arm3.urdf").write_text(_arm3(False))
    (tmp_path / "wall.yaml").write_text("obstacles:\n  - {name: wall, halfspace: [-1, 0, 0, -0.35]}\n")
    (tmp_path / "part.urdf").write_text(_arm3(True).replace(
        f'<axis xyz="0 0 1"/><limit lower="{-math.pi}" upper="{math.pi}"',
        '<axis xyz="0 0 1"/><limit lower="-2" upper="2"', 1))
    cases = [("arm3.urdf", load_obstacles(tmp_path / "wall.yaml"), "no turn envelope"),
             ("part.urdf", None, "no full base turn")]
    for name, obstacles, why in cases:
        robot = load_robot(tmp_path / name)
        mech = mechanism_of(robot)
        model = collision_model_of(robot, obstacles, True)
        dist = AnalyticDistances(model)
        with pytest.warns(KinematicsWarning, match=why):
            margin, env = serial_margin(mech, robot, model, dist, "envelope")
        assert env is None and margin.reach.setup.mode == "spatial"
        with warnings.catch_warnings():
            warnings.simplefilter("error", KinematicsWarning)
            assert serial_margin(mech, robot, model, dist, "auto")[1] is None
