"""Joint-space references of the planar 2R arm, independent of the volume engine and of the
singular-locus scan: its singular set on a joint grid with the smallest-radius map, and its
reachable area by a quadrature over the radius."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from kinematics.errors import InvalidInputError
from kinematics.mechanisms.scara.closed_form import ELBOWS, ScaraParams, det_jacobian, fk, manipulability
from kinematics.sizes import check_points


def singular_set(sp: ScaraParams, step: float = math.radians(1.0)) -> dict[str, Any]:
    """The SCARA's singular set within its joint limits and a map of the smallest radius.

    det J = l1 l2 sin(theta2) vanishes at theta2 = 0 (arm stretched, tip on r = l1 + l2) and at
    theta2 = +/-pi (folded; outside the joint-2 range here). The locus is found on a joint grid of
    step `step` [rad] by sign changes of det J along theta2 and interpolated; the smallest
    manipulability radius is mapped on the same grid.
    """
    if not (math.isfinite(step) and step > 0):
        raise InvalidInputError("step", f"must be a positive angle [rad], got {step}")
    w1, w2 = sp.upper[0] - sp.lower[0], sp.upper[1] - sp.lower[1]
    # workspace-volume scans at the default step: the ranges (--range) are what its user can change
    check_points("angle step", (w1 / step + 1) * (w2 / step + 1),
                 hint=f"{math.degrees(step):g} deg is too fine a joint-grid step for joint ranges of {w1:.3g} and "
                      f"{w2:.3g} rad (a coarser --angle-step-deg, or narrower --range)")
    t1 = np.linspace(sp.lower[0], sp.upper[0], max(2, math.ceil((sp.upper[0] - sp.lower[0]) / step) + 1))
    t2 = np.linspace(sp.lower[1], sp.upper[1], max(2, math.ceil((sp.upper[1] - sp.lower[1]) / step) + 1))
    Q = np.stack(np.meshgrid(t1, t2, indexing="ij"), axis=-1)
    det = det_jacobian(sp, Q)
    ell = manipulability(sp, Q)
    a, b = det[:, :-1], det[:, 1:]
    hit = (a == 0) | ((a > 0) != (b > 0))
    i, j = np.nonzero(hit)
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.where(a[i, j] == b[i, j], 0.0, a[i, j] / (a[i, j] - b[i, j]))
    theta2 = t2[j] + frac * (t2[j + 1] - t2[j])
    qs = np.stack([t1[i], theta2], axis=-1)
    points = fk(sp, qs) if len(qs) else np.empty((0, 2))
    return {
        "theta1": t1, "theta2": t2, "min_radius": ell.radii[..., 0], "det": det,
        "singular_q": qs, "singular_points": points,
        "theta2_zero_within_limits": bool(sp.lower[1] <= 0.0 <= sp.upper[1]),
        "theta2_pi_within_limits": bool(sp.lower[1] <= -math.pi or sp.upper[1] >= math.pi),
    }


def area_quadrature(sp: ScaraParams, n: int = 20001, elbows: Sequence[str] = ELBOWS) -> float:
    """Reachable area [m^2] as the integral over r of r x (measure of reachable polar angles).

    At radius r each elbow's theta2 is fixed, and theta1 sweeps its range, so that elbow covers
    the arc [lower1, upper1] + psi(theta2) of polar angles; the arcs' union is measured on the
    circle. Composite Simpson over r in [|l1 - l2|, l1 + l2].
    """
    inner, outer = sp.reach
    r = np.linspace(inner, outer, n)
    c2 = np.clip((r * r - sp.l1**2 - sp.l2**2) / (2 * sp.l1 * sp.l2), -1.0, 1.0)
    width = sp.upper[0] - sp.lower[0]
    arcs = []
    for elbow in elbows:
        t2 = (-1.0 if elbow == "up" else 1.0) * np.arccos(c2)
        ok = (t2 >= sp.lower[1]) & (t2 <= sp.upper[1])
        start = sp.lower[0] + np.arctan2(sp.l2 * np.sin(t2), sp.l1 + sp.l2 * np.cos(t2))
        arcs.append((start, ok))
    measure = np.zeros(n)
    for k in range(n):
        ivs = [(a[k] % (2 * math.pi), width) for a, ok in arcs if ok[k]]
        measure[k] = _circle_union(ivs)
    f = r * measure
    h = (outer - inner) / (n - 1)
    return float(h / 3 * (f[0] + f[-1] + 4 * f[1:-1:2].sum() + 2 * f[2:-1:2].sum()))


def _circle_union(arcs: list[tuple[float, float]]) -> float:
    """Total length of a union of arcs (start in [0, 2 pi), length) on the unit circle."""
    if not arcs:
        return 0.0
    if any(w >= 2 * math.pi for _, w in arcs):
        return 2 * math.pi
    pieces = []
    for s, w in arcs:
        e = s + w
        if e > 2 * math.pi:
            pieces += [(s, 2 * math.pi), (0.0, e - 2 * math.pi)]
        else:
            pieces.append((s, e))
    pieces.sort()
    total, cur_s, cur_e = 0.0, *pieces[0]
    for s, e in pieces[1:]:
        if s > cur_e:
            total += cur_e - cur_s
            cur_s, cur_e = s, e
        else:
            cur_e = max(cur_e, e)
    return total + cur_e - cur_s
