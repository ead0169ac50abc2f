"""The batched closed-loop solver (kinematics.generic.loop_batch) against the closed forms of the
3-[P2(US)] (kinematics.mechanisms.p2us.closed_form), the Delta (kinematics.mechanisms.delta.closed_form) and the planar five-bar
(tests/fivebar.py).

Tolerances. The solver stops at residual rows <= 1e-12 m (loop_batch.TOL). At the seeded points
below the closed forms' singularity measures are >= ~0.02 (points closer to a singularity are left
out), so joint errors are at most ~1e-12 / 0.02 = 5e-11 rad or m; the issue's 1e-9 keeps a factor
20 above that. Volumes: both engines integrate the same zero sets; their difference must be within
the sum of their own error estimates.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from kinematics.analyses.columns import column_volume
from kinematics.errors import InvalidInputError, UnknownChoiceError
from kinematics.generic.loop_batch import SINGULAR_TOL, LoopBatch
from kinematics.mechanisms.delta import closed_form as dl
from kinematics.mechanisms.delta.urdf import read_params as delta_params
from kinematics.mechanisms.p2us import closed_form as par
from kinematics.mechanisms.p2us.mechanism import p2us_margin
from kinematics.mechanisms.p2us.scan import bounding_box, scan
from kinematics.mechanisms.p2us.urdf import read_params as p2us_params
from kinematics.mechanisms.three_limb.modes import MODE_ROOTS
from kinematics.model.robot import load_robot

from .fivebar import FiveBar

FIVEBAR = Path(__file__).parent / "models" / "fivebar_gepetto" / "robot.urdf"
JOINT_TOL = 1e-9


@pytest.fixture(scope="module")
def p2us():
    robot = load_robot("p2us")
    return robot, p2us_params(robot.urdf_path), LoopBatch.from_robot(robot, seeds=256)


def mode_map(generic: np.ndarray, closed: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """generic (N, B, a), closed (N, M, a) actuator values -> (B,) closed mode of each generic
    branch, the same at every point `ok`; fails unless it is a bijection."""
    d = np.abs(generic[ok][:, :, None, :] - closed[ok][:, None, :, :]).max(axis=-1)  # (N, B, M)
    per_point = np.argmin(d, axis=2)
    assert np.all(per_point == per_point[:1]), "a branch label maps to different closed-form modes"
    mapping = per_point[0]
    assert sorted(mapping.tolist()) == list(range(closed.shape[1]))
    return mapping


def wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


# -- 3-[P2(US)] ------------------------------------------------------------------------------------
def test_p2us_branches_are_the_eight_closed_form_modes(p2us):
    robot, P, lb = p2us
    assert len(lb.labels) == 8
    lo, hi = bounding_box(P)
    pts = np.random.default_rng(1).uniform(lo, hi, (400, 3))
    ik = par.ik(P, pts, limits=False)
    jac = par.jacobians(P, pts, np.nan_to_num(ik.q[:, 0]))
    reach = ik.reachable[:, 0]
    sol = lb.ik(pts, warm=False)
    # no branch where the closed form has none; all eight where it has them
    assert not sol.found[~reach].any()
    clear = reach & (jac.iota_I > 0.02)
    assert clear.sum() > 50 and sol.found[clear].all()
    qa = sol.x[..., lb.actuated]
    mapping = mode_map(qa, ik.q, clear)
    np.testing.assert_allclose(qa[clear], ik.q[clear][:, mapping], rtol=0, atol=JOINT_TOL)
    # universal-joint angles: both rods of limb i follow its rod direction n_i. The universal joint
    # that carries the platform (limb 1, rod 1) may come as (theta + pi, pi - phi), the same rod
    # (spun about its axis, the spherical joint compensating): either representation is accepted
    theta, phi = par.passive_angles(P, ik.limbs.n)  # (N, 3, 2): limb, root
    roots = MODE_ROOTS[mapping]  # (B, 3)
    names = robot.joint_names
    for i in range(3):
        want_t = theta[clear][:, i, roots[:, i]]
        want_p = phi[clear][:, i, roots[:, i]]
        for rod in (1, 2):
            got_t = sol.x[clear][:, :, names.index(f"u_theta_{i + 1}_{rod}")]
            got_p = sol.x[clear][:, :, names.index(f"u_phi_{i + 1}_{rod}")]
            same = np.maximum(np.abs(wrap(got_t - want_t)), np.abs(wrap(got_p - want_p)))
            other = np.maximum(np.abs(wrap(got_t - want_t - np.pi)), np.abs(wrap(got_p - np.pi + want_p)))
            assert np.minimum(same, other).max() <= JOINT_TOL
            if (i, rod) != (0, 1):
                assert same.max() <= JOINT_TOL


def test_p2us_margin_sign_matches_the_closed_form(p2us):
    _, P, lb = p2us
    lo, hi = bounding_box(P)
    pts = np.random.default_rng(2).uniform(lo, hi, (300, 3))
    closed = scan(P, pts, "all").margin  # (N, 8) in parallel.MODES order
    ik = par.ik(P, pts, limits=False)
    reach = ik.reachable[:, 0]
    sol = lb.ik(pts[reach][:5], warm=False)
    mapping = mode_map(sol.x[..., lb.actuated], ik.q[reach][:5], np.ones(5, bool))
    generic = lb.margin(pts)
    assert generic.shape == (300, 9)
    np.testing.assert_array_equal(generic[:, 8], generic[:, :8].max(axis=1))
    # exact zeros and boundary points (|closed| < 1e-9 m) are left out: signs there are rounding
    c = closed[:, mapping]
    clear = np.abs(c) > 1e-9
    assert np.any(c > 0) and np.any(c < 0)
    np.testing.assert_array_equal(np.sign(generic[:, :8][clear]), np.sign(c[clear]))


def test_p2us_strokes_only_grid_signs_match_the_closed_form(p2us):
    """A whole grid in one batch, strokes only: the continuation carries least-squares ends of
    targets outside into targets inside, next to the boundary, where the search used to miss
    branches (35 of the 19,333 grid points inside at this step read as outside before a stalled
    neighbour start got its atlas start too). Each branch's inside set must equal its closed-form
    mode's; a sign exactly at the boundary (|closed margin| < 1e-9 m) is rounding and left out."""
    _, P, lb = p2us
    lo, hi = bounding_box(P)
    axes = [np.arange(a, b + 1e-9, 0.02) for a, b in zip(lo, hi, strict=True)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    closed = scan(P, pts, "actuators").margin
    home = np.array([[0.0, 0.0, -0.45]])
    mapping = mode_map(lb.ik(home, warm=False).x[..., lb.actuated], par.ik(P, home, limits=False).q, np.ones(1, bool))
    lb.forget()
    generic = lb.margin(pts, "actuators")
    c = closed[:, mapping]
    clear = np.abs(c) > 1e-9
    assert (c[clear] >= 0).sum() > 20_000  # (32,101 (point, mode) pairs inside: a large set)
    np.testing.assert_array_equal(generic[:, :8][clear] >= 0, c[clear] >= 0)


def test_p2us_singularity_types_match_classify(p2us):
    _, P, lb = p2us
    rng = np.random.default_rng(3)
    lo, hi = bounding_box(P)
    pts = rng.uniform(lo, hi, (400, 3))
    ik = par.ik(P, pts, limits=False)
    reach = ik.reachable[:, 0]
    pts = pts[reach][:60]
    sol = lb.ik(pts, warm=False)
    mapping = mode_map(sol.x[..., lb.actuated], par.ik(P, pts, limits=False).q, np.ones(len(pts), bool))
    closed = par.jacobians(P, pts[:, None, :], par.ik(P, pts, limits=False).q[:, mapping])
    gen = lb.singularities(pts, sol.x)
    regular = (closed.iota_I > 0.02) & (closed.iota_II > 0.02)
    assert regular.sum() > 100
    assert np.all(gen.types[regular] == 0)
    # type II poses: det[n1; n2; n3] changes sign along a segment in one mode; bisect to it
    b = 0
    m = mapping[b]
    found = 0
    for _ in range(400):
        a, c = rng.uniform(lo, hi, (2, 3))
        f = lambda s, a=a, c=c: par.ik(P, a + s * (c - a), limits=False)
        fa, fc = f(0.0), f(1.0)
        if not (fa.reachable[0] and fc.reachable[0]):
            continue
        ja = np.linalg.det(par.jacobians(P, a, fa.q[m]).Jx)
        jc = np.linalg.det(par.jacobians(P, c, fc.q[m]).Jx)
        if np.sign(ja) == np.sign(jc) or not np.all(par.ik(P, a + np.linspace(0, 1, 50)[:, None] * (c - a),
                                                               limits=False).reachable[:, 0]):
            continue
        s0, s1 = 0.0, 1.0
        for _ in range(60):
            sm = 0.5 * (s0 + s1)
            jm = np.linalg.det(par.jacobians(P, a + sm * (c - a), f(sm).q[m]).Jx)
            s0, s1 = (sm, s1) if np.sign(jm) == np.sign(ja) else (s0, sm)
        p = (a + s0 * (c - a))[None]
        cj = par.jacobians(P, p, f(s0).q[m][None])
        if cj.iota_I[0] < 0.05:
            continue
        s = lb.ik(p, warm=False)
        assert s.found[0, b]
        g = lb.singularities(p, s.x[:, b])
        assert par.classify(cj.iota_I, cj.iota_II)[0] == 2
        assert g.types[0, 0] == 2, (g.iota_I, g.iota_II)
        found += 1
        if found == 3:
            break
    assert found == 3


def test_p2us_type_one_at_a_reach_boundary(p2us):
    _, P, lb = p2us
    # walk from a reachable point outwards until limb 1 stops reaching; bisect on its discriminant
    a = np.array([0.0, 0.0, -0.45])
    c = np.array([0.45, 0.0, -0.45])
    limb = lambda s: par.limb_ik(P, a + s * (c - a))
    assert limb(0.0).reach.all() and not limb(1.0).reach.all()
    s0, s1 = 0.0, 1.0
    for _ in range(60):
        sm = 0.5 * (s0 + s1)
        s0, s1 = (sm, s1) if limb(sm).reach.all() else (s0, sm)
    # approaching the fold, both type I measures vanish together (like the square root of the
    # distance); their ratio stays bounded (the generic one is a different but equivalent norm)
    ratios = []
    for delta in (1e-2, 1e-4, 1e-6):
        p = (a + (s0 - delta) * (c - a))[None]
        sol = lb.ik(p, warm=False)
        assert sol.found[0].all()
        g = lb.singularities(p, sol.x)
        closed = par.jacobians(P, np.repeat(p, 8, axis=0), sol.x[0][:, lb.actuated])
        ratios.append(g.iota_I[0] / closed.iota_I)
        assert np.all(g.iota_II[0] > SINGULAR_TOL)
    ratios = np.array(ratios)
    assert np.all((ratios > 0.1) & (ratios < 10)), ratios
    assert np.all(np.abs(np.log10(ratios[-1] / ratios[0])) < 0.5)


def test_pinned_closure_block_meets_the_platform_at_the_target(p2us):
    """Where limb 1 cannot reach, limb 2's closure block (its slider and passive joints against
    the platform) solved with the platform pinned at the target closes exactly where limb 2
    reaches, on one of limb 2's two closed-form slider values; unpinned, the platform stays where
    limb 1's values put it and the block solves the wrong problem."""
    robot, P, lb = p2us
    lo, hi = bounding_box(P)
    pts = np.random.default_rng(11).uniform(lo, hi, (3000, 3))
    reach = par.limb_ik(P, pts).reach
    sel = ~reach[:, 0]
    pts, reach2 = pts[sel], reach[sel, 1]
    assert 100 < reach2.sum() < len(pts) - 100  # both cases present
    slider = robot.joint_names.index("slider_2")
    blk = next(b for b in lb.blocks if slider in b.cols)
    rows = np.zeros(lb.row_dependencies().shape[0], dtype=bool)
    rows[list(blk.rows)] = True
    free = np.zeros(lb.n, dtype=bool)
    free[list(blk.cols)] = True
    assert not set(blk.rows) & set(lb.task_rows)
    x0 = np.repeat(lb.atlas[:1], len(pts), axis=0)
    x, res, _ = lb.newton(pts, x0, iters=60, free=free, rows=rows, pinned=True)
    closes = res <= 1e-12
    # LM from one start can stall short of a root it could reach (measured here: none did): allow
    # 1 % of misses, never a closure where limb 2 cannot reach
    assert not np.any(closes & ~reach2)
    assert closes[reach2].mean() >= 0.99
    q = par.limb_ik(P, pts[closes]).q[:, 1]  # (K, 2) limb 2's two roots [m]
    # the solver's 1e-12 m residual moves the slider by ~1e-12 / |dr/dq| (~1 away from the fold)
    assert np.all(np.abs(q - x[closes, slider][:, None]).min(axis=1) <= 1e-8)
    # the other rows are not touched: limb 1's joints keep their starting values
    assert np.array_equal(x[:, ~free], x0[:, ~free])
    # unpinned, the block closes against the platform where the start (the atlas) holds it, and
    # limb 2's slider sits where the reference position needs it, not the target
    xu, resu, _ = lb.newton(pts, x0, iters=60, free=free, rows=rows)
    ok = (resu <= 1e-12) & reach2
    off = np.abs(par.limb_ik(P, pts[ok]).q[:, 1] - xu[ok, slider][:, None]).min(axis=1)
    assert ok.sum() > 100 and np.median(off) > 1e-2


def test_pinning_needs_a_translational_spatial_task():
    from kinematics.errors import UnsupportedRobotError

    lb = LoopBatch.from_robot(load_robot(FIVEBAR), seeds=64)
    assert not lb.can_pin
    with pytest.raises(UnsupportedRobotError, match="translational"):
        lb.newton(np.zeros((1, 2)), lb.atlas[:1], pinned=True)


@pytest.mark.slow
def test_p2us_slice_areas_match_the_closed_form_engine(p2us):
    """Per-mode and union areas of the y = 0.03 m slice through both margins, every limit (a
    slice, not the volume, and not the actuators-only limits: the generic path evaluates ~1e3-1e4
    points/s; the volume needs millions of points, the actuators-only slice ~4e5)."""
    limits = "all"
    _, P, lb = p2us
    lo, hi = bounding_box(P)
    lo2, hi2 = lo[[0, 2]], hi[[0, 2]]
    y0 = 0.03
    closed = p2us_margin(P, limits=limits)
    lift = lambda p: np.c_[p[:, 0], np.full(len(p), y0), p[:, 1]]
    ref = column_volume(lambda p: closed(lift(p)), lo2, hi2, step=0.02, rtol=1e-3)
    pts = np.array([[0.0, y0, -0.45], [0.05, y0, -0.5]])
    ik = par.ik(P, pts, limits=False)
    mapping = mode_map(lb.ik(pts, warm=False).x[..., lb.actuated], ik.q, ik.reachable[:, 0])
    lb.forget()
    gen = column_volume(lambda p: lb.margin(lift(p), limits), lo2, hi2, step=0.02, rtol=1e-3)
    want = ref.estimate[list(mapping) + [8]]
    err = ref.error[list(mapping) + [8]] + gen.error
    assert want[-1] > 0.01
    assert np.all(np.abs(gen.estimate - want) <= err), (gen.estimate, want, err)


def test_tree_kinematics_match_the_per_frame_batched_kernel(p2us):
    """The solver's whole-tree kernel against kinematics.generic.batched (one chain per frame) and
    Pinocchio's joint placements: both compose the same placements, to rounding (1e-15 m)."""
    import pinocchio as pin

    from kinematics.generic.batched import batched_fk, configurations

    robot, _, lb = p2us
    x = lb.random_configurations(50, np.random.default_rng(6))
    _, _, pos = lb.evaluate(np.zeros((50, 3)), x)
    q = configurations(robot, x)
    for k, name in enumerate(lb.frames):
        np.testing.assert_allclose(pos[:, lb.n + k], batched_fk(robot, q, name).position, rtol=0, atol=1e-15)
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q[0])
    want = np.array([data.oMi[j].translation for j in range(1, robot.model.njoints)])
    np.testing.assert_allclose(pos[0, : lb.n], want, rtol=0, atol=1e-15)


