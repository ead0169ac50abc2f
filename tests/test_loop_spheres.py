"""Spherical triples behind 6D closures in closed form (`kinematics.generic.loop_batch.spheres`):
the closed form against an independent forward kinematics, and the reduced block solver against
the full 6D closure (the same roots, the same branches)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kinematics.generic.loop_batch.compiled import REVOLUTE
from kinematics.generic.loop_batch.spheres import sphere_angles, sphere_cuts
from kinematics.model.robot import load_robot

from .conftest import GEPETTO

needs_models = pytest.mark.skipif(not GEPETTO.is_dir(), reason=f"Gepetto's models are not at {GEPETTO}")


def _rot(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    return Rotation.from_rotvec(np.asarray(angle)[:, None] * axis).as_matrix()


def _triple_model(rng: np.random.Generator, hand: float) -> tuple:
    """A tree: joint 0 (base, revolute) -> triple 1, 2, 3 (perpendicular axes through one point,
    random fixed rotations between them; hand: the sign of det[u1 v2 v3]) carrying frame 0;
    joint 4 (base, revolute) carrying frame 1; a 6D closure between the frames: the model tuple
    (`LoopModel._g` layout)."""
    n = 5
    parent = np.array([-1, 0, 1, 2, -1])
    jR = Rotation.random(n, random_state=rng).as_matrix()
    jt = rng.normal(size=(n, 3))
    jt[2] = jt[3] = 0.0  # the triple shares joint 1's origin
    u1 = rng.normal(size=3)
    u1 /= np.linalg.norm(u1)
    v2 = np.cross(u1, rng.normal(size=3))
    v2 /= np.linalg.norm(v2)
    v3 = hand * np.cross(u1, v2)
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    axis[1] = u1
    axis[2] = jR[2].T @ v2  # v2 = jR2 a2
    axis[3] = (jR[2] @ jR[3]).T @ v3  # v3 = jR2 jR3 a3
    fparent = np.array([3, 4])
    fR = Rotation.random(2, random_state=rng).as_matrix()
    ft = rng.normal(size=(2, 3))
    anc = np.array([[1, 1, 1, 1, 0], [0, 0, 0, 0, 1]], dtype=bool)
    g = (parent, np.full(n, REVOLUTE), axis, jR, jt, fparent, fR, ft, anc, np.array([1]), np.array([0]), np.array([1]),
         1, np.array([0, 1]), np.eye(3), False, 1.0)
    return g


def _link_rotation(g: tuple, x: np.ndarray, j: int) -> np.ndarray:
    """World rotation of joint j's link at x (R, n), by scipy's rotation vectors (independent of
    `spheres`' Rodrigues pass)."""
    parent, axis, jR = g[0], g[2], g[3]
    chain = []
    while j >= 0:
        chain.append(j)
        j = int(parent[j])
    R = np.broadcast_to(np.eye(3), (len(x), 3, 3))
    for j in reversed(chain):
        R = R @ jR[j] @ _rot(axis[j], x[:, j])
    return R


@pytest.mark.parametrize("hand", [1.0, -1.0])
def test_sphere_angles_invert_the_triples_rotation(hand):
    """Random triples (random fixed rotations between perpendicular axes, either handedness) at
    random angles: the other side's frame is placed where the weld puts it, and the closed form
    returns the angles in the representation with cos x2 >= 0 ((x1 + pi, pi - x2, x3 + pi)
    otherwise). Tolerance 1e-9 rad: rounding (~1e-15) amplified by 1 / cos x2, with |cos x2| >= 1e-3
    kept."""
    rng = np.random.default_rng(7)
    for _ in range(5):
        g = _triple_model(rng, hand)
        x = rng.uniform(-np.pi, np.pi, (400, 5))
        x = x[np.abs(np.cos(x[:, 2])) >= 1e-3]
        cuts = sphere_cuts(g, ((1, 2, 3),))
        assert set(cuts) == {0} and cuts[0].hand == hand
        # per row, frame 1's placement on joint 4's link that welds it to frame 0 at x: fR_1 = R4^T R0
        R0 = _link_rotation(g, x, 3) @ g[6][0]
        R4 = _link_rotation(g, x, 4)
        got = np.empty((len(x), 3))
        for r in range(len(x)):
            g2 = (*g[:6], np.stack([g[6][0], R4[r].T @ R0[r]]), *g[7:])
            got[r] = sphere_angles(g2, sphere_cuts(g2, ((1, 2, 3),))[0], x[r: r + 1])[0]
        want = x[:, 1:4].copy()
        flip = np.cos(want[:, 1]) < 0
        want[flip] += [np.pi, 0.0, np.pi]
        want[flip, 1] = np.pi - want[flip, 1]
        d = (got - want + np.pi) % (2 * np.pi) - np.pi
        assert np.abs(d).max() <= 1e-9


def test_a_triple_with_a_joint_or_frame_below_is_not_cut():
    """The closed form holds only where the triple's last link carries the closure frame alone."""
    g = _triple_model(np.random.default_rng(3), 1.0)
    busy = (*g[:12], 0, *g[13:])  # the end effector on the triple's last link too
    assert sphere_cuts(busy, ((1, 2, 3),)) == {}
    assert sphere_cuts(g, ((1, 2),)) == {}  # a pair is no spherical joint


@pytest.fixture(scope="module")
def iso6d():
    from kinematics.generic.loop_batch import LoopBatch

    if not GEPETTO.is_dir():
        pytest.skip(f"Gepetto's models are not at {GEPETTO}")
    robot = load_robot(GEPETTO / "5bar_linkage_iso6d", ranges={"mot1": (-np.pi, np.pi), "mot2": (-np.pi, np.pi)})
    return LoopBatch.from_robot(robot), LoopBatch.from_robot(robot, spheres=False)


@needs_models
def test_iso6d_block_is_cut_to_a_point_closure(iso6d):
    new, old = iso6d
    (bm,) = new.block_models
    assert len(bm.cols) == 5 and bm.m == 5 and len(bm.cuts) == 1  # was 8 x 8
    assert [new.robot.joint_names[j] for j in bm.ends[5:]] == [f"part_4_part_6_rev{i}" for i in range(3)]
    (full,) = old.block_models
    assert len(full.cols) == 8 and full.cuts == ()
    assert new.labels == old.labels


@needs_models
def test_iso6d_reduced_solver_finds_the_full_closures_roots_and_branches(iso6d):
    """Random targets over the bounding box, both solvers without warm starts. Every root of the
    reduced solver closes the full 6D closure: its position rows are the point closure's (<= TOL =
    1e-12 m) up to rounding, its orientation rows vanish to rounding (closed form): 1e-11 m. Its
    full label (`label_of`: the full 8 x 8 block's determinant, as the old solver labels) is the
    branch it is reported in. The branches found agree with the full solver's at all but 0.5 % of
    (target, branch) pairs (either search can miss a root next to a fold; seen: 2 of 8,000)."""
    new, old = iso6d
    rng = np.random.default_rng(11)
    lo, hi = new.bounding_box()
    p = rng.uniform(lo, hi, (2000, 2))
    sn, so = new.ik(p, warm=False), old.ik(p, warm=False)
    assert sn.found.sum() > 1500  # a real share of the box is inside
    i, b = np.nonzero(sn.found)
    r, J, _ = new.evaluate(p[i], sn.x[i, b])
    assert np.abs(r).max() <= 1e-11
    lab = new.label_of(J, sn.x[i, b])
    want = np.array(new.labels)[b]
    assert np.array_equal(lab, want), int(np.sum(np.any(lab != want, axis=1)))
    assert np.mean(sn.found != so.found) <= 5e-3


@needs_models
def test_iso6d_cold_start_that_stalls_reduced_is_retried_whole(iso6d):
    """A target 18 mm inside the freeortho = 0 plane's reach, solved alone (no warm start): from
    the atlas starts the reduced block stalls 8 mm from closure (seen), the whole block closes;
    the retry (`BlockSolver._retry_whole`) finds what the whole-block solver finds."""
    new, old = iso6d
    p = np.array([[-0.4982, 0.4093]])
    so, sn = old.ik(p, warm=False), new.ik(p, warm=False)
    assert so.found[0].tolist() == [True, False, True, False]
    assert np.array_equal(sn.found, so.found)
