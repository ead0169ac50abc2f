"""`singularities ROBOT --collisions` / `--obstacles FILE` for serial arms
(kinematics.analyses.serial_singular_collisions): each listed singular box judged at its centre,
the base angles at which it is free, the box bound; held to conditions derived by hand on the 3R
arm of test_serial_collisions (full-turn yaw, pitch and elbow in a vertical plane, capsules) and
to coal's own collision checks on the ur5's meshes.

By hand, for the 3R arm at (yaw psi, pitch t, elbow e): pitch about y sends the link's x axis to
(cos t, 0, -sin t), so the elbow E and the tool P have in-plane horizontal coordinates
u_E = L1 cos t, u_P = u_E + L2 cos(t + e) and heights z_E = -L1 sin t, z_P = z_E - L2 sin(t + e);
the yaw turns that plane, a point's world x being u cos psi.
"""

from __future__ import annotations

import json
import math

import numpy as np

from kinematics.analyses.collisions import collision_model_of
from kinematics.analyses.serial_singular_collisions import STEP, singular_collisions
from kinematics.analyses.serial_workspace import serial_workspace
from kinematics.model.robot import load_robot

from .test_cli import run, run_json
from .test_serial_collisions import L1, L2, POST, RP, WALL, R, _arm3, _segment_distance, arm3  # noqa: F401 (a fixture)

C = WALL - R
"""A capsule along a segment clears the wall x >= WALL iff the segment's largest x is below C [m]."""


def _plane(q: np.ndarray) -> tuple[np.ndarray, ...]:
    """u_E, u_P, z_E, z_P [m] of configurations q (K, 3) = (yaw, pitch, elbow) (module docstring)."""
    t, e = q[:, 1], q[:, 2]
    ue, ze = L1 * np.cos(t), -L1 * np.sin(t)
    return ue, ue + L2 * np.cos(t + e), ze, ze - L2 * np.sin(t + e)


def _wall_gap(q: np.ndarray) -> np.ndarray:
    """C - the arm's largest x at configurations q (K, 3) [m]: > 0 exactly where it clears the wall
    (link 1 starts on the yaw axis, x = 0 < C)."""
    ue, up, _, _ = _plane(q)
    return C - np.maximum(ue, up) * np.cos(q[:, 0])


