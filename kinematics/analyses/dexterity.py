"""Dexterity over a workspace, with error bars: the global conditioning index and the mean
Yoshikawa index of any `Mechanism`, per branch (working mode, elbow) and for their union.

Definitions, over the region W_b where branch b exists within the limits:

* GCI_b = (1/|W_b|) integral over W_b of 1/kappa dV (Gosselin & Angeles 1991), kappa =
  sigma_max / sigma_min of the forward Jacobian J (pdot = J qdot, `Mechanism.branch_velocity`), in
  [0, 1]. kappa is scale-free when J's columns share one unit (every actuator prismatic, or every
  one revolute: the 3-[P2(US)] (m/m), the Delta and the SCARA (m/rad)); for a chain that mixes
  prismatic and revolute actuators the value depends on the unit chosen for the angles: it is taken
  as 1 rad <-> 1 m, and `Dexterity.mixed_units` says so.
* Yoshikawa mean w_b = (1/|W_b|) integral of sqrt(det(J J^T)) dV, in (m/s per actuator unit/s)^d:
  dimensionless for the 3-[P2(US)], m^3/rad^3 for the Delta, m^2/rad^2 for the SCARA. Near a type II
  singularity the forward J grows like 1/distance, so where a type II surface crosses W_b the
  integral diverges (logarithmically); so it does where W_b's boundary runs along a type II
  surface. Two flags say when the sample mean cannot be trusted, and its error is then infinite:
  `yoshikawa_diverges` (a sign change of the mechanism's type II field between samples inside W_b:
  a type II surface crosses it) and `yoshikawa_heavy_tail` (one sample carries more than
  HEAVY_TAIL of the sum: the tail of w near a singularity dominates, and the replicates'
  spread understates the error).
* union: a point counts when any branch reaches it, and takes the best branch there (the largest
  1/kappa, the largest w): what a designer free to pick the branch gets.

Estimator (randomised quasi-Monte Carlo): R independent Owen-scrambled Sobol' point sets of n = 2^m
points each over the mechanism's bounding box. For target t and replicate r let c_r be the count
of points inside W_t and S_r the sum of 1/kappa over them. The estimate is the ratio
G = sum S_r / sum c_r, and its standard error the ratio estimator's over the R i.i.d. replicates,
se^2 = sum (S_r - G c_r)^2 / (R (R - 1) cbar^2); the reported error is t_{0.975, R-1} se, a 95 %
confidence half-width (Student t over the replicates, exact for normal replicate means, which
scrambled nets with n >= 2^10 come close to). The ratio's own bias is O(1/(R n)), far below se.
The volume |W_t| = box x mean(c_r / n) comes with the same kind of error bar. A target some
replicate misses entirely (a sliver of a working mode) gets an infinite error: its estimate rests
on a handful of points.

What can be missed: a part of W_t smaller than the points' spacing (n^(-1/d) of the box) that no
replicate samples; the error bar does not cover it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from kinematics.errors import InvalidInputError
from kinematics.sizes import check_points

if TYPE_CHECKING:
    from kinematics.mechanisms.base import Mechanism

HEAVY_TAIL = 0.01
"""Largest share of the Yoshikawa sum one sample may carry before the mean is called tail-dominated:
with a bounded w over N >= 10^3 inside samples, one carries about 1/N (<< 1 %)."""

CHUNK = 1 << 14
"""Points per Jacobian batch (bounds the (N, d, a) temporaries)."""
MAX_SAMPLES = 1 << 26
"""Points per replicate (64 Mi: minutes per replicate already)."""


@dataclass(frozen=True)
class Dexterity:
    """Global dexterity of a mechanism, per target (the chosen branches, then "union").

    Attributes:
        robot: the mechanism's name; limits: the limit set; targets: branch labels then "union".
        gci, gci_error: GCI and its 95 % half-width per target (NaN where the target is empty).
        yoshikawa, yoshikawa_error: mean Yoshikawa index and its half-width (inf where it diverges).
        yoshikawa_unit: the unit of w.
        yoshikawa_diverges: a type II surface crosses the target's region (module docstring).
        yoshikawa_heavy_tail: one sample carries more than HEAVY_TAIL of the Yoshikawa sum.
        volume, volume_error: the region's measure [m^3, m^2 for a planar arm] and half-width.
        inside: sample points inside each target (all replicates).
        samples: points per replicate; replicates: R; seed: the RNG seed.
        mixed_units: J's columns mix m and rad (kappa then depends on the angle unit).
        seconds: wall time.
    """

    robot: str
    limits: str
    targets: tuple[str, ...]
    gci: np.ndarray
    gci_error: np.ndarray
    yoshikawa: np.ndarray
    yoshikawa_error: np.ndarray
    yoshikawa_unit: str
    yoshikawa_diverges: np.ndarray
    yoshikawa_heavy_tail: np.ndarray
    volume: np.ndarray
    volume_error: np.ndarray
    inside: np.ndarray
    samples: int
    replicates: int
    seed: int
    mixed_units: bool
    planar: bool
    seconds: float
    parameters: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready report: top-level `gci`, `gci_error`, `yoshikawa_mean`, `yoshikawa_error` of
        the union of the branches asked for (`target`: "union", or the one branch's label), `modes` per branch, `samples`
        (points per replicate), `replicates`, `seconds`. Non-finite numbers become None."""
        key = "area_m2" if self.planar else "volume_m3"

        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        def entry(k: int) -> dict[str, Any]:
            return {"gci": num(self.gci[k]), "gci_error": num(self.gci_error[k]),
                    "yoshikawa_mean": num(self.yoshikawa[k]), "yoshikawa_error": num(self.yoshikawa_error[k]),
                    "yoshikawa_diverges": bool(self.yoshikawa_diverges[k]),
                    "yoshikawa_heavy_tail": bool(self.yoshikawa_heavy_tail[k]), key: float(self.volume[k]),
                    f"{key}_error": float(self.volume_error[k]), "points_inside": int(self.inside[k])}

        last = len(self.targets) - 1
        # one branch asked for: the union of it alone is that branch, named as such
        name = self.targets[0] if last == 1 else self.targets[last]
        return {
            "robot": self.robot, "limits": self.limits, "target": name, **entry(last),
            "modes": {t: entry(k) for k, t in enumerate(self.targets[:-1])},
            "yoshikawa_unit": self.yoshikawa_unit, "mixed_units": self.mixed_units,
            "confidence": 0.95, "samples": self.samples, "replicates": self.replicates, "seed": self.seed,
            "seconds": self.seconds, "parameters": self.parameters,
        }