# -- Delta -----------------------------------------------------------------------------------------
def test_delta_branches_are_its_closed_form_modes():
    robot = load_robot("delta")
    P = delta_params(robot.urdf_path)
    lb = LoopBatch.from_robot(robot, seeds=256)
    assert len(lb.labels) == 8
    pts = np.random.default_rng(4).uniform([-0.5, -0.5, -1.1], [0.5, 0.5, -0.3], (150, 3))
    ik = dl.ik(P, pts, limits=False)
    reach = ik.reachable[:, 0]
    jac = dl.jacobians(P, pts, np.nan_to_num(ik.q[:, 0]))
    clear = reach & (jac.iota_I > 0.05)
    sol = lb.ik(pts, warm=False)
    assert not sol.found[~reach].any()
    assert clear.sum() > 30 and sol.found[clear].all()
    qa = sol.x[..., lb.actuated]
    d = np.abs(wrap(qa[clear][:, :, None, :] - ik.q[clear][:, None, :, :])).max(axis=-1)
    per_point = np.argmin(d, axis=2)
    assert np.all(per_point == per_point[:1]) and sorted(per_point[0].tolist()) == list(range(8))
    assert np.min(d, axis=2).max() <= JOINT_TOL


# -- planar five-bar -------------------------------------------------------------------------------
def test_fivebar_branches_and_joint_values():
    robot = load_robot(FIVEBAR)
    five = FiveBar.from_robot(robot)
    lb = LoopBatch.from_robot(robot, seeds=256)
    assert lb.task_dim == 2 and not lb.translational and len(lb.labels) == 4
    pts = np.random.default_rng(5).uniform([-0.05, 0.22], [0.25, 0.45], (40, 2))
    sol = lb.ik(pts, warm=False)
    hits = np.zeros((4, 4), dtype=int)
    for i, P in enumerate(pts):
        for k, _, want in _closed_form_modes(five, robot, P, 0.05):
            d = np.abs(wrap(sol.x[i] - want)).max(axis=1)
            assert np.nanmin(d) <= JOINT_TOL
            hits[k, int(np.nanargmin(d))] += 1
    # each closed-form mode always lands on the same generic branch, and they are all different
    assert np.count_nonzero(hits) == 4 and np.all(hits.sum(axis=0) > 0)


