"""Dexterity over a workspace, with error bars: the global conditioning index, the mean
Yoshikawa index and the mean smallest radius of any `Mechanism` (closed forms or a serial arm's
reachability search), per branch (working mode, elbow) and for their union, and per cell of a
coarse grid (`kinematics.analyses.dexterity_cells`).

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
* smallest radius: the mean over W_b of sigma_d(J), the smallest semi-axis of the velocity
  ellipsoid {J qdot : |qdot| <= 1} (d the task dimension; 0 when J has fewer columns than d), in
  m/rad or m/m: the speed the tool is sure of in its worst direction per unit joint speed.
* union: a point counts when any branch reaches it, and takes the best branch there (the largest
  1/kappa, the largest w, the largest radius, each on its own): what a designer free to pick the
  branch gets.
* serial arms (no branches, no closed forms: `ReachingJacobians`): a point is inside when one of
  the reachability search's seeds (its `restarts` nearest joint-space samples, each descended by
  bounded Levenberg-Marquardt to its end: `kinematics.mechanisms.serial.reach`) reaches it within
  the joint limits, and J is the position Jacobian at a reaching configuration, the best one per
  index. For a non-redundant arm these configurations are its inverse-kinematics solutions (elbow
  up/down, shoulder left/right ...) whose basin holds a seed, so the value is the union's rule;
  for a redundant arm (7 joints for a 3-D position, or 6 with the orientation free) it is the best
  over up to `restarts` points of the self-motion set, a lower bound on the best over the whole
  set. A solution no seed falls towards is not seen (the indices are then low, never high).

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
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from kinematics.analyses.dexterity_cells import CellGrid, CellTable, ratio_errors
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

UNION_RULE = "the best branch at each point, per index"
SEARCH_RULE = ("the best, per index, over the configurations the reachability search reaches the point with "
               "from its seeds (each of the nearest joint-space samples descended to its end)")
"""How a point's indices are chosen: over branches (closed forms), over a serial arm's search."""


@runtime_checkable
class ReachingJacobians(Protocol):
    """A mechanism without branches whose points are reached by a search (a serial arm,
    `SerialArm.reaching_jacobians`): Jacobians (N, K, d, a) at the K configurations tried per point
    and whether each reached it (N, K)."""

    def reaching_jacobians(self, points: np.ndarray, limits: str = "all") -> tuple[np.ndarray, np.ndarray]: ...


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
        radius, radius_error: mean smallest radius sigma_d of the velocity ellipsoid and its half-width.
        volume, volume_error: the region's measure [m^3, m^2 for a planar arm] and half-width.
        inside: sample points inside each target (all replicates).
        samples: points per replicate; replicates: R; seed: the RNG seed.
        mixed_units: J's columns mix m and rad (kappa then depends on the angle unit).
        cells: the union's per-cell table (`dexterity_cells.CellTable`), None unless asked for.
        configurations: how a point's Jacobian is chosen (branches, or a serial arm's search).
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
    radius: np.ndarray
    radius_error: np.ndarray
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
    cells: CellTable | None = None
    configurations: str = UNION_RULE

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready report: top-level `gci`, `gci_error`, `kappa_harmonic_mean`, `yoshikawa_mean`,
        `yoshikawa_error`, `smallest_radius_mean`, `smallest_radius_error` of the union of the
        branches asked for (`target`: "union", or the one branch's label), `modes` per branch,
        `cells` (the union's per-cell table, when asked for), `configurations`, `samples` (points
        per replicate), `replicates`, `seconds`. Non-finite numbers become None."""
        key = "area_m2" if self.planar else "volume_m3"

        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        def entry(k: int) -> dict[str, Any]:
            g = float(self.gci[k])
            return {"gci": num(g), "gci_error": num(self.gci_error[k]),
                    "kappa_harmonic_mean": num(1.0 / g) if g > 0 else None,
                    "yoshikawa_mean": num(self.yoshikawa[k]), "yoshikawa_error": num(self.yoshikawa_error[k]),
                    "yoshikawa_diverges": bool(self.yoshikawa_diverges[k]),
                    "yoshikawa_heavy_tail": bool(self.yoshikawa_heavy_tail[k]),
                    "smallest_radius_mean": num(self.radius[k]), "smallest_radius_error": num(self.radius_error[k]),
                    key: float(self.volume[k]), f"{key}_error": float(self.volume_error[k]),
                    "points_inside": int(self.inside[k])}

        last = len(self.targets) - 1
        # one branch asked for: the union of it alone is that branch, named as such
        name = self.targets[0] if last == 1 else self.targets[last]
        out = {
            "robot": self.robot, "limits": self.limits, "target": name, **entry(last),
            "modes": {t: entry(k) for k, t in enumerate(self.targets[:-1])},
            "yoshikawa_unit": self.yoshikawa_unit, "mixed_units": self.mixed_units,
            "smallest_radius_unit": radius_unit(self.yoshikawa_unit),
            "configurations": self.configurations,
            "confidence": 0.95, "samples": self.samples, "replicates": self.replicates, "seed": self.seed,
            "seconds": self.seconds, "parameters": self.parameters,
        }
        if self.cells is not None:
            g = self.cells.grid
            out["cells"] = {"step_m": g.step, "origin": g.origin.tolist(), "shape": list(g.shape),
                            "rows": self.cells.rows(self.planar)}
        return out


