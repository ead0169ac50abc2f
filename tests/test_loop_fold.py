"""The block solver next to a fold of the reach, as a root refinement probes it: each probe's warm
starts come from the previous probe a few micrometres away, so a stalled start's fold verdict
(`compiled.fold_roots`) replaces the quasi-random restarts. Held to the planar five-bar's closed
form (tests/fivebar.py): a chain reaches a point iff it lies between its two reach circles.

Tolerances. The solver closes to residual rows <= 1e-12 m; next to a fold at distance d inside,
the two roots of the stretched chain are ~sqrt(d / radius) rad apart, so at d >= 1e-8 m they are
distinct roots well above the closure tolerance, and outside the least-squares residual is d
itself (>= 1e-8 m >> 1e-12 m): the sign is decided, and every branch must be found inside and
none outside.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinematics.generic.loop_batch import LoopBatch
from kinematics.generic.loop_batch.compiled import FOLD_SOURCE, TOL, fold_roots, lm_kernel, pack, scratch
from kinematics.generic.loop_batch.warm import WARM_RADIUS_FACTOR
from kinematics.model.robot import load_robot

from .fivebar import FiveBar

FIVEBAR = Path(__file__).parent / "models" / "fivebar_gepetto" / "robot.urdf"


def _outer_boundary(five: FiveBar, count: int, chains: tuple[int, ...] = (0, 1)) -> tuple[np.ndarray, np.ndarray]:
    """Points on each chain's outer reach circle that the other chain reaches with 2 cm to spare
    (a fold of one chain only), and the circle's outward normals there."""
    pts, normals = [], []
    for i in chains:
        phi = np.linspace(0.0, 2 * np.pi, 720, endpoint=False)
        n = np.stack([np.cos(phi), np.sin(phi)], axis=1)
        p = five.A[i] + (five.a[i] + five.b[i]) * n
        slack = five.reach(p)
        ok = (slack[:, 1 - i] > 0.02) & (np.abs(slack[:, i]) < 1e-12)
        pts.append(p[ok])
        normals.append(n[ok])
    p, n = np.concatenate(pts), np.concatenate(normals)
    keep = np.linspace(0, len(p) - 1, count).astype(int)
    return p[keep], n[keep]


def test_probes_across_a_fold_match_the_closed_form_reach():
    """A bisection across each chain's outer reach circle (steps 1e-4 x scale down to 1e-8 m,
    alternating sides): inside every probe finds all four branches, outside none. The probes' warm
    starts come from the previous probe, closer than FOLD_SOURCE x the continuation radius, where
    the fold verdict decides instead of restarts."""
    robot = load_robot(FIVEBAR)
    five = FiveBar.from_robot(robot)
    lb = LoopBatch.from_robot(robot)
    pb, n = _outer_boundary(five, 24)
    assert len(pb) == 24
    h = 1e-4 * lb.scale
    assert 2 * h < FOLD_SOURCE * WARM_RADIUS_FACTOR * lb.scale  # the probes' sources are near enough
    offsets = [-1e-3, h] + [(-1) ** k * h / 2**k for k in range(1, 30) if h / 2**k >= 1e-8]
    assert len(offsets) > 10
    lb.forget()
    for d in offsets:
        p = pb + d * n
        sol = lb.ik(p)
        inside = (five.reach(p) > 0).all(axis=1)
        assert inside.all() if d < 0 else not inside.any()
        assert sol.found[inside].all(), f"a branch missed {abs(d):.1e} m inside a fold"
        assert not sol.found[~inside].any(), f"a root {d:.1e} m outside a fold"


def test_fold_model_tells_a_fold_from_beyond_it():
    """`fold_roots` at the least-squares point of a target 1e-6 m beyond chain 1's outer reach
    circle (its block: the 2R chain that carries the end effector): for a target 1e-6 m inside it
    predicts roots along the fold direction, and from each prediction Levenberg-Marquardt closes to
    a root, the two distinct (the chain's two elbows, ~2 sqrt(1e-6 / 0.5) ~ 3e-3 rad apart, far
    above the 1e-12 m closure); for targets 1e-6 m and 1e-4 m beyond it says no root is next to
    the fold; at a regular root it says nothing (not a fold)."""
    robot = load_robot(FIVEBAR)
    five = FiveBar.from_robot(robot)
    lb = LoopBatch.from_robot(robot)
    assert lb.task_axes == (0, 1)
    (k, bm), = [(k, bm) for k, bm in enumerate(lb.block_models) if set(bm.block.rows) & set(lb.task_rows)]
    names = [robot.dofs[int(j)].name for j in bm.joints]
    assert len(bm.held) == 0 and "mot1" in names
    gi, gf = pack(bm.g)
    ws, r, rt, J, Jt, A, D, gr, dx, _ = scratch(gi, bm.m)
    v, s12 = np.empty(len(bm.joints)), np.empty(2)

    def lm(target: np.ndarray, x0: np.ndarray) -> tuple[np.ndarray, float]:
        x, res, it = np.empty((1, len(x0))), np.empty(1), np.empty(1, dtype=np.int64)
        lm_kernel(target[None], x0[None], gi, gf, bm.m, bm.nzc, bm.nzn, bm.centre, bm.free, bm.weights, 60, TOL,
                  x, res, it, bm.pinned)
        return x[0], float(res[0])

    def verdict(target: np.ndarray, x: np.ndarray) -> tuple[int, np.ndarray]:
        x = x.copy()
        got = fold_roots(target, x, gi, gf, bm.m, bm.centre, bm.free, bm.weights, bm.pinned, ws, r, rt, J, Jt, A, D,
                         gr, dx, v, s12)
        return got, x

    for pb, n in zip(*_outer_boundary(five, 6, (0,)), strict=True):
        jv = five.joint_values(five.ik(pb - 1e-2 * n, (1, 1)), pb - 1e-2 * n)
        x_in, res = lm(pb - 1e-2 * n, np.array([jv.get(name, 0.0) for name in names]))
        assert res <= TOL
        assert verdict(pb - 1e-2 * n, x_in)[0] == 0  # a regular root: no fold
        x_ls, res = lm(pb + 1e-6 * n, x_in)
        assert 0.5e-6 < res < 2e-6  # the least-squares point at the fold: residual = the distance
        got, x1 = verdict(pb - 1e-6 * n, x_ls)
        assert got == 2
        roots = [lm(pb - 1e-6 * n, x1 + s * v) for s in s12.copy()]
        assert all(res <= TOL for _, res in roots)
        assert np.abs(roots[0][0] - roots[1][0]).max() > 1e-3
        for beyond in (1e-6, 1e-4):
            assert verdict(pb + beyond * n, x_ls)[0] == 1