def test_fivebar_cold_grid_finds_every_reachable_branch():
    """A cold first pass over a 0.01 m grid of the five-bar's box against its reach annuli (each
    distal point within a_i + b_i and beyond |a_i - b_i| of its motor, 1e-6 m clear of both circles:
    4 branches there, none elsewhere). The search may miss a basin (its documented limit): at most
    1 pair in 10,000 (measured 0 of 27,064 here and 1 on the grids shifted by 3 and 7 mm; with
    lam / 10 after every step for the descents too, 8, 2 and 5: Levenberg-Marquardt from chain 1's
    atlas start stalled on the plateau beside its folded configuration)."""
    robot = load_robot(FIVEBAR)
    five = FiveBar.from_robot(robot)
    lb = LoopBatch.from_robot(robot)
    lo, hi = lb.bounding_box()
    g = np.stack(np.meshgrid(*[np.arange(lo[k], hi[k], 0.01) for k in range(2)], indexing="ij"), -1).reshape(-1, 2)
    slack = five.reach(g)
    reach, out = (slack > 1e-6).all(axis=1), (slack < -1e-6).any(axis=1)
    assert reach.sum() > 5000 and out.sum() > 5000
    s = lb.ik(g, warm=False)
    assert not s.found[out].any()
    assert np.sum(~s.found[reach]) <= 1e-4 * 4 * reach.sum()