def radius_unit(yoshikawa: str) -> str:
    """The unit of sigma_d(J) (a column's) from the Yoshikawa index's (`yoshikawa_unit`)."""
    if yoshikawa.startswith("1 "):
        return "1 (m/m)"
    return "m/rad" if "/rad^" in yoshikawa else "m/(actuator unit) (m or rad per column)"


def yoshikawa_unit(mech: Mechanism) -> str:
    """The unit of sqrt(det(J J^T)) for the mechanism's J [m per actuator unit]."""
    d = mech.task_dim
    if mech.actuator_unit == "m":
        return "1 (m/m)"
    if mech.actuator_unit == "rad":
        return f"m^{d}/rad^{d}"
    return f"m^{d}/(actuator unit)^{d} (m or rad per column)"


def indices(J: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per (..., d, a) Jacobian: 1/kappa, w = sqrt(det(J J^T)) and the smallest radius sigma_d
    (the d-th singular value: 0 when a < d). A non-finite J (a type II pose) gives 1/kappa = 0,
    w = inf and radius 0."""
    from kinematics.analyses.usable import singular_ratio

    J = np.asarray(J, dtype=float)
    d, a = J.shape[-2:]
    finite = np.isfinite(J).all(axis=(-2, -1))
    inv, w, rad = np.zeros(J.shape[:-2]), np.full(J.shape[:-2], np.inf), np.zeros(J.shape[:-2])
    sv = np.linalg.svd(J[finite], compute_uv=False)  # one SVD, of the finite rows only
    inv[finite] = singular_ratio(sv)
    w[finite] = np.prod(sv, axis=-1) if a >= d else 0.0  # sqrt(det(J J^T)) = prod of the d sigmas
    rad[finite] = sv[..., d - 1] if a >= d else 0.0
    return inv, w, rad


def _values(mech: Mechanism, points: np.ndarray, branches: Sequence[str], limits: str
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per target (the branches, then their union) at N points: inside, 1/kappa, w, smallest radius
    (N, T), and each branch's type II sign (N, B) (0 unknown). The union takes the best value of each
    index over the branches reaching the point; a mechanism without branches (a serial arm), the best
    over the configurations its search reaches the point with (`reaching_jacobians`)."""
    n, B = len(points), len(branches)
    sign = np.zeros((n, B), np.int8)
    if isinstance(mech, ReachingJacobians) and not branches:
        J, ok = mech.reaching_jacobians(points, limits)
    else:
        J = np.full((n, B, mech.task_dim, 1), np.nan)
        ok = np.zeros((n, B), bool)
        for k, (v, ok[:, k]) in enumerate(mech.branch_velocities(points, branches, limits)):
            if k == 0:
                J = np.full((n, B, *v.J.shape[1:]), np.nan)
            J[:, k] = v.J
    inv, w, rad = (np.where(ok, x, 0.0) for x in indices(J))
    if branches and "singular_fields" in mech.capabilities:
        det_all = mech.singular_fields(points, limits).det
        idx = [mech.branches.index(b) for b in branches]
        sign = np.sign(np.nan_to_num(det_all[:, idx])).astype(np.int8)  # NaN: not evaluable there, unknown
    per: list[np.ndarray] = []
    for x in (ok, inv, w, rad):
        best = np.asarray(x.max(axis=1, initial=0))
        per.append(best[:, None] if not branches else np.column_stack([x, best]))
    return per[0], per[1], per[2], per[3], sign


def dexterity(mech: Mechanism, branches: Sequence[str] | None = None, *, limits: str = "all",
              samples: int = 1 << 14, replicates: int = 8, seed: int = 0, cells: int | None = None) -> Dexterity:
    """GCI, mean Yoshikawa index and mean smallest radius, with 95 % error bars, per branch and for
    their union (module docstring); with `cells`, the union's per-cell table too.

    Args:
        branches: branch labels (default: every branch; a serial arm has none: its union).
        samples: points per replicate, rounded up to a power of two (Sobol' balance).
        replicates: independent scramblings R (>= 2, for the error bar).
        seed: seeds the scramblings: the same seed gives the same numbers.
        cells: steps of the per-cell grid along the bounding box's longest side (None: no table).
    """
    from kinematics.mechanisms.base import check_mechanism

    check_mechanism(mech, "dexterity")
    from scipy.stats import qmc
    from scipy.stats import t as student

    t0 = time.perf_counter()
    searched = isinstance(mech, ReachingJacobians) and not mech.branches
    if not searched:
        mech.require("ik", "dexterity over the workspace")
        mech.require("velocity", "dexterity over the workspace")
    mech.check_limits(limits)
    chosen = mech.check_branches(branches) if mech.branches or branches else ()
    if not (isinstance(replicates, int) and replicates >= 2):
        raise InvalidInputError("replicates", f"need at least 2 independent replicates for an error bar, got {replicates}")
    if not samples >= 16:  # NaN too
        raise InvalidInputError("samples", f"need at least 16 points per replicate, got {samples}")
    if not (isinstance(seed, int) and seed >= 0):  # numpy's SeedSequence takes no negative entropy
        raise InvalidInputError("seed", f"must be a whole number >= 0, got {seed}")
    if samples > MAX_SAMPLES:
        raise InvalidInputError("samples", f"at most {MAX_SAMPLES:,} points per replicate, got {samples:,}")
    m = math.ceil(math.log2(samples))
    n = 1 << m
    check_points("samples", float(n) * replicates * max(1, len(chosen)), hint="use fewer samples")
    lo, hi = (np.asarray(a, dtype=float) for a in mech.bounding_box(limits))
    grid = None if cells is None else CellGrid.over(lo, hi, cells)
    box = float(np.prod(hi - lo))
    T = len(chosen) + 1
    c, S, Y, Rs = (np.zeros((replicates, T)) for _ in range(4))
    G = 0 if grid is None else grid.size
    cc, cS, cY, cR = (np.zeros((replicates, G)) for _ in range(4))
    lo_sign = np.zeros(T, bool)
    hi_sign = np.zeros(T, bool)
    infinite = np.zeros(T, bool)
    w_max = np.zeros(T)
    seeds = np.random.SeedSequence(seed).spawn(replicates)
    for r in range(replicates):
        u = qmc.Sobol(mech.task_dim, scramble=True, seed=np.random.default_rng(seeds[r])).random_base2(m)
        pts = lo + (hi - lo) * u
        for s in range(0, n, CHUNK):
            inside, inv, w, rad, sign = _values(mech, pts[s:s + CHUNK], chosen, limits)
            c[r] += inside.sum(axis=0)
            S[r] += inv.sum(axis=0)
            Rs[r] += rad.sum(axis=0)
            infinite |= np.isinf(w).any(axis=0)
            finite_w = np.where(np.isinf(w), 0.0, w)
            Y[r] += finite_w.sum(axis=0)
            w_max = np.maximum(w_max, finite_w.max(axis=0, initial=0.0))
            for k in range(T - 1):
                lo_sign[k] |= bool((sign[inside[:, k], k] < 0).any())
                hi_sign[k] |= bool((sign[inside[:, k], k] > 0).any())
            if grid is not None:
                sel = inside[:, -1]
                idx = grid.flat_index(pts[s:s + CHUNK][sel])
                for acc, val in ((cc, None), (cS, inv), (cY, finite_w), (cR, rad)):
                    acc[r] += np.bincount(idx, None if val is None else val[sel, -1], minlength=G)
    # the union's type II loci: any branch's
    lo_sign[-1] = hi_sign[-1] = bool((lo_sign[:-1] & hi_sign[:-1]).any())
    diverges = (lo_sign & hi_sign) | infinite
    with np.errstate(invalid="ignore", divide="ignore"):
        heavy = w_max > HEAVY_TAIL * Y.sum(axis=0)
    t = float(student.ppf(0.975, replicates - 1))
    gci, gci_err = ratio_errors(S, c, t)
    yo, yo_err = ratio_errors(Y, c, t)
    rad_mean, rad_err = ratio_errors(Rs, c, t)
    yo_err = np.where(diverges | heavy, np.inf, yo_err)
    frac = c / n
    vol = box * frac.mean(axis=0)
    vol_err = box * t * frac.std(axis=0, ddof=1) / math.sqrt(replicates)
    table = None if grid is None else CellTable.from_sums(grid, cc, (cS, cY, cR), n, box, t)
    from kinematics.mechanisms.base import UNION

    mixed = mech.actuator_unit not in ("m", "rad")
    return Dexterity(mech.name, limits, (*chosen, UNION), gci, gci_err, yo, yo_err, yoshikawa_unit(mech), diverges,
                     heavy, rad_mean, rad_err, vol, vol_err, c.sum(axis=0).astype(int), n, replicates, seed, mixed,
                     mech.task_dim == 2, time.perf_counter() - t0, mech.parameters(), table,
                     SEARCH_RULE if searched else UNION_RULE)


MAP_CELLS = 50
"""Default grid of the conditioning maps: this many steps along the bounding box's longest side."""


def conditioning_grid(mech: Mechanism, branch: str, *, limits: str = "all", step: float | None = None
                      ) -> tuple[list[np.ndarray], np.ndarray]:
    """1/kappa on a regular grid over the bounding box, for maps: (axes, values shaped like the
    grid; NaN outside the branch, or outside every branch for "union", where the best is taken).

    Args:
        step: grid step [m] (default: the box's longest side / MAP_CELLS).
    """
    from kinematics.sizes import grid_points

    mech.check_limits(limits)
    chosen = mech.check_target(branch)
    lo, hi = (np.asarray(a, dtype=float) for a in mech.bounding_box(limits))
    step = float(np.max(hi - lo)) / MAP_CELLS if step is None else step
    if not (step > 0 and math.isfinite(step)):
        raise InvalidInputError("step", f"must be a positive number of metres, got {step!r}")
    check_points("step", grid_points(lo, hi, step) * max(1, len(chosen)), hint="use a larger step")
    axes = [np.arange(a, b + step / 2, step) for a, b in zip(lo, hi, strict=True)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(axes))
    out = np.full(len(pts), np.nan)
    for s in range(0, len(pts), CHUNK):
        inside, inv, _, _, _ = _values(mech, pts[s:s + CHUNK], chosen, limits)  # last column: their union
        out[s:s + CHUNK] = np.where(inside[:, -1], inv[:, -1], np.nan)
    return axes, out.reshape([len(a) for a in axes])
