"""The mechanism interface: the one dispatcher, what each family provides (and says it lacks),
and the families' maps held against each other (margin vs IK limits, IK vs FK) and their Jacobians
against finite differences of their FK and IK."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from kinematics.errors import InvalidInputError, MissingCapabilityError, UnknownChoiceError, UnknownModeError
from kinematics.mechanisms import CAPABILITIES, Mechanism, mechanism_of
from kinematics.model import load_robot

MODELS = Path(__file__).parent / "models"


@pytest.mark.parametrize(("name", "family", "task_dim"), [
    ("scara", "scara", 2), ("p2us", "p2us", 3), ("p2us-results", "p2us", 3), ("delta", "delta", 3),
    ("ur5", "serial", 3), (str(MODELS / "rssr.urdf"), "closed-loop", 1),  # RSSR: one degree of freedom
])
def test_the_dispatcher_decides_the_family(name, family, task_dim):
    mech = mechanism_of(load_robot(name))
    assert isinstance(mech, Mechanism)
    assert (mech.family, mech.task_dim) == (family, task_dim)
    assert mech.capabilities <= set(CAPABILITIES)
    assert mech.closed_loop == (family in ("p2us", "delta", "closed-loop"))


def test_the_dispatcher_refuses_what_is_no_robot_or_no_orientation():
    """mechanism_of("scara") was an AttributeError ('str' object has no attribute 'loops');
    orientation="rpy 0 0 0" (the command line's text) was kept, and the margin's search failed on
    it later."""
    from kinematics.errors import InvalidInputError

    with pytest.raises(InvalidInputError, match=r"load_robot\('scara'\)"):
        mechanism_of("scara")
    with pytest.raises(InvalidInputError, match="ToolOrientation"):
        mechanism_of(load_robot("ur5"), orientation="rpy 0 0 0")


def test_a_missing_capability_names_what_is_missing_and_what_exists():
    ur5 = mechanism_of(load_robot("ur5"))
    with pytest.raises(MissingCapabilityError) as err:
        ur5.ik(np.zeros((1, 3)))
    assert err.value.capability == "ik"
    assert set(err.value.available) == {"fk", "margin", "velocity", "reach_search"}
    assert "ik" in str(err.value) and "fk, margin, reach_search, velocity" in str(err.value)
    loop = mechanism_of(load_robot(str(MODELS / "rssr.urdf")))
    with pytest.raises(MissingCapabilityError, match="pose_ik"):
        loop.pose_ik(np.zeros(1))
    # what is missing is never among what it provides (a generic loop has joint_values, and its
    # missing reference pose was said to need joint_values)
    with pytest.raises(MissingCapabilityError) as err:
        loop.reference_pose()
    assert "joint_values" in loop.capabilities and err.value.capability not in err.value.available


def test_bad_branches_and_limits_name_the_valid_choices():
    delta = mechanism_of(load_robot("delta"))
    with pytest.raises(UnknownModeError, match=r"\+\+\+"):
        delta.margin(["+0+"])
    with pytest.raises(UnknownChoiceError, match="actuators"):
        delta.margin(limits="strokes")
    scara = mechanism_of(load_robot("scara"))
    with pytest.raises(UnknownChoiceError):
        scara.margin(limits="actuators")


def test_one_branch_name_given_alone_is_that_branch():
    """branches="---" is the one working mode, not the modes "-", "-", "-": the Delta refused it
    as "unknown mode '-'" (and Gepetto's five-bar, whose branches are '+' and '-', took "+-" as
    both of them)."""
    delta = mechanism_of(load_robot("delta"))
    assert delta.check_branches("---") == ("---",)
    assert len(delta.branch_velocities(np.array([[0.0, 0.0, -0.8]]), "---")) == 1
    p = np.array([[0.0, 0.0, -0.8]])
    np.testing.assert_array_equal(delta.margin("---")(p), delta.margin(["---"])(p))
    with pytest.raises(UnknownModeError, match="'--'"):
        delta.check_branches("--")
    five = mechanism_of(load_robot(str(MODELS / "fivebar_gepetto" / "robot.urdf")))
    assert five.branches == ("++", "+-", "-+", "--")
    assert five.check_branches("+-") == ("+-",)


CLOSED_FORMS = ["scara", "p2us", "p2us-results", "delta"]


def _sample(mech: Mechanism, n: int, seed: int, grow: float = 1.0) -> np.ndarray:
    lo, hi = mech.bounding_box()
    mid, half = (lo + hi) / 2, grow * (hi - lo) / 2
    return mid - half + 2 * half * np.random.default_rng(seed).random((n, len(lo)))


@pytest.mark.parametrize("name", CLOSED_FORMS)
@pytest.mark.parametrize("limits", ["all", "actuators"])
def test_the_margin_is_non_negative_exactly_where_ik_is_within_limits(name, limits):
    mech = mechanism_of(load_robot(name))
    if limits not in mech.limit_sets:
        pytest.skip(f"{name} has one set of limits")
    p = _sample(mech, 20000, seed=1)
    m = mech.margin(None, limits)(p)
    ok = mech.ik(p, limits).within_limits
    # a margin within 1e-9 m of 0 is on a boundary, where the IK's own tolerances decide
    clear = np.abs(m[:, :-1]) > 1e-9
    assert np.array_equal((m[:, :-1] >= 0)[clear], ok[clear])
    assert np.array_equal(m[:, -1], m[:, :-1].max(axis=1))
    assert ok.any(), "the sample must see the workspace"


@pytest.mark.parametrize("name", CLOSED_FORMS)
def test_the_bounding_box_holds_the_whole_workspace(name):
    mech = mechanism_of(load_robot(name))
    lo, hi = mech.bounding_box("actuators" if "actuators" in mech.limit_sets else "all")
    p = _sample(mech, 40000, seed=2, grow=1.6)
    inside = mech.ik(p, mech.limit_sets[-1]).within_limits.any(axis=1)  # the widest limits
    assert inside.any()
    assert np.all((p[inside] >= lo) & (p[inside] <= hi))


def _actuator_box(mech: Mechanism) -> np.ndarray:
    """(a, 2) every actuator's range [m or rad], from the family's design."""
    P = mech.params
    if mech.family == "scara":
        return np.array([P.lower, P.upper]).T
    return np.array([P.stroke if mech.family == "p2us" else P.theta_limits] * 3)


@pytest.mark.parametrize("name", CLOSED_FORMS)
def test_the_bounding_box_holds_forward_kinematics_over_the_actuator_ranges(name):
    """The box against the other path to the workspace: FK of actuator values drawn over their
    ranges (the test above samples task space through the IK). Every assembly of such values is
    reachable with the actuators' limits; with every limit, those whose own working mode (the one
    the IK gives these actuators back in, to 1e-8) is within limits. Containment is exact: the box
    is proved (closed forms), and a point FK puts outside it is outside by the design's size, not
    by rounding (measured: never outside, 3000 draws). The boxes are supersets: the draws come
    within 0.01-7 % of the box's size of each face, so a face misplaced by more (a sign, an axis,
    a wrong length) fails."""
    mech = mechanism_of(load_robot(name))
    box = _actuator_box(mech)
    q = box[:, 0] + (box[:, 1] - box[:, 0]) * np.random.default_rng(9).random((3000, len(box)))
    asm = mech.fk(q)
    k, m = np.nonzero(asm.exists)
    p, q = asm.p[k, m], q[k]
    for limits in mech.limit_sets:
        keep = np.ones(len(p), dtype=bool)
        if limits != "actuators" and mech.family != "scara":  # scara's one set is its actuators'
            res = mech.ik(p, limits)
            own = np.all(np.abs(res.q - q[:, None]) < 1e-8, axis=-1)
            keep = (own & res.within_limits).any(axis=1)
        lo, hi = mech.bounding_box(limits)
        assert keep.sum() > 300, "the sample must see the workspace"
        assert np.all((p[keep] >= lo) & (p[keep] <= hi)), (limits, p[keep][((p[keep] < lo) | (p[keep] > hi)).any(1)][:3])


@pytest.mark.parametrize("name", CLOSED_FORMS)
def test_forward_kinematics_returns_the_point_of_every_branch(name):
    mech = mechanism_of(load_robot(name))
    p = _sample(mech, 4000, seed=3)
    res = mech.ik(p, mech.limit_sets[-1])
    k, b = np.nonzero(res.reachable)
    asm = mech.fk(res.q[k, b])
    err = np.nanmin(np.linalg.norm(asm.p - p[k, None, :], axis=-1), axis=1)
    # IK then FK: a few roundings of metre-sized coordinates, amplified near singular poses
    assert np.nanmax(err) < 1e-8, np.nanmax(err)


def _central_differences(f, x: np.ndarray, h: float) -> np.ndarray:
    """(N, m, n) central differences (f(x + h e_j) - f(x - h e_j)) / 2h of f: (N, n) -> (N, m)."""
    cols = []
    for j in range(x.shape[1]):
        dx = np.zeros(x.shape[1])
        dx[j] = h
        cols.append((f(x + dx) - f(x - dx)) / (2 * h))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("name", CLOSED_FORMS)
def test_the_jacobians_are_the_derivatives_of_fk_and_ik(name):
    """J = dp/dq by central differences of the closed-form FK, J^-1 = dq/dp by those of the IK,
    at well-conditioned points of every branch.

    Step and tolerance: a central difference errs by ~h^2 |f'''| / 6 (truncation) plus
    ~eps |f| / h (rounding). Points and actuator values are O(1) m or rad, so with h = 1e-6 the
    rounding is ~2e-16 / 1e-6 = 2e-10. With |f'''| ~ |J| / rho^2 for rho the distance to the
    nearest singularity or reach boundary, the truncation relative to |J| is ~h^2 / (6 rho^2),
    below 1e-6 for rho > 0.4 mm; keeping iota_I, iota_II > 0.1 keeps rho at centimetres (measured
    worst 3e-8 over these samples). A wrong sign, axis, length or transposition is an O(1) error.
    """
    mech = mechanism_of(load_robot(name))
    p = _sample(mech, 400, seed=4)
    h, rtol = 1e-6, 1e-6
    checked = 0
    for b, branch in enumerate(mech.branches):
        v, ok = mech.branch_velocity(p, branch, mech.limit_sets[-1])
        assert np.all(np.isnan(v.J[~ok]))
        regular = ok & (np.minimum(v.iota_I, v.iota_II) > 0.1)
        if not regular.any():
            continue
        pts = p[regular]
        q = mech.ik(pts, mech.limit_sets[-1]).q[:, b]
        rows = np.arange(len(pts))

        def fk_here(qq, pts=pts, rows=rows):  # the assembly mode nearest the branch's point
            asm = mech.fk(qq).p
            return asm[rows, np.nanargmin(np.linalg.norm(asm - pts[:, None], axis=-1), axis=1)]

        def ik_here(pp, b=b):
            return mech.ik(pp).q[:, b]

        for got, fd in ((v.J[regular], _central_differences(fk_here, q, h)),
                        (v.J_inverse[regular], _central_differences(ik_here, pts, h))):
            scale = np.abs(got).max(axis=(1, 2), keepdims=True)
            err = np.abs(got - fd) / scale
            assert np.all(err <= rtol), (branch, float(np.nanmax(err)))
        checked += len(pts)
    assert checked >= 50, "the sample must see enough regular points"


@pytest.mark.parametrize("name", ["p2us", "delta", "scara"])
def test_branch_velocities_are_each_branchs_velocity_at_its_ik(name):
    """`branch_velocities` (one IK of every branch, the velocity evaluated only where a branch
    exists) against `velocity` at each branch's own IK solution over every point, asked in the
    reverse of the mechanism's branch order: the same arithmetic on the same rows, so equal to
    1e-12 relative (rounding only); NaN and not inside where the branch does not exist."""
    mech = mechanism_of(load_robot(name))
    limits = mech.limit_sets[-1]
    p = _sample(mech, 300, seed=8)
    asked = list(reversed(mech.branches))
    res = mech.ik(p, limits)
    got = mech.branch_velocities(p, asked, limits)
    assert len(got) == len(asked)
    for branch, (v, ok) in zip(asked, got, strict=True):
        k = mech.branches.index(branch)
        want_ok = res.within_limits[:, k] & np.isfinite(res.q[:, k]).all(axis=-1)
        assert np.array_equal(ok, want_ok)
        assert np.isnan(v.J[~ok]).all() and np.isnan(v.iota_I[~ok]).all()
        if ok.any():
            ref = mech.velocity(p[ok], res.q[ok, k])
            assert np.allclose(v.J[ok], ref.J, rtol=1e-12, atol=0, equal_nan=True)
            assert np.allclose(v.iota_II[ok], ref.iota_II, rtol=1e-12, atol=0, equal_nan=True)
    assert sum(ok.sum() for _, ok in got) > 0, "the sample must reach some branch"


def test_finite_differences_of_ik_give_the_inverse_jacobian():
    """J^-1 = dq/dp from the closed forms of IK, by central differences (h = 1e-6 m: truncation
    ~h^2 |q'''| ~ 1e-12, rounding ~eps |q| / h ~ 1e-10)."""
    for name in ("p2us", "delta"):
        mech = mechanism_of(load_robot(name))
        p0, branch = mech.reference_pose()
        b = mech.branches.index(branch)
        h = 1e-6
        cols = []
        for k in range(3):
            d = np.zeros(3)
            d[k] = h
            cols.append((mech.ik((p0 + d)[None]).q[0, b] - mech.ik((p0 - d)[None]).q[0, b]) / (2 * h))
        v, _ = mech.branch_velocity(p0[None], branch)
        assert np.allclose(np.stack(cols, axis=1), v.J_inverse[0], atol=1e-7)


def test_the_serial_arm_jacobian_is_pinocchios():
    import pinocchio as pin

    robot = load_robot("ur5")
    mech = mechanism_of(robot)
    pin.seed(5)
    q = np.stack([pin.randomConfiguration(robot.model) for _ in range(5)])
    v = mech.velocity(np.zeros((5, 3)), q)
    for k in range(5):
        J = pin.computeFrameJacobian(robot.model, robot.data, q[k], robot.frame_id(), pin.LOCAL_WORLD_ALIGNED)[:3]
        assert np.allclose(v.J[k], J, atol=1e-12)
        s = np.linalg.svd(J, compute_uv=False)
        assert np.isclose(v.iota_I[k], s[-1] / s[0], rtol=1e-9)


def test_a_generic_loops_fk_and_velocity_take_and_give_its_task_coordinates():
    """The generic closed loop's fk returns points in the task coordinates its ik takes (the
    five-bar's plane: 2, not the world position's 3), so ik then fk returns the point on a branch
    the continuation from the reference reaches; bad actuator values are refused, not NaN, and an
    empty batch is an empty answer. Tolerance: the batched IK and the continuation each close the
    loops to ~1e-12 m; 1e-9 m leaves the same margin as tests/test_loop_batch.py."""
    from kinematics.errors import InvalidInputError

    mech = mechanism_of(load_robot(str(MODELS / "fivebar_gepetto" / "robot.urdf")))
    assert mech.task_dim == 2
    p = np.array([[0.1, 0.3], [0.05, 0.35]])
    res = mech.ik(p)
    assert res.reachable.all(axis=0).any()
    errors = []
    for b in np.flatnonzero(res.reachable.all(axis=0)):
        asm = mech.fk(res.q[:, b])
        assert asm.p.shape == (2, 1, 2)
        errors.append(np.linalg.norm(asm.p[:, 0] - p, axis=-1))
    assert np.nanmin(errors, axis=0).max() <= 1e-9
    for bad in (np.zeros((1, 3)), np.zeros((1, 1)), np.array([[np.nan, 0.0]]), 0.3):
        with pytest.raises(InvalidInputError, match="q"):
            mech.fk(bad)
    q = res.q[:, np.flatnonzero(res.reachable.all(axis=0))[0]]
    assert mech.velocity(p, q).J.shape == (2, 2, 2)
    empty = mech.velocity(np.zeros((0, 2)), np.zeros((0, 2)))
    assert empty.J.shape == (0, 2, 2) and empty.iota_I.shape == (0,)
    for bad in (np.zeros((2, 3)), q[:1], np.full((2, 2), np.nan)):
        with pytest.raises(InvalidInputError, match="q"):
            mech.velocity(p, bad)


@pytest.mark.parametrize("name", ["p2us", "delta"])
def test_the_single_pose_reports_refuse_a_batch_or_a_wrong_length(name):
    """pose_ik, pose_fk, pose_jacobians and joint_values take one point / one actuator vector: a
    (1, 3) row, 2 or 4 values are an InvalidInputError (a numpy ValueError, 'truth value of an
    array is ambiguous' or 'cannot reshape', before)."""
    from kinematics.errors import InvalidInputError

    mech = mechanism_of(load_robot(name))
    p, branch = mech.reference_pose()
    q = mech.ik(p[None]).q[0, mech.branches.index(branch)]
    assert mech.pose_fk(q).exists and mech.pose_ik(p).reachable.any()  # the single ones work
    for bad in (p[None], p[:2], np.append(p, 0.0)):
        for call, args in ((mech.pose_ik, (bad,)), (mech.pose_jacobians, (bad, q)), (mech.joint_values, (bad, branch))):
            with pytest.raises(InvalidInputError, match="position"):
                call(*args)
    word = "angles" if name == "delta" else "values"  # the family's closed forms say the same
    for bad in (q[None], q[:2], np.append(q, 0.0)):
        for call, args in ((mech.pose_fk, (bad,)), (mech.pose_jacobians, (p, bad))):
            with pytest.raises(InvalidInputError, match=f"q: .*{word}|q: expected one 3-vector"):
                call(*args)


def _analyses_given(robot):
    from kinematics.analyses import (
        dexterity,
        measure_workspace,
        singular_loci,
        synthesize,
        usable,
        volume_monte_carlo,
        workspace_mesh,
    )
    from kinematics.analyses.collision_volume import measure_collision_workspace

    return {"measure_workspace": lambda: measure_workspace(robot),
            "volume_monte_carlo": lambda: volume_monte_carlo(robot, 10, np.random.default_rng(0)),
            "singular_loci": lambda: singular_loci(robot), "usable": lambda: usable(robot, "cube"),
            "dexterity": lambda: dexterity(robot), "synthesize": lambda: synthesize(robot, []),
            "workspace_mesh": lambda: workspace_mesh(robot),
            "measure_collision_workspace": lambda: measure_collision_workspace(robot, robot)}


@pytest.mark.parametrize("analysis", sorted(_analyses_given(None)))
def test_an_analysis_given_a_robot_says_how_to_get_its_mechanism(analysis):
    # a Robot where a Mechanism belongs (the usual slip in a notebook) raised AttributeError
    # ('Robot' object has no attribute 'require') from inside each analysis
    with pytest.raises(InvalidInputError, match=rf"{analysis} takes a Mechanism .*a Robot: pass mechanism_of\(robot\)"):
        _analyses_given(load_robot("p2us"))[analysis]()
    with pytest.raises(InvalidInputError, match=rf"{analysis} takes a Mechanism .*got str"):
        _analyses_given("p2us")[analysis]()


def test_workspace_mesh_by_default_meshes_the_union_of_a_serial_arm():
    # the default branch was "---", which a serial arm (its union only) refused: now its union, a
    # closed surface within the bounding box (a coarse grid: only the refusal's absence is at stake)
    from kinematics.analyses import workspace_mesh

    mech = mechanism_of(load_robot("ur5"))
    mesh = workspace_mesh(mech, step=0.25).mesh
    lo, hi = mech.bounding_box("all")
    assert mesh.is_watertight and 0 < mesh.volume < np.prod(hi - lo)
    assert np.all(mesh.vertices >= lo - 0.25) and np.all(mesh.vertices <= hi + 0.25)


def _bisect_sign_change(f, a: np.ndarray, b: np.ndarray, iterations: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows a, b (N, d) where f: (N, d) -> (N,) has opposite signs, narrowed to 2^-iterations of
    their distance, a keeping f(a)'s sign."""
    fa = f(a)
    for _ in range(iterations):
        m = (a + b) / 2
        same = (np.sign(f(m)) == np.sign(fa))[:, None]
        a, b = np.where(same, m, a), np.where(same, b, m)
    return a, b


@pytest.mark.parametrize("name", ["p2us", "delta"])
def test_the_singular_fields_vanish_where_the_velocitys_measures_do(name):
    """`singular_fields` (signed fields for scans) against `velocity`'s iota_I / iota_II, two
    paths to the same loci: where a branch's det changes sign between neighbours on random
    segments (the branch existing at both), bisected to 2^-40 of the step (< 1e-13 m), iota_II
    vanishes; where a limb's field (its IK discriminant) changes sign, iota_I of every branch at
    the reaching end vanishes.

    Tolerances: det is smooth with a simple zero, so iota_II (a normalised |det|) at 1e-13 m from
    it is ~1e-13 x its gradient (O(10) per metre): 1e-9 holds (measured worst 1e-14). The
    discriminant Delta [m^2] is linear across its zero, and iota_I = min |n.w| ~ sqrt(Delta) / L
    (the two IK roots meet): at 1e-13 m, sqrt(1e-13 m x O(1) m) / 0.3 m ~ 1e-6; 1e-5 holds
    (measured worst 1e-7). A field whose zero set is not the measure's is off by O(step) ~ 1e-2."""
    mech = mechanism_of(load_robot(name))
    limits = "actuators"
    lo, hi = mech.bounding_box(limits)
    rng = np.random.default_rng(3)
    nseg, steps = 60, 40
    a, b = lo + (hi - lo) * rng.random((2, nseg, 3))
    seg = (a[:, None] + np.linspace(0, 1, steps)[None, :, None] * (b - a)[:, None])
    pts = seg.reshape(-1, 3)
    f = mech.singular_fields(pts, limits)
    reach = mech.ik(pts, limits).reachable.reshape(nseg, steps, -1)

    def crossings(field: np.ndarray, where: np.ndarray) -> tuple[np.ndarray, ...]:
        """(segment, step, column) of every sign change of field (N, c) between neighbours."""
        v = field.reshape(nseg, steps, -1)
        return np.nonzero((v[:, 1:] * v[:, :-1] < 0) & where)

    # type II: one bisection for every crossing of every branch's det (its column per row)
    s, j, k = crossings(f.det, reach[:, 1:] & reach[:, :-1])
    rows = np.arange(len(s))
    near, _ = _bisect_sign_change(lambda x: mech.singular_fields(x, limits).det[rows, k], seg[s, j], seg[s, j + 1], 40)
    res = mech.ik(near, limits)
    ok = res.reachable[rows, k]
    iota_II = mech.velocity(near[ok], res.q[rows, k][ok]).iota_II
    assert np.all(iota_II <= 1e-9), float(iota_II.max())
    # type I: every crossing of every limb's field; iota_I of each branch at the reaching end
    s, j, limb = crossings(f.limb, True)
    rows = np.arange(len(s))

    def field(x: np.ndarray) -> np.ndarray:
        return mech.singular_fields(x, limits).limb[rows, limb]

    x, y = _bisect_sign_change(field, seg[s, j], seg[s, j + 1], 40)
    reaching = np.where((field(x) >= 0)[:, None], x, y)
    res = mech.ik(reaching, limits)
    seen = [0, int(ok.sum())]
    for k in range(len(mech.branches)):
        ok = res.reachable[:, k]
        if ok.any():
            iota_I = mech.velocity(reaching[ok], res.q[ok, k]).iota_I
            assert np.all(iota_I <= 1e-5), (mech.branches[k], float(iota_I.max()))
            seen[0] += int(ok.sum())
    assert min(seen) >= 20, seen  # both loci were met


def test_a_generic_loops_velocity_is_the_derivative_of_its_fk_and_ik():
    """The generic closed loop's `velocity` (Jacobians of the batched solver's joint values, from
    the constraint matrices) against central differences of its own `fk` (Pinocchio's loop
    closure by `ClosedLoop.solve`) and `ik` (the batched solver), at seeded points of Gepetto's
    five-bar (tests/models), every branch, clear of singularities (iota_I, iota_II > 0.1); and
    `joint_values` there closes the loops in Pinocchio (`ClosedLoop.residual`).

    Tolerances: both solvers stop at residual rows <= 1e-12 m, so a central difference with
    h = 1e-5 carries ~1e-12 / 1e-5 = 1e-7 of solver noise, and truncation h^2 |f'''| / 6 ~
    h^2 / (6 rho^2) |J| ~ 2e-8 |J| at rho >= 3 cm from a singularity: 1e-5 |J| holds (measured
    worst 1.4e-9 relative over the 18 regular branches checked). A wrong sign, column or
    transposition is an O(1) error. The joint values are the batched solver's roots: their
    residual is <= 1e-12 per row (measured 2.5e-13), 1e-11 leaves rounding room for the tree's
    forward kinematics."""
    from kinematics.generic.closedloop import ClosedLoop

    robot = load_robot(str(MODELS / "fivebar_gepetto" / "robot.urdf"))
    mech = mechanism_of(robot)
    loop = ClosedLoop(robot)
    p = np.random.default_rng(21).uniform([-0.05, 0.22], [0.25, 0.45], (6, 2))
    res = mech.ik(p)
    h, checked = 1e-5, 0
    for i, b in np.argwhere(res.within_limits):
        q = res.q[i, b]
        v = mech.velocity(p[i][None], q[None])
        if min(v.iota_I[0], v.iota_II[0]) <= 0.1 or not np.linalg.norm(mech.fk(q).p[0, 0] - p[i]) <= 1e-9:
            continue  # near a singularity, or fk's continuation from the reference gets stuck or reaches another assembly
        J = np.stack([(mech.fk(q + h * e).p[0, 0] - mech.fk(q - h * e).p[0, 0]) / (2 * h) for e in np.eye(2)], axis=1)
        Ji = np.stack([(mech.ik((p[i] + h * e)[None]).q[0, b] - mech.ik((p[i] - h * e)[None]).q[0, b]) / (2 * h)
                       for e in np.eye(2)], axis=1)
        assert np.abs(J - v.J[0]).max() <= 1e-5 * np.abs(v.J[0]).max(), (p[i], b, J, v.J[0])
        assert np.abs(Ji - v.J_inverse[0]).max() <= 1e-5 * np.abs(v.J_inverse[0]).max(), (p[i], b, Ji, v.J_inverse[0])
        values = mech.joint_values(p[i], mech.branches[b])
        assert np.abs(loop.residual(robot.configuration([values[n] for n in robot.joint_names]))[0]).max() <= 1e-11
        checked += 1
    assert checked >= 12, "the sample must see enough regular branches"


@pytest.mark.parametrize("name", ["ur5", "panda", "double_pendulum"])
def test_a_serial_arms_velocity_and_box_hold_against_its_fk(name):
    """A serial arm's `velocity` (Pinocchio's batched frame Jacobian, the task rows: y, z for the
    planar double pendulum) against central differences of its `fk` (batched frame placements),
    and its `bounding_box` (the reach ball's, from link lengths) around `fk` of configurations drawn
    over the joint ranges (the pendulum's are given: its URDF has none).

    Tolerance: h = 1e-6 rad, truncation h^2 |p'''| / 6 <= 1e-12 x the arm's size (~1 m) and
    rounding eps |p| / h ~ 2e-10 m: 1e-8 m/rad holds (measured worst 2e-10). A wrong row, sign or
    joint column is off by O(link length). Containment is exact: the box is a proved bound (the
    draws come within 1-19 % of its size of each face: a face misplaced by more fails)."""
    ranges = {"joint1": (-np.pi, np.pi), "joint2": (-np.pi, np.pi)} if name == "double_pendulum" else None
    robot = load_robot(name, ranges=ranges)
    mech = mechanism_of(robot)
    q = np.random.default_rng(13).uniform(robot.lower, robot.upper, (300, robot.nv))
    p = mech.fk(q).p[:, 0]
    lo, hi = mech.bounding_box()
    assert np.all((p >= lo) & (p <= hi))
    h = 1e-6
    v = mech.velocity(p[:40], q[:40])
    fd = np.stack([(mech.fk(q[:40] + h * e).p[:, 0] - mech.fk(q[:40] - h * e).p[:, 0]) / (2 * h)
                   for e in np.eye(robot.nv)], axis=-1)
    assert v.J.shape == (40, mech.task_dim, robot.nv)
    np.testing.assert_allclose(v.J, fd, rtol=0, atol=1e-8)


@pytest.mark.parametrize("name", ["scara", "p2us", "delta", "ur5", str(MODELS / "fivebar_gepetto" / "robot.urdf")])
def test_every_margin_and_ik_refuse_what_is_no_batch_of_finite_points(name):
    """A margin is the volume engine's inner loop: the closed forms' (scara, p2us, delta) gave NaN
    margins for a NaN point, which an engine reads as "outside", while the serial arm's and the
    generic loop's refused it; text ("0 0 0") was numpy's ValueError in every family's ik, complex
    points lost their imaginary parts with a warning, a ragged list (the generic loop's) and an
    integer beyond a float's range raised numpy's errors. Now one check (`kinematics.inputs`)
    refuses each, naming the input, and a good batch still passes."""
    mech = mechanism_of(load_robot(name))
    d = mech.task_dim
    margin = mech.margin()
    good = np.zeros((2, d))
    assert margin(good).shape == (2, len(mech.branches) + 1)
    nan = good.copy()
    nan[1, 0] = np.nan
    ragged = [[0.0] * d, [0.0]]
    for bad, why in ((nan, "points: must be finite; row 1"), (np.zeros((2, d + 1)), "points: expected shape"),
                     ("0 0 0", "points: expected real numbers"), (ragged, "points: expected real numbers"),
                     (good + 1j, "points: expected real numbers"), ([[10**400] * d], "points: expected real numbers")):
        with pytest.raises(InvalidInputError, match=why):
            margin(bad)
    if "ik" in mech.capabilities:
        with pytest.raises(InvalidInputError, match="expected real numbers"):
            mech.ik("0 0 0")
