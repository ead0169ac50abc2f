"""Workspaces: the 3-[P2(US)]'s volume per working mode and their union, the SCARA's area.

Both are measured by `kinematics.columns.column_volume` (exact columns, adaptive quadrature, with
an error estimate) on a continuous margin (> 0 inside); the earlier cell-refinement estimator
`kinematics.volume.adaptive_volume` stays available (engine="cells", used by the design sweep and
the benchmark):

* 3-[P2(US)]: the fused kernel's per-mode margin (`p2us_scan`); the union is their maximum;
* SCARA: per elbow, the smallest of the reach slacks (l1 + l2 - r, r - |l1 - l2|) [m] and the
  joint-limit slacks [rad] times l1 + l2 (~ the tip's travel to the limit) [m].

Every limit comes from the URDF (through `read_params` / `ScaraParams.from_robot`). Two
independent checks, used by the tests: a Monte-Carlo volume from the NumPy closed forms of
`kinematics.parallel`, and the SCARA's area by a 1D quadrature over the radius.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .columns import ColumnVolume, column_volume
from .errors import UnknownModeError
from .p2us_scan import bounding_box, check_limits, scan
from .parallel import MODES, P2USParams
from .scara import ELBOWS, ScaraParams
from .volume import VolumeEstimate, adaptive_volume

UNION = "union"


@dataclass(frozen=True)
class Workspace:
    """A measured workspace.

    Attributes:
        robot: its name. planar: area [m^2] rather than volume [m^3].
        targets: the regions measured, e.g. ("---", "union") or ("up", "down", "union").
        limits: "all" or "actuators".
        result: the measurement, one entry per target (ColumnVolume; VolumeEstimate for the
            "cells" engine).
        seconds: wall time of the measurement.
    """

    robot: str
    planar: bool
    targets: tuple[str, ...]
    limits: str
    result: ColumnVolume | VolumeEstimate
    seconds: float
    parameters: dict[str, Any] = field(default_factory=dict)

    @property
    def total(self) -> float:
        """The union's measure [m^3 or m^2]."""
        return float(self.result.estimate[-1])

    @property
    def error(self) -> float:
        """The union's estimated error [m^3 or m^2]."""
        return float(self.result.error[-1])

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready report with the issue's stable keys (volume_m3 / area_m2, error_estimate,
        converged, modes / elbows, seconds)."""
        r = self.result
        unit = "m2" if self.planar else "m3"
        key = "area" if self.planar else "volume"
        per = {name: {key: float(r.estimate[k]), "error_estimate": float(r.error[k])}
               for k, name in enumerate(self.targets[:-1])}
        box = r.box
        out: dict[str, Any] = {
            "robot": self.robot,
            "limits": self.limits,
            f"{key}_{unit}": self.total,
            "error_estimate": self.error,
            "rtol": r.rtol,
            "converged": r.converged,
            "elbows" if self.planar else "modes": per,
            "bbox": [box[0].tolist(), box[1].tolist()],
            "points_evaluated": r.points_evaluated,
            "step_m": r.step,
            "seconds": self.seconds,
            "parameters": self.parameters,
        }
        if isinstance(r, ColumnVolume):
            out.update(method="columns", columns=r.columns)
        else:
            out.update(method="cells", **{f"bounds_{unit}": [float(r.lower[-1]), float(r.upper[-1])]},
                       finest_step_m=r.finest_step)
        return out


def _check_modes(modes: Sequence[str], valid: Sequence[str]) -> tuple[str, ...]:
    for m in modes:
        if m not in valid:
            raise UnknownModeError(m, tuple(valid))
    if not modes:
        raise UnknownModeError("", tuple(valid))
    return tuple(dict.fromkeys(modes))


# -- 3-[P2(US)] -----------------------------------------------------------------------------------
def p2us_margin(params: P2USParams, modes: Sequence[str] = MODES, limits: str = "all"
                ) -> Callable[[np.ndarray], np.ndarray]:
    """points (N, 3) -> (N, len(modes) + 1) margins [m]: each mode, then their union (max)."""
    modes = _check_modes(modes, MODES)
    check_limits(limits)
    return P2USMargin(params, [MODES.index(m) for m in modes], limits)


class P2USMargin:
    """The 3-[P2(US)] margin as `p2us_margin` returns it: callable on points, and with
    `exact_columns` (`p2us_exact.ExactColumns`), which `column_volume` uses instead of sampling."""

    def __init__(self, params: P2USParams, cols: list[int], limits: str) -> None:
        from .p2us_exact import ExactColumns

        self.params, self.cols, self.limits = params, cols, limits
        self.exact_columns = ExactColumns(params, np.array(cols), limits)

    def __call__(self, points: np.ndarray) -> np.ndarray:
        m = scan(self.params, points, self.limits).margin[:, self.cols]
        return np.concatenate([m, m.max(axis=1, keepdims=True)], axis=1)

    def sampled(self) -> Callable[[np.ndarray], np.ndarray]:
        """The same margin without exact columns (the engine then samples every column)."""
        def margin(points: np.ndarray) -> np.ndarray:
            return self(points)

        return margin


def _measure(margin: Callable[[np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray, step: float,
             rtol: float | None, engine: str, progress: bool, max_points: int | None, check: bool
             ) -> ColumnVolume | VolumeEstimate:
    if engine == "cells":
        kw = {} if max_points is None else {"max_points": max_points}
        return adaptive_volume(margin, lo, hi, step, rtol, progress=progress, **kw)
    if engine != "columns":
        from .errors import UnknownChoiceError

        raise UnknownChoiceError(engine, ("columns", "cells"))
    kw = {} if max_points is None else {"max_points": max_points}
    return column_volume(margin, lo, hi, step=step, rtol=1e-2 if rtol is None else rtol, check=check,
                         progress=progress, **kw)


def p2us_workspace(params: P2USParams, *, step: float = 0.005, rtol: float | None = 1e-4,
                   modes: Sequence[str] = MODES, limits: str = "all", name: str = "p2us",
                   progress: bool = False, max_points: int | None = None, engine: str = "columns",
                   check: bool = False) -> Workspace:
    """Volume of the 3-[P2(US)] workspace per working mode and of their union [m^3].

    engine "columns" (default): `column_volume` with column sampling step `step` [m] and relative
    tolerance `rtol` on its error estimate; "cells": the cell-refinement estimator with grid step
    `step`. check: rerun at half the step and compare (columns only).
    """
    modes = _check_modes(modes, MODES)
    lo, hi = bounding_box(params)
    t0 = time.perf_counter()
    res = _measure(p2us_margin(params, modes, limits), lo, hi, step, rtol, engine, progress, max_points, check)
    return Workspace(name, False, (*modes, UNION), limits, res, time.perf_counter() - t0, params.as_dict())


def p2us_volume_monte_carlo(params: P2USParams, n: int, rng: np.random.Generator,
                            limits: str = "all") -> tuple[float, float]:
    """Union volume [m^3] and its standard error by uniform sampling of the bounding box, through
    the NumPy closed forms (`parallel.ik`), independent of the scan kernel."""
    from .parallel import ik

    lo, hi = bounding_box(params)
    p = lo + (hi - lo) * rng.random((n, 3))
    inside = ik(params, p, limits=check_limits(limits)).within_limits.any(axis=-1)
    box = float(np.prod(hi - lo))
    frac = float(inside.mean())
    return box * frac, box * math.sqrt(frac * (1 - frac) / n)


# -- SCARA ----------------------------------------------------------------------------------------
def scara_margin(sp: ScaraParams, elbows: Sequence[str] = ELBOWS) -> Callable[[np.ndarray], np.ndarray]:
    """points (N, 2) -> (N, len(elbows) + 1) margins [m]: each elbow, then their union."""
    elbows = _check_modes(elbows, ELBOWS)
    inner, outer = sp.reach
    lo, hi = np.asarray(sp.lower), np.asarray(sp.upper)

    def margin(points: np.ndarray) -> np.ndarray:
        x, y = points[:, 0], points[:, 1]
        r = np.hypot(x, y)
        reach = np.minimum(outer - r, r - inner)
        # joint angles of each elbow with the radius clamped into the annulus: continuous, and
        # exactly the IK inside it
        rc = np.clip(r, inner, outer)
        c2 = np.clip((rc * rc - sp.l1**2 - sp.l2**2) / (2 * sp.l1 * sp.l2), -1.0, 1.0)
        phi = np.arctan2(y, x)
        cols = []
        for elbow in elbows:
            t2 = (-1.0 if elbow == "up" else 1.0) * np.arccos(c2)
            t1 = phi - np.arctan2(sp.l2 * np.sin(t2), sp.l1 + sp.l2 * np.cos(t2))
            t1 = (t1 + math.pi) % (2 * math.pi) - math.pi
            q = np.stack([t1, t2], axis=-1)
            joint = np.minimum(q - lo, hi - q).min(axis=-1) * outer
            cols.append(np.minimum(reach, joint))
        m = np.stack(cols, axis=1)
        return np.concatenate([m, m.max(axis=1, keepdims=True)], axis=1)

    return margin


def scara_workspace(sp: ScaraParams, *, step: float = 0.005, rtol: float | None = 1e-4,
                    elbows: Sequence[str] = ELBOWS, name: str = "scara", progress: bool = False,
                    engine: str = "columns", check: bool = False) -> Workspace:
    """Reachable area of the planar arm per elbow and of their union [m^2] (engines as
    `p2us_workspace`)."""
    elbows = _check_modes(elbows, ELBOWS)
    outer = sp.reach[1]
    t0 = time.perf_counter()
    res = _measure(scara_margin(sp, elbows), np.full(2, -outer), np.full(2, outer) + 1e-9, step, rtol, engine,
                   progress, None, check)
    return Workspace(name, True, (*elbows, UNION), "all", res, time.perf_counter() - t0,
                     {"l1": sp.l1, "l2": sp.l2, "lower": list(sp.lower), "upper": list(sp.upper)})


def scara_area_quadrature(sp: ScaraParams, n: int = 20001, elbows: Sequence[str] = ELBOWS) -> float:
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
