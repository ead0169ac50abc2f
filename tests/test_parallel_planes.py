"""Planar or spatial decided once for every command (`kinematics.mechanisms.plane_of`), and the iso
five-bars' two assemblies, whose tips move in two parallel planes, each a branch of the batched
solver and each plane's area measured (the union: their sum)."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

from kinematics.cli.app import main
from kinematics.model.robot import load_robot

from .conftest import GEPETTO

needs_models = pytest.mark.skipif(not GEPETTO.is_dir(), reason=f"Gepetto's models are not at {GEPETTO}")

PI = "3.141592653589793"


def _plane_fields(capsys, args: list[str]) -> object:
    assert main([*args, "--json"]) == 0
    return json.loads(capsys.readouterr().out)["plane"]


@needs_models
@pytest.mark.parametrize("name", ["5bar_linkage_iso3d", "5bar_linkage_iso6d", "battobot_6d"])
def test_every_command_reports_one_plane(name, capsys, tmp_path):
    """info, fk, jacobian, mobility and show report the same plane (or null); the workspace's task
    axes are that plane's. The iso five-bars' tips stay at y = -0.2 m (their default assembly),
    checked here on Pinocchio's closure solver at disturbed actuators, not on the plane test."""
    from kinematics.generic.closedloop import ClosedLoop
    from kinematics.mechanisms import mechanism_of

    path = str(GEPETTO / name)
    got = {cmd: _plane_fields(capsys, [cmd, path]) for cmd in ("info", "fk", "jacobian", "mobility")}
    got["show"] = _plane_fields(capsys, ["show", path, "--export", str(tmp_path / "v.html")])
    assert len({json.dumps(v, sort_keys=True) for v in got.values()}) == 1, got
    plane = got["info"]
    if name == "battobot_6d":
        assert plane is None
        assert main(["info", path]) == 0 and ", spatial" in capsys.readouterr().out
        return
    assert plane["axes"] == ["x", "z"] and plane["normal"] == "y" and plane["decided_on"] == "closed motion"
    robot = load_robot(GEPETTO / name)
    loop = ClosedLoop(robot)
    a0 = robot.values_from_configuration(loop.reference)[loop.actuated_dofs]
    rng = np.random.default_rng(3)
    y = [loop.solve(a0 + rng.uniform(-0.3, 0.3, 2), q0=loop.reference).pose.translation[1] for _ in range(3)]
    np.testing.assert_allclose(y, plane["offset_m"], rtol=0, atol=1e-9)  # closure to 1e-10 m
    assert main(["info", path]) == 0 and "planar in x-z at y = -0.2 m" in capsys.readouterr().out
    assert mechanism_of(robot).task_axes == ("x", "z")  # what workspace-volume measures in


def _grid(lo: np.ndarray, hi: np.ndarray, n: int) -> tuple[np.ndarray, float]:
    h = (hi - lo) / n
    g = np.meshgrid(*(lo[i] + h[i] * (np.arange(n) + 0.5) for i in range(2)), indexing="ij")
    return np.stack(g, axis=-1).reshape(-1, 2), float(h[0] * h[1])


def _iso_plane_reference(robot, ortho: float, n: int) -> tuple[float, float]:
    """(area [m^2], plane's y [m]) of the iso five-bar's assembly with `freeortho` = ortho, by
    counting the centres of an n x n grid from the URDF's geometry alone. Chain 1 (mot1 at A1,
    free1 at B1, then freeortho, fixed in the assembly) carries the effector E and the closure
    point P on one body; chain 2 (free2 at A2, mot2 at B2) carries the closure's other point Q.
    The joints' axes are all along y, so in-plane (x, z) distances between them and the points do
    not depend on the joint values: they are read at the neutral pose with freeortho set, loops
    open. For a point E, B1 is on circle(A1, a1) at distance e from E (two choices); the body's
    fixed angle then places P, which chain 2 must reach (|P - A2| within its annulus). Ranges are
    full turns, the passive joints unbounded: reach is the only limit."""
    reach = _iso_reach(robot, ortho)
    E, cell = _grid(reach["A1"] - (reach["a1"] + reach["e"]), reach["A1"] + (reach["a1"] + reach["e"]), n)
    return float((_iso_inside(robot, ortho, E) >= 0).sum() * cell), reach["y"]


