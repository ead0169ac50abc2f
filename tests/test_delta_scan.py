"""The compiled Delta scan kernel against the NumPy closed forms, and the Delta's bounding box."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.mechanisms.delta import closed_form as cf
from kinematics.mechanisms.delta.mechanism import Delta, limb_margins
from kinematics.mechanisms.delta.scan import scan

DESIGNS = {
    "default": cf.DeltaParams(),
    # a lopsided design: unequal limb angles, a wide actuator range, tight cones, tilted sockets
    "lopsided": cf.DeltaParams(R=0.25, r=0.08, la=0.35, lb=0.7, alpha=(0.1, 2.0, 4.4),
                               theta_limits=(-1.2, 2.0), cone=0.5, elbow_socket=1.2, platform_socket=0.4),
}
_ROOTS = np.array([[0 if c == "+" else 1 for c in m] for m in cf.MODES])  # (8, 3)


def _points(params: cf.DeltaParams, n: int, seed: int) -> np.ndarray:
    lo, hi = Delta(params).bounding_box("actuators")
    mid, half = (lo + hi) / 2, 0.6 * (hi - lo)  # beyond the box: limbs that cannot reach too
    return mid - half + 2 * half * np.random.default_rng(seed).random((n, 3))


@pytest.mark.parametrize("design", DESIGNS)
@pytest.mark.parametrize("limits", ["all", "actuators"])
def test_kernel_equals_the_numpy_closed_forms(design, limits):
    params = DESIGNS[design]
    p = _points(params, 60000, seed=11)
    s = scan(params, p, passive=limits == "all")
    lm = limb_margins(params, p, limits)  # (N, 3, 2)
    ref = lm[:, np.arange(3), _ROOTS].min(axis=-1)  # (N, 8)
    limbs = cf.limb_ik(params, p)
    disc = (params.lb - limbs.near) * (limbs.far - params.lb)
    n = limbs.n[:, np.arange(3), _ROOTS]
    det = np.linalg.det(np.where(np.isfinite(n), n, 0.0))
    # Away from a limb's reach boundary (|rho^2 - K^2| > 1e-6 m^2) theta = phi0 +/- atan2(sqrt(disc), K)
    # is well conditioned and both paths round the same metre-sized terms in a different order: ~10
    # operations of 1e-16 relative each, times l_b and the slope 1/sin(cone) of the cone test's acos
    # where it binds (2.1 for the lopsided design's 0.5 rad) -> 1e-15 x 10 x 2.1 x 10 (margin) ~ 2e-13 m. Within
    # 1e-6 m^2 of it sqrt amplifies a rounding of disc (~1e-16 m^2) to ~1e-8 rad, l_a x that in metres.
    far = (np.abs(limbs.near - params.lb) > 1e-6) & (np.abs(limbs.far - params.lb) > 1e-6)
    far = far.all(axis=1)
    assert far.mean() > 0.9
    # Below l_b (2 cone - pi) a binding cone angle lies within `cone` of pi, where acos's slope
    # 1/sin(angle) exceeds 1/sin(cone) (the kernel takes cos(theta) from the roots' closed form, the
    # NumPy path from cos(theta), a few ulps apart); at these samples sin(angle) > 1e-3 (angles within
    # 1e-3 of pi: a fraction ~1e-6 of the box), so 1e-15 x 10 x 1e3 x 10 ~ 1e-10 m (5e-13 seen).
    tight = far[:, None] & (ref >= params.lb * (2 * params.cone - np.pi))
    np.testing.assert_allclose(s.margin[tight], ref[tight], rtol=0, atol=2e-13)
    np.testing.assert_allclose(s.margin[far], ref[far], rtol=0, atol=1e-10)
    np.testing.assert_allclose(s.margin, ref, rtol=0, atol=1e-7)
    np.testing.assert_allclose(s.disc, disc, rtol=0, atol=1e-15)  # the same expression, the same rounding
    np.testing.assert_allclose(s.det[far], det[far], rtol=0, atol=1e-13)  # a 3x3 det of unit vectors
    inside = (ref >= 0).any(axis=1)
    assert 100 < inside.sum() < len(p) - 100, "the sample must straddle the workspace boundary"
    clear = np.abs(ref) > 1e-7
    assert np.array_equal(s.margin[clear] >= 0, ref[clear] >= 0)


@pytest.mark.parametrize("design", DESIGNS)
@pytest.mark.parametrize("limits", ["all", "actuators"])
def test_the_bounding_box_holds_the_workspace(design, limits):
    params = DESIGNS[design]
    mech = Delta(params)
    lo, hi = mech.bounding_box(limits)
    p = _points(params, 400000, seed=12)  # a region 1.2 x the widest (actuators) box
    inside = cf.ik(params, p, limits=limits == "all").within_limits.any(axis=1)
    q = p[inside]
    assert len(q) > 1000
    assert np.all((q >= lo) & (q <= hi))


def test_every_limit_box_is_much_smaller_than_the_reach_balls():
    """The ball-joint cones keep the platform below the base: the every-limit box's top is lower
    than the actuators-only box's by at least l_b cos(platform socket + cone) (the rod cannot
    point higher than that above the horizontal)."""
    params = DESIGNS["default"]
    mech = Delta(params)
    top_all = mech.bounding_box("all")[1][2]
    top_act = mech.bounding_box("actuators")[1][2]
    assert top_act - top_all >= params.lb * np.cos(params.platform_socket + params.cone) - 1e-12


@pytest.mark.parametrize("name", ["delta", "p2us"])
def test_kernels_report_their_compile_state(name):
    """After a run the kernels are in Numba's cache, under the names `kinematics.jit` looks for
    (a stale name made the "compiling kernels" notice print on every run)."""
    from kinematics import jit
    from kinematics.mechanisms import mechanism_of
    from kinematics.model.robot import load_robot

    mech = mechanism_of(load_robot(name))
    kernels = mech.kernels()
    assert kernels
    lo, hi = mech.bounding_box()
    mech.margin()(np.array([(lo + hi) / 2]))
    if name in ("p2us", "delta"):  # their exact-columns kernels run in the volume engine
        from kinematics.analyses.columns import column_volume

        column_volume(mech.margin(["---"]), lo, hi, step=0.05, rtol=1e-2)
    if any(k.stats.cache_path is None for k in kernels):
        pytest.skip("Numba has no writable cache directory here")
    assert jit.cached(kernels)
    assert isinstance(jit.compiled(kernels), bool)