def _free_turn(q: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """(K, M) the arm clears the wall at base angle psi[m] with pitch and elbow of q[k]."""
    ue, up, _, _ = _plane(q)
    c = np.cos(psi)[None, :]
    return (ue[:, None] * c < C) & (up[:, None] * c < C)


def test_wall_flags_and_free_base_angles_by_hand(arm3, capsys, rng):  # noqa: F811
    """The 3R arm beside the wall (the wall does not turn with the yaw): each listed box's centre
    collides at its listed yaw exactly where the arm's largest x reaches C; every certified free
    base-angle interval lies in the free set by hand, and falls short of it by a few steps at
    most (the bisection stops at STEP beside each of the at most 4 ends of the free set); a box
    certified free holds only free configurations (random ones in it, by hand)."""
    code, d, err = run_json(capsys, "singularities", str(arm3 / "arm3.urdf"), "--obstacles", str(arm3 / "wall.yaml"),
                            "--max-points", "100000")
    assert code == 0, err
    c = d["collisions"]
    assert (c["base_angle"], c["base_joint"], c["obstacles"]) == ("varies", "yaw", ["wall"])
    pts = d["singular_points"]
    q = np.array([p["q"] for p in pts])
    gap = _wall_gap(q)
    sure = np.abs(gap) > 1e-9
    got = np.array([p["colliding"] for p in pts])
    assert sure.all() and got.any() and (~got).any()
    assert np.array_equal(got, gap < 0)
    assert c["colliding_points"] == got.sum() and c["singular_points"] == len(pts) == 200
    ue, up, ze, zp = _plane(q)  # each listed position is the centre's tool, at its listed yaw
    where = np.stack([up * np.cos(q[:, 0]), up * np.sin(q[:, 0]), zp], axis=1)
    assert np.allclose([p["position"] for p in pts], where, rtol=0, atol=1e-12)
    for p, a, b in zip(pts, ue, up, strict=True):  # the tool's link binds where it reaches farther
        if p["colliding"] and abs(a - b) > 1e-9:
            assert p["pair"] == ["link2" if b > a else "link1", "wall"]
    short = _shortfalls(pts, q)
    assert max(short) < 8 * STEP and np.mean(short) < 2 * STEP
    verdicts = [p["base_angles"]["free"] for p in pts]
    assert c["free_at_every_base_angle"] == verdicts.count("every") and c["free_at_no_base_angle"] == 0
    assert c["any_collision_free"]
    # the box bound by hand: turning the pitch by dt moves link 1's points by at most (L1 + R) dt
    # and link 2's by (L1 + L2 + R) dt, the elbow link 2's by (L2 + R) de; the wall's gaps at the
    # centre are C - max(0, u_E) (link 1) and C - max(u_E, u_P) (link 2); the code's rates come
    # from the capsules' bounding spheres, at most 1 % above these (sqrt(2 R^2 + (L/2 + R)^2) for
    # L/2 + R): a box it settles clears the hand bound, and one clearing 1.01 x it is settled
    w = np.array([p["half_width"] for p in pts])
    assert (w[:, 0] == 0).all()  # the yaw: every angle stands for itself (the base-angle search)
    g1, g2 = C - np.maximum(0, ue), C - np.maximum(ue, up)
    b1, b2 = (L1 + R) * w[:, 1], (L1 + L2 + R) * w[:, 1] + (L2 + R) * w[:, 2]
    settled = np.array([p["box_free"] for p in pts])
    assert settled.sum() > len(pts) // 4 and c["boxes_certified_free"] == settled.sum()
    assert ((g1 > b1) & (g2 > b2))[settled].all()
    assert settled[(g1 > 1.01 * b1) & (g2 > 1.01 * b2)].all()
    for p in np.array(pts)[settled]:  # random configurations of a settled box clear the wall
        box = np.array(p["q"]) + rng.uniform(-1, 1, (200, 3)) * np.array(p["half_width"])
        assert (_wall_gap(box) > 0).all()


def _shortfalls(pts: list, q: np.ndarray, exact: bool = True) -> np.ndarray:
    """Per listed point of the 3R arm beside the wall, how much of the free turn by hand (on a
    72,000-angle grid) its certified free base-angle intervals miss [rad], after checking every
    interval lies in that free set and the verdict is "every" or "some" as it is whole or not
    (not `exact`: "every" only where it is whole; a coarse step may leave a thin gap uncertified)."""
    psi = np.linspace(-math.pi, math.pi, 72_000, endpoint=False)
    free = _free_turn(q, psi)
    true = free.mean(axis=1) * 2 * math.pi
    short = []
    for k, p in enumerate(pts):
        b = p["base_angles"]
        for lo, hi in b["free_intervals"]:
            inside = (psi >= lo) & (psi <= hi)
            assert free[k, inside].all(), (p, lo, hi)
        assert b["free_rad"] <= true[k] + 2 * math.pi / 72_000  # the grid's own spacing
        short.append(true[k] - b["free_rad"])
        if exact or b["free"] == "every" or not free[k].all():  # the yaw at pi/2 puts the arm at x = 0
            assert b["free"] == ("every" if free[k].all() else "some")
    return np.array(short)


def test_base_step_deg_sets_the_finest_base_angle_interval(arm3, capsys):  # noqa: F811
    """--base-step-deg 6 (the default 1): the intervals stay inside the free set by hand and fall
    short of it by a few of the coarser steps at most, so they miss more of it than at 1 degree
    (each of the free set's ends costs up to a step); the JSON gives the step in radians, the
    human report in degrees."""
    urdf, wall = str(arm3 / "arm3.urdf"), str(arm3 / "wall.yaml")
    short = {}
    for deg in (None, 6):
        code, d, err = run_json(capsys, "singularities", urdf, "--obstacles", wall, "--max-points", "20000",
                                *(["--base-step-deg", str(deg)] if deg else []))
        assert code == 0 and "warning" not in err, err
        step = math.radians(deg or 1)
        assert abs(d["collisions"]["base_angle_step_rad"] - step) < 1e-15
        pts = d["singular_points"]
        short[deg] = s = _shortfalls(pts, np.array([p["q"] for p in pts]), exact=deg is None)
        assert max(s) < 8 * step and np.mean(s) < 2 * step
    # each end of a free set is missed by up to a step, ~ half a step on average: 6 times the step,
    # several times the shortfall (0.64 deg on average at 1 deg, 5.8 deg at 6 deg when written)
    assert np.mean(short[6]) > 3 * np.mean(short[None])
    code, out, err = run(capsys, "singularities", urdf, "--obstacles", wall, "--max-points", "20000",
                         "--base-step-deg", "6")
    assert code == 0 and "(base-angle step 6 deg)" in out, err


def test_base_step_deg_bad_input(arm3, capsys):  # noqa: F811
    """--base-step-deg not finite, not positive or over 90, or without collisions, or on a robot
    with closed forms: one line on stderr naming the valid range or use, exit 2."""
    urdf, wall = str(arm3 / "arm3.urdf"), str(arm3 / "wall.yaml")
    for bad in ("0", "-1", "nan", "inf", "90.5", "1e9", "one"):
        code, _, err = run(capsys, "singularities", urdf, "--obstacles", wall, "--base-step-deg", bad)
        assert code == 2 and len(err.strip().splitlines()) == 1 and "--base-step-deg" in err, (bad, err)
        assert "(0, 90] degrees" in err or "number of degrees" in err, err
    for argv in ([urdf], ["scara", "--collisions"]):
        code, _, err = run(capsys, "singularities", *argv, "--base-step-deg", "5")
        assert code == 2 and len(err.strip().splitlines()) == 1, err
        assert "--base-step-deg" in err and "--collisions or --obstacles" in err, err


def test_post_turning_with_the_arm_is_invariant(arm3, capsys):  # noqa: F811
    """The post on the turret turns with the yaw (self-collisions only): every verdict holds at
    every base angle, and each centre collides exactly where link 2's segment comes within
    R + RP of the post's, in the arm's plane by hand."""
    code, d, err = run_json(capsys, "singularities", str(arm3 / "arm3p.urdf"), "--collisions",
                            "--max-points", "100000")
    assert code == 0, err
    c = d["collisions"]
    assert c["base_angle"] == "invariant" and c["pairs_checked"] == 1
    pts = d["singular_points"]
    assert all("base_angles" not in p for p in pts)
    ue, up, ze, zp = _plane(np.array([p["q"] for p in pts]))
    n = len(pts)
    gap = _segment_distance(np.stack([ue, ze], 1), np.stack([up, zp], 1), np.tile([0.0, POST[0]], (n, 1)),
                            np.tile([0.0, POST[1]], (n, 1))) - (R + RP)
    got = np.array([p["colliding"] for p in pts])
    assert (np.abs(gap) > 1e-9).all() and got.any() and (~got).any()
    assert np.array_equal(got, gap < 0)
    assert all(p["pair"] == ["turret", "link2"] for p in pts if p["colliding"])
    assert c["any_collision_free"] and c["colliding_points"] == got.sum()


def test_post_and_wall_together(arm3, capsys):  # noqa: F811
    """The post (turning with the yaw) and the wall (not): a centre whose link 2 meets the post
    collides at every base angle ("none", by the segment distance by hand), the others' verdicts
    are the wall's by hand, their certified intervals inside its free set."""
    code, d, err = run_json(capsys, "singularities", str(arm3 / "arm3p.urdf"), "--collisions", "--obstacles",
                            str(arm3 / "wall.yaml"), "--max-points", "100000")
    assert code == 0, err
    assert d["collisions"]["base_angle"] == "varies"
    pts = d["singular_points"]
    q = np.array([p["q"] for p in pts])
    ue, up, ze, zp = _plane(q)
    n = len(pts)
    post = _segment_distance(np.stack([ue, ze], 1), np.stack([up, zp], 1), np.tile([0.0, POST[0]], (n, 1)),
                             np.tile([0.0, POST[1]], (n, 1))) - (R + RP)
    psi = np.linspace(-math.pi, math.pi, 7200, endpoint=False)
    wall = _free_turn(q, psi)
    verdicts = np.array([p["base_angles"]["free"] for p in pts])
    assert (np.abs(post) > 1e-9).all() and (post < 0).any() and (post > 0).any()
    assert (verdicts[post < 0] == "none").all()
    assert np.array_equal(verdicts[post > 0], np.where(wall[post > 0].all(axis=1), "every", "some"))
    for k in np.flatnonzero(post > 0):
        for lo, hi in pts[k]["base_angles"]["free_intervals"]:
            assert wall[k, (psi >= lo) & (psi <= hi)].all()
    assert d["collisions"]["free_at_no_base_angle"] == (post < 0).sum()
    # the human table says so in words: a box shown colliding with the post is free at no base angle
    code, out, err = run(capsys, "singularities", str(arm3 / "arm3p.urdf"), "--collisions", "--obstacles",
                         str(arm3 / "wall.yaml"), "--max-points", "100000")
    shown = verdicts[:: max(1, n // 10)]
    assert code == 0 and (shown == "none").any(), err
    assert out.count("; free at no base angle\n") + out.count("; free at no base angle;") == (shown == "none").sum()
    assert out.count("; free at some base angles") == (shown == "some").sum() and "at none base" not in out


def test_base_turning_less_than_a_turn_keeps_its_listed_angle(arm3, capsys):  # noqa: F811
    """A yaw of range [-1, 1] rad: the scan is spatial, the yaw one of the box's joints, so each
    verdict is the listed configuration's own (its listed yaw), by hand; --base-step-deg, given,
    is unused and a warning says so."""
    code, d, err = run_json(capsys, "singularities", str(arm3 / "arm3.urdf"), "--obstacles", str(arm3 / "wall.yaml"),
                            "--range", "yaw=-1:1", "--max-points", "100000", "--base-step-deg", "5")
    assert code == 0 and err.startswith("warning: --base-step-deg unused") and err.count("\n") == 1, err
    assert "base_angle_step_rad" not in d["collisions"]
    assert d["mode"] == "spatial" and d["collisions"]["base_angle"] == "in the configuration"
    q = np.array([p["q"] for p in d["singular_points"]])
    gap = _wall_gap(q)
    got = np.array([p["colliding"] for p in d["singular_points"]])
    assert np.ptp(q[:, 0]) > 1 and got.any() and (~got).any()
    assert np.array_equal(got[np.abs(gap) > 1e-9], gap[np.abs(gap) > 1e-9] < 0)


def test_human_report_and_bad_input(arm3, capsys, tmp_path):  # noqa: F811
    """The human report gives the counts; obstacles nothing can touch: exit 2, one line."""
    code, out, err = run(capsys, "singularities", str(arm3 / "arm3.urdf"), "--obstacles", str(arm3 / "wall.yaml"),
                         "--max-points", "20000")
    assert code == 0, err
    assert "colliding singular configurations:" in out and "free at every base angle" in out
    assert "whole boxes certified free:" in out
    # the table's collision column says what the JSON says of each point it shows (every len // 10-th)
    code, js, err = run(capsys, "singularities", str(arm3 / "arm3.urdf"), "--obstacles", str(arm3 / "wall.yaml"),
                        "--max-points", "20000", "--json")
    points = json.loads(js)["singular_points"]
    shown = points[:: max(1, len(points) // 10)]
    table = out.split("collisions (centre)", 1)[1]
    assert table.count("colliding (") == sum(p["colliding"] for p in shown) > 0
    assert table.count("; free at ") == sum("base_angles" in p for p in shown) > 0
    bare = tmp_path / "bare.urdf"
    bare.write_text(_arm3(False).replace("<collision>", "<!--").replace("</collision>", "-->"))
    code, out, err = run(capsys, "singularities", str(bare), "--obstacles", str(arm3 / "wall.yaml"))
    assert code == 2 and err.count("\n") == 1 and "nothing can touch the obstacles" in err


def test_ur5_verdicts_against_coal(rng):
    """The ur5 with self-collisions (its base link's pairs change with the base angle): at each
    listed centre, `colliding` is coal's own verdict on the URDF's meshes (pin.computeCollisions
    over the same link pairs), the binding pair one coal finds in collision; at the ends of the
    certified free base-angle intervals and at random angles inside them coal finds no collision;
    a centre colliding at every base angle ("none") collides at random angles by coal."""
    import pinocchio as pin

    from kinematics.generic.batched import configurations
    from kinematics.model.geometry import geometry_model

    robot = load_robot("ur5")
    ws = serial_workspace(robot, max_points=20_000)
    idx = np.linspace(0, len(ws.singular_radius) - 1, 24).astype(int)
    values = ws.singular_configurations[idx]
    model = collision_model_of(robot)
    res = singular_collisions(robot, ws, model, values, ws.singular_half_widths[idx])
    assert res.base_angle == "varies" and robot.dofs[res.base_joint].name == "shoulder_pan_joint"
    geom = geometry_model(robot, "collision")[0]
    links = [robot.model.frames[g.parentFrame].name for g in geom.geometryObjects]
    wanted = {frozenset(p) for p in model.pair_links}
    for i in range(geom.ngeoms):
        for k in range(i + 1, geom.ngeoms):
            if frozenset((links[i], links[k])) in wanted:
                geom.addCollisionPair(pin.CollisionPair(i, k))
    data, gdata = robot.model.createData(), pin.GeometryData(geom)

    def hits(v: np.ndarray) -> set[frozenset[str]]:
        pin.computeCollisions(robot.model, data, geom, gdata, configurations(robot, v[None])[0], False)
        return {frozenset((links[p.first], links[p.second])) for p, r in
                zip(geom.collisionPairs, gdata.collisionResults, strict=True) if r.isCollision()}

    flags = []
    for k, v in enumerate(values):
        found = hits(v)
        flags.append(bool(found))
        assert res.colliding[k] == bool(found), k
        if found:
            assert frozenset(model.pair_links[int(res.pair[k])]) in found
        for lo, hi in res.free_intervals[k]:  # its ends (beside a colliding angle) and within
            for psi in (lo + 1e-9, hi - 1e-9, *rng.uniform(lo, hi, 2)):
                w = v.copy()
                w[res.base_joint] = psi
                assert not hits(w), (k, w)
    assert any(flags) and not all(flags)
    assert set(res.verdict) >= {"every", "some", "none"}
    for k in np.flatnonzero(res.verdict == "none"):  # a pair the base's turn leaves alone collides
        for psi in rng.uniform(-math.pi, math.pi, 3):
            w = values[k].copy()
            w[res.base_joint] = psi
            assert hits(w), (k, w)