def _iso_closure_points(robot, d) -> tuple[np.ndarray, np.ndarray]:
    """World positions [m] of the closure's two points at a pose whose loop is open (data d after
    framesForwardKinematics). iso3d's point closure: its frames closedloop3D_1A (chain 1) and
    closedloop3D_1B (chain 2). iso6d's 6D closure welds closedloop6D_1A (on part_6, behind a
    spherical joint of three concurrent revolutes at the point S of chain 1's body part_4) to
    closedloop6D_1B (on chain 2's part_5): P = S, the revolutes' common origin, and Q = the point of
    part_5 where S lands when the two frames coincide, oMf[1B] 1A^-1 (1A's placement in part_6)."""
    m = robot.model
    if robot.model.existFrame("closedloop3D_1A"):
        return (np.array(d.oMf[robot.frame_id("closedloop3D_1A")].translation),
                np.array(d.oMf[robot.frame_id("closedloop3D_1B")].translation))
    a = m.frames[robot.frame_id("closedloop6D_1A")]
    S = d.oMi[m.getJointId("part_4_part_6_rev0")].translation
    for name in ("part_4_part_6_rev1", "part_4_part_6_rev2"):  # concurrent: one centre
        assert np.linalg.norm(d.oMi[m.getJointId(name)].translation - S) <= 1e-12
    assert m.names[a.parentJoint] == "part_4_part_6_rev2"
    return np.array(S), np.array((d.oMf[robot.frame_id("closedloop6D_1B")] * a.placement.inverse()).translation)


def _iso_reach(robot, ortho: float) -> dict[str, Any]:
    """The in-plane geometry `_iso_plane_reference` describes, read at the neutral pose with
    freeortho = ortho: joint centres A1, A2, link lengths a1, e, b1, a2, b2, the body's fixed angle
    delta at B1 between E and P, and the plane's y [m]. P and Q (`_iso_closure_points`) lie at one
    y: the closure is in-plane."""
    m = robot.model
    d = m.createData()
    q = pin.neutral(m)
    q[m.joints[m.getJointId("freeortho")].idx_q] = ortho
    pin.framesForwardKinematics(m, d, q)

    def xz(v: np.ndarray) -> np.ndarray:
        return np.array([v[0], v[2]])

    A1, B1, A2, B2 = (xz(d.oMi[m.getJointId(k)].translation) for k in ("mot1", "free1", "free2", "mot2"))
    P3, Q3 = _iso_closure_points(robot, d)
    assert abs(P3[1] - Q3[1]) <= 1e-12, (P3, Q3)
    P0, Q0, E0 = xz(P3), xz(Q3), xz(d.oMf[robot.frame_id("effector")].translation)
    return {"A1": A1, "A2": A2, "a1": float(np.linalg.norm(B1 - A1)), "e": float(np.linalg.norm(E0 - B1)),
            "b1": float(np.linalg.norm(P0 - B1)), "a2": float(np.linalg.norm(B2 - A2)),
            "b2": float(np.linalg.norm(Q0 - B2)), "delta": float(_angle(P0 - B1) - _angle(E0 - B1)),
            "y": float(d.oMf[robot.frame_id("effector")].translation[1])}


def _angle(v: np.ndarray) -> np.ndarray:
    return np.arctan2(v[..., 1], v[..., 0])


@needs_models
def test_the_iso_fivebar_assemblies_are_branches_in_their_planes():
    """The batched solver's atlas has a branch per determinant sign and per freeortho assembly (0
    and pi, found although the pi assembly does not reach the reference position), each atlas
    pose's tip in its plane (the planes' y from the open-loop geometry above)."""
    from kinematics.generic.loop_batch import loop_batch

    robot = load_robot(GEPETTO / "5bar_linkage_iso3d")
    batch = loop_batch(robot)
    assert [robot.dofs[j].name for j in batch.locked_joints] == ["freeortho"]
    assert sorted(batch.branch_names) == ["+/freeortho=-3.142", "+/freeortho=0", "-/freeortho=-3.142", "-/freeortho=0"]
    y = batch.end_effector_positions(batch.atlas)[:, 1]
    planes = {0.0: _iso_plane_reference(robot, 0.0, 8)[1], np.pi: _iso_plane_reference(robot, np.pi, 8)[1]}
    for name, yb in zip(batch.branch_names, y, strict=True):
        want = planes[np.pi] if name.endswith("3.142") else planes[0.0]
        assert abs(yb - want) <= 1e-9, (name, yb, want)
    assert abs(planes[0.0] - planes[np.pi]) > 1e-2  # two distinct planes
    five = loop_batch(load_robot(GEPETTO / "5bar_linkage"))
    assert five.locked_joints == () and five.branch_names == ("+", "-")