def yoshikawa_unit(mech: Mechanism) -> str:
    """The unit of sqrt(det(J J^T)) for the mechanism's J [m per actuator unit]."""
    d = mech.task_dim
    if mech.actuator_unit == "m":
        return "1 (m/m)"
    if mech.actuator_unit == "rad":
        return f"m^{d}/rad^{d}"
    return f"m^{d}/(actuator unit)^{d} (m or rad per column)"


def _values(mech: Mechanism, points: np.ndarray, branches: Sequence[str], limits: str
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per branch at N points: inside (N, B), 1/kappa (N, B), w (N, B), type II sign (N, B) (0 unknown)."""
    from kinematics.analyses.usable import inverse_condition

    n, B = len(points), len(branches)
    inside = np.zeros((n, B), bool)
    inv = np.zeros((n, B))
    w = np.zeros((n, B))
    sign = np.zeros((n, B), np.int8)
    for k, b in enumerate(branches):
        v, ok = mech.branch_velocity(points, b, limits)
        inside[:, k] = ok
        inv[:, k] = np.where(ok, inverse_condition(v.J), 0.0)
        J = np.where(ok[:, None, None] & np.isfinite(v.J), v.J, 0.0)
        with np.errstate(invalid="ignore", over="ignore"):
            det = np.linalg.det(J @ np.swapaxes(J, -1, -2))
        # a non-finite J inside the branch is a type II pose: w is unbounded there
        w[:, k] = np.where(ok, np.where(np.isfinite(v.J).all(axis=(1, 2)), np.sqrt(np.maximum(det, 0.0)), np.inf),
                           0.0)
    if "singular_fields" in mech.capabilities:
        det_all = mech.singular_fields(points, limits).det
        cols = [mech.branches.index(b) for b in branches]
        sign = np.sign(np.nan_to_num(det_all[:, cols])).astype(np.int8)  # NaN: not evaluable there, unknown
    return inside, inv, w, sign


def _ratio(S: np.ndarray, c: np.ndarray, t: float) -> tuple[float, float]:
    """Pooled ratio sum S / sum c over replicates and its t half-width (NaN, NaN if c sums to 0;
    an infinite half-width when a replicate has no point inside: the spread of the others then
    says nothing about the error)."""
    R = len(c)
    if c.sum() == 0:
        return math.nan, math.nan
    G = float(S.sum() / c.sum())
    if (c == 0).any():
        return G, math.inf
    with np.errstate(invalid="ignore"):
        resid = S - G * c
        se = math.sqrt(float((resid**2).sum()) / (R * (R - 1))) / float(c.mean())
    return G, t * se if math.isfinite(se) else math.inf


def dexterity(mech: Mechanism, branches: Sequence[str] | None = None, *, limits: str = "all",
              samples: int = 1 << 14, replicates: int = 8, seed: int = 0) -> Dexterity:
    """GCI and mean Yoshikawa index, with 95 % error bars, per branch and for their union (module
    docstring).

    Args:
        branches: branch labels (default: every branch).
        samples: points per replicate, rounded up to a power of two (Sobol' balance).
        replicates: independent scramblings R (>= 2, for the error bar).
        seed: seeds the scramblings: the same seed gives the same numbers.
    """
    from scipy.stats import qmc
    from scipy.stats import t as student

    t0 = time.perf_counter()
    mech.require("ik", "dexterity over the workspace")
    mech.require("velocity", "dexterity over the workspace")
    mech.check_limits(limits)
    chosen = mech.check_branches(branches)
    if not (isinstance(replicates, int) and replicates >= 2):
        raise InvalidInputError("replicates", f"need at least 2 independent replicates for an error bar, got {replicates}")
    if samples < 16:
        raise InvalidInputError("samples", f"need at least 16 points per replicate, got {samples}")
    if samples > MAX_SAMPLES:
        raise InvalidInputError("samples", f"at most {MAX_SAMPLES:,} points per replicate, got {samples:,}")
    m = math.ceil(math.log2(samples))
    n = 1 << m
    check_points("samples", float(n) * replicates * len(chosen), hint="use fewer samples")
    lo, hi = (np.asarray(a, dtype=float) for a in mech.bounding_box(limits))
    box = float(np.prod(hi - lo))
    T = len(chosen) + 1
    c = np.zeros((replicates, T))
    S = np.zeros((replicates, T))
    Y = np.zeros((replicates, T))
    lo_sign = np.zeros(T, bool)
    hi_sign = np.zeros(T, bool)
    infinite = np.zeros(T, bool)
    w_max = np.zeros(T)
    seeds = np.random.SeedSequence(seed).spawn(replicates)
    for r in range(replicates):
        u = qmc.Sobol(mech.task_dim, scramble=True, seed=np.random.default_rng(seeds[r])).random_base2(m)
        pts = lo + (hi - lo) * u
        for s in range(0, n, CHUNK):
            inside, inv, w, sign = _values(mech, pts[s:s + CHUNK], chosen, limits)
            anyin = inside.any(axis=1)
            cols_in = np.column_stack([inside, anyin])
            cols_inv = np.column_stack([inv, inv.max(axis=1)])
            cols_w = np.column_stack([w, w.max(axis=1)])
            c[r] += cols_in.sum(axis=0)
            S[r] += cols_inv.sum(axis=0)
            infinite |= np.isinf(cols_w).any(axis=0)
            finite_w = np.where(np.isinf(cols_w), 0.0, cols_w)
            Y[r] += finite_w.sum(axis=0)
            w_max = np.maximum(w_max, finite_w.max(axis=0, initial=0.0))
            for k in range(T - 1):
                lo_sign[k] |= bool((sign[inside[:, k], k] < 0).any())
                hi_sign[k] |= bool((sign[inside[:, k], k] > 0).any())
    # the union's type II loci: any branch's
    lo_sign[-1] = hi_sign[-1] = bool((lo_sign[:-1] & hi_sign[:-1]).any())
    diverges = (lo_sign & hi_sign) | infinite
    with np.errstate(invalid="ignore", divide="ignore"):
        heavy = w_max > HEAVY_TAIL * Y.sum(axis=0)
    t = float(student.ppf(0.975, replicates - 1))
    gci = np.empty(T)
    gci_err = np.empty(T)
    yo = np.empty(T)
    yo_err = np.empty(T)
    vol = np.empty(T)
    vol_err = np.empty(T)
    for k in range(T):
        gci[k], gci_err[k] = _ratio(S[:, k], c[:, k], t)
        yo[k], yo_err[k] = _ratio(Y[:, k], c[:, k], t)
        if diverges[k] or heavy[k]:
            yo_err[k] = math.inf
        frac = c[:, k] / n
        vol[k] = box * float(frac.mean())
        vol_err[k] = box * t * float(frac.std(ddof=1)) / math.sqrt(replicates)
    from kinematics.mechanisms.base import UNION

    mixed = mech.actuator_unit not in ("m", "rad")
    return Dexterity(mech.name, limits, (*chosen, UNION), gci, gci_err, yo, yo_err, yoshikawa_unit(mech), diverges,
                     heavy, vol, vol_err, c.sum(axis=0).astype(int), n, replicates, seed, mixed, mech.task_dim == 2,
                     time.perf_counter() - t0, mech.parameters())


MAP_CELLS = 50
"""Default grid of the conditioning maps: this many steps along the bounding box's longest side."""


def conditioning_grid(mech: Mechanism, branch: str, *, limits: str = "all", step: float | None = None
                      ) -> tuple[list[np.ndarray], np.ndarray]:
    """1/kappa on a regular grid over the bounding box, for maps: (axes, values shaped like the
    grid; NaN outside the branch, or outside every branch for "union", where the best is taken).

    Args:
        step: grid step [m] (default: the box's longest side / MAP_CELLS).
    """
    from kinematics.mechanisms.base import UNION
    from kinematics.sizes import grid_points

    mech.check_limits(limits)
    chosen = mech.branches if branch == UNION else mech.check_branches([branch])
    lo, hi = (np.asarray(a, dtype=float) for a in mech.bounding_box(limits))
    step = float(np.max(hi - lo)) / MAP_CELLS if step is None else step
    if not (step > 0 and math.isfinite(step)):
        raise InvalidInputError("step", f"must be a positive number of metres, got {step!r}")
    check_points("step", grid_points(lo, hi, step) * len(chosen), hint="use a larger step")
    axes = [np.arange(a, b + step / 2, step) for a, b in zip(lo, hi, strict=True)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(axes))
    out = np.full(len(pts), np.nan)
    for s in range(0, len(pts), CHUNK):
        inside, inv, _, _ = _values(mech, pts[s:s + CHUNK], chosen, limits)
        best = np.where(inside, inv, -1.0).max(axis=1)
        out[s:s + CHUNK] = np.where(best >= 0, best, np.nan)
    return axes, out.reshape([len(a) for a in axes])