def _closed_form_modes(five: FiveBar, robot, P: np.ndarray, clear: float):
    """(index, mode, every joint's value in URDF order) of each closed-form mode that reaches P
    with its singularity indices >= `clear`."""
    for k, m in enumerate([(1, 1), (1, -1), (-1, 1), (-1, -1)]):
        theta = five.ik(P, m)
        if theta is None or min(five.singularity_indices(theta, P)) < clear:
            continue
        jv = five.joint_values(theta, P)
        yield k, m, np.array([jv[n] for n in robot.joint_names])


def _missed_modes(five: FiveBar, robot, pts: np.ndarray, sol) -> list[tuple[int, tuple[int, int]]]:
    """(point, mode) pairs the closed form reaches, clear of singularities (indices >= 0.02: joint
    errors <= 5e-11 rad, module docstring), that no found branch of `sol` matches to JOINT_TOL."""
    missed = []
    for i, P in enumerate(pts):
        for _, m, want in _closed_form_modes(five, robot, P, 0.02):
            d = np.abs(wrap(sol.x[i] - want)).max(axis=1)
            if not np.any(sol.found[i] & (d <= JOINT_TOL)):
                missed.append((i, m))
    return missed


def test_fivebar_first_batch_finds_every_closed_form_mode():
    """A fresh solver's first batch (2000 seeded points of the five-bar's box, warm starts inside
    the batch only) finds every working mode the closed form has at each point (its joints turn
    freely: no limit to respect). Before the restarts were keyed to the target and extended where a
    start closed on the other elbow, this batch missed 2 of 3,596 pairs (points 1784 and 1942; a
    second call found them)."""
    robot = load_robot(FIVEBAR)
    five = FiveBar.from_robot(robot)
    lb = LoopBatch.from_robot(robot)
    lo, hi = lb.bounding_box()
    pts = np.random.default_rng(2).uniform(lo, hi, (2000, 2))
    sol = lb.ik(pts)
    assert sol.found.sum() > 3000
    assert _missed_modes(five, robot, pts, sol) == []