@needs_models
@pytest.mark.parametrize("name", ["5bar_linkage_iso3d", "5bar_linkage_iso6d"])
def test_iso_fivebar_planes_hold_their_geometric_reference(name, capsys):
    """workspace-volume measures each plane's area and reports the union as their sum; each holds
    the grid count within the reported estimate plus the count's own error (its change from the
    grid of half the resolution: first order at worst in the cell size, so the finer count is at
    least twice as close). References: iso3d 1.17694 m^2 (y = -0.2 m), 0.71852 m^2 (y = -0.15 m);
    iso6d 1.39224 m^2 and 0.74625 m^2 (its 6D closure also closes with freeortho = pi: four
    branches, two planes)."""
    path = GEPETTO / name
    assert main(["workspace-volume", str(path), "--range", f"mot1=-{PI}:{PI}", "--range", f"mot2=-{PI}:{PI}",
                 "--rtol", "1e-1", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    robot = load_robot(path)
    assert len(data["modes"]) == 4 + 2  # two branches per plane, then the planes' unions
    total, total_err = 0.0, 0.0
    for ortho in (0.0, np.pi):
        (fine, y), (coarse, _) = _iso_plane_reference(robot, ortho, 2400), _iso_plane_reference(robot, ortho, 1200)
        got = data["modes"][f"plane y={y:.6g}"]
        assert abs(got["area"] - fine) <= got["error_estimate"] + abs(fine - coarse), (y, got, fine)
        total, total_err = total + fine, total_err + abs(fine - coarse)
    assert abs(data["area_m2"] - total) <= data["error_estimate"] + total_err
    assert "sum of the parallel planes' areas" in data["union_rule"]


def _iso_inside(robot, ortho: float, E: np.ndarray) -> np.ndarray:
    """Chain 2's reach slack [m] at the effector points E (N, 2) in the freeortho = ortho assembly
    (best of chain 1's two elbows; >= 0 inside), from `_iso_reach` (see `_iso_plane_reference`)."""
    g = _iso_reach(robot, ortho)
    A1, A2, a1, e, b1, a2, b2 = (g[k] for k in ("A1", "A2", "a1", "e", "b1", "a2", "b2"))
    D = E - A1
    r = np.linalg.norm(D, axis=1)
    x = (a1**2 - e**2 + r**2) / (2 * r)
    h2 = a1**2 - x**2
    perp = np.stack([-D[:, 1], D[:, 0]], axis=1)
    slack = np.full(len(E), -np.inf)
    for side in (1, -1):
        B = A1 + (x / r)[:, None] * D + side * (np.sqrt(np.maximum(h2, 0)) / r)[:, None] * perp
        phi = _angle(E - B) + g["delta"]
        P = B + b1 * np.stack([np.cos(phi), np.sin(phi)], axis=1)
        d2 = np.linalg.norm(P - A2, axis=1)
        slack = np.maximum(slack, np.where(h2 >= 0, np.minimum(d2 - abs(a2 - b2), a2 + b2 - d2), -np.inf))
    return slack


@needs_models
@pytest.mark.parametrize("name", ["5bar_linkage_iso3d", "5bar_linkage_iso6d"])
def test_iso_fivebar_columns_miss_no_inside_point(name):
    """Points walked column by column (as the volume engine does) through the batched solver's
    margin, against the geometric reach: inside points (slack > 1e-6 m) the solver calls outside
    were 0.25 % before the single-block restart rule (all within 5 mm of a fold of the reach);
    allowed: 1 in 5,000. No outside point may be called inside."""
    from kinematics.generic.loop_batch import LoopBatch

    robot = load_robot(GEPETTO / name, ranges={"mot1": (-np.pi, np.pi), "mot2": (-np.pi, np.pi)})
    batch = LoopBatch.from_robot(robot)
    lo, hi = batch.bounding_box()
    xs, zs = np.arange(lo[0] + 0.01, hi[0], 0.02), np.arange(lo[1] + 0.0033, hi[1], 0.01)
    pts = np.stack(np.meshgrid(xs, zs, indexing="ij"), -1).reshape(-1, 2)
    margin = np.vstack([batch.margin(pts[c:c + 4096]) for c in range(0, len(pts), 4096)])
    for ortho, tag in ((0.0, "freeortho=0"), (np.pi, "freeortho=-3.142")):
        cols = [k for k, n in enumerate(batch.branch_names) if n.split("/")[1] == tag]
        assert len(cols) == 2
        got = margin[:, cols].max(axis=1) > 0
        slack = _iso_inside(robot, ortho, pts)
        inside = slack > 1e-6
        assert not np.any(got & (slack < -1e-6))
        assert np.sum(inside & ~got) <= inside.sum() / 5000, (tag, int(np.sum(inside & ~got)), int(inside.sum()))