def test_fivebar_point_answer_does_not_depend_on_its_row():
    """The audit's point (0.13652706, -0.18748007), four modes there, solved cold in 64 rows of one
    batch: every row finds all four (the restarts are a function of the target, not of its row).
    Before, rows 13 and 20 missed mode (-1, +1): chain 2's atlas start and its 8 restarts there all
    closed on the other elbow, and a fresh solver's first batch of 300 points, with this point at
    row 20 of its coarse level, reported margin -2e-17 for that mode."""
    robot = load_robot(FIVEBAR)
    five = FiveBar.from_robot(robot)
    lb = LoopBatch.from_robot(robot)
    pts = np.repeat([[0.13652706, -0.18748007]], 64, axis=0)
    sol = lb.ik(pts, warm=False)
    assert sol.found.sum(axis=1).tolist() == [4] * 64
    assert _missed_modes(five, robot, pts, sol) == []


def test_restart_windows_spread_over_a_lattice_of_targets():
    """`restart_base` puts the targets of a grid (a volume's columns, a test's lattice) in different
    windows of the quasi-random sequence: on 2,500 points of a 1/128 m lattice at most a few share
    one (2^20 windows: ~3 pairs expected were they random). An integer hash reduced at each
    coordinate gave all of them one window: every one of its restarts the same."""
    from kinematics.generic.loop_batch.compiled import restart_base

    g = np.arange(-25, 25) / 128.0
    pts = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    windows = {restart_base(p, 0, 1, 1, 1) for p in pts}
    assert len(windows) >= len(pts) - 20


def test_bad_input(p2us):
    _, _, lb = p2us
    with pytest.raises(InvalidInputError):
        lb.ik(np.zeros((3, 2)))
    with pytest.raises(InvalidInputError):
        lb.margin(np.array([[np.nan, 0.0, 0.0]]))
    with pytest.raises(UnknownChoiceError):
        lb.margin_function(limits="some")


# -- the block solver against the whole-system solver (two independent paths) -----------------------
def _cases():
    return [("p2us", None, 11), ("delta", None, 12), ("fivebar", FIVEBAR, 13)]


@pytest.mark.parametrize(("name", "path", "seed"), _cases())
def test_block_solver_agrees_with_the_whole_system_solver(name, path, seed):
    """Same atlas (same seeds), two solvers: where both find a (point, branch) they find the same
    pose (every joint origin to 1e-9 m: joint representations may differ) and the same margin.
    Tolerance: both solve to residual rows <= 1e-12 m at points whose Jacobian blocks are regular,
    so poses agree to ~1e-12 / (smallest singular value); 1e-9 allows 1e-3. Each search can miss a
    branch's basin (the documented limit; not at the same points, as their starts differ): the
    found sets may differ in at most 2 % of the pairs either finds, where a wrong label map or a
    wrong block would differ in whole branches (>= 1/8 of them)."""
    robot = load_robot(path or name)
    blocks = LoopBatch.from_robot(robot, seeds=256)
    whole = LoopBatch.from_robot(robot, seeds=256, solver="whole")
    assert blocks.labels == whole.labels and np.array_equal(blocks.atlas, whole.atlas)
    lo, hi = blocks.bounding_box()
    pts = np.random.default_rng(seed).uniform(lo, hi, (400, blocks.task_dim))
    a, b = blocks.ik(pts, warm=False), whole.ik(pts, warm=False)
    assert 40 < a.found.any(axis=1).sum() < 360, "the sample must see points inside and outside"
    assert np.sum(a.found != b.found) <= 0.02 * np.sum(a.found | b.found)
    i, k = np.nonzero(a.found & b.found)
    _, _, pa = blocks.evaluate(pts[i], a.x[i, k])
    _, _, pb = whole.evaluate(pts[i], b.x[i, k])
    assert np.abs(pa - pb).max() <= 1e-9
    both = a.found & b.found
    np.testing.assert_allclose(a.margin[both], b.margin[both], rtol=0, atol=1e-9)  # inf: no limited joint
    assert (a.margin[~a.found] < 0).all() and (b.margin[~b.found] < 0).all()


def test_every_block_solves_blocks_no_branch_needs(p2us):
    """Outside the workspace the block solver skips a limb's blocks once another limb rules every
    branch out; every_block solves them anyway, so each limb's own end is there (loop_fields)."""
    _, _, lb = p2us
    lo, hi = lb.bounding_box()
    pts = np.random.default_rng(14).uniform(lo, hi, (300, 3))
    lazy, full = lb.ik(pts, warm=False), lb.ik(pts, warm=False, every_block=True)
    assert np.array_equal(lazy.found, full.found)
    out = ~full.found.any(axis=1)
    first = list(lb.block_models[0].block.cols)  # the platform's limb (no held joints)
    assert np.isfinite(full.end[out][:, :, first]).all()
    assert np.isnan(lazy.end[out][:, :, first]).any()


def test_a_nan_start_is_no_root(p2us):
    _, _, lb = p2us
    x, res, _ = lb.newton(np.zeros((1, 3)), np.full((1, lb.n), np.nan))
    assert not res[0] <= 1e-12


def test_warm_cache_ring_returns_each_points_own_ends(monkeypatch):
    """The warm-start cache is a ring whose big KD-tree is rebuilt every RECENT_POINTS new points
    (CACHE_POINTS kept); shrunk here so that batches of every size relative to RECENT_POINTS wrap
    it several times. Each point's "ends" are its own coordinates, so a stale row (a tree index
    pointing at a row since overwritten) would show as ends that differ from the point found; and
    exactly the newest CACHE_POINTS .. CACHE_POINTS + RECENT_POINTS points must be findable."""
    import kinematics.generic.loop_batch.warm as module

    monkeypatch.setattr(module, "CACHE_POINTS", 40)
    monkeypatch.setattr(module, "RECENT_POINTS", 16)
    cache = module.WarmCache((3,))
    added = np.empty((0, 3))
    rng = np.random.default_rng(22)
    for size in (10, 37, 5, 60, 16, 1, 90, 3):
        p = rng.uniform(0.0, 1.0, (size, 3))
        cache.add(p, p.copy())
        added = np.concatenate([added, p])
        d, ends = cache.nearest(added, 1e-12)  # each point exactly, or nothing
        hit = np.isfinite(d)
        np.testing.assert_array_equal(ends[hit], added[hit])
        newest = np.zeros(len(added), dtype=bool)
        newest[-40:] = True
        assert hit[newest].all() and hit.sum() <= 40 + 16
