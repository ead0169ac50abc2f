"""Optimal dimensions: multi-objective dimensional synthesis of a parallel robot (the 3-[P2(US)]
and the Delta) with pymoo's NSGA-II, every design evaluated as a task on Dask.

Objectives of a design (built with `params.replace(**changes)` and its family's `Mechanism`):

* usable-cube edge [m], maximised (collision-free with `Settings.collisions`: the design's URDF is
  generated with the collision sizes and the collision-aware margin joins the limits):
  `usable.usable(mech, "cube", search=False)` in the chosen
  branch (default "---") with kappa <= kappa_max and no singularity: the distance-transform optimum
  on a coarse grid (step = the design's bounding box's longest side / `cube_cells`), its size
  bisected at that centre and checked by the dense membership test. Without the pattern search
  the edge is a *checked lower bound* of the largest cube, measured 12-35 % below the refined
  optimum on the built-in designs (docs/design.md); the ranking of designs is what the search needs.
* GCI, maximised: `dexterity.dexterity` in the same branch (mean 1/kappa over its workspace,
  randomised QMC with `gci_samples` x `gci_replicates` points); every design uses the same
  scrambling seed (common random numbers, so that differences between designs are not noise).
  Its 95 % error is kept in the table.
* footprint [m], minimised: the radius of the smallest vertical cylinder about the base axis holding
  the fixed base and the actuated links at any actuator value: b for the 3-[P2(US)] (its rails run
  inward and down from A_i = b e_i), R + l_a max cos(theta) over the actuator range for the Delta
  (the elbows' outermost reach).

A design whose parameters are degenerate (InvalidDesignError and the like) is infeasible (pymoo's
constraint G = 1); one whose usable region is empty at the grid step has edge 0.

Reproducible: NSGA-II's own randomness is seeded (`seed`), tasks return in order, and every
evaluation is deterministic, so the same seed gives the same front on any cluster.
"""

from __future__ import annotations

import csv
import io
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from kinematics.errors import (
    InvalidInputError,
    KinematicsError,
    SweepError,
    UnknownParameterError,
    UnsupportedRobotError,
)

if TYPE_CHECKING:
    from kinematics.mechanisms.base import Mechanism

VARIABLES: dict[str, tuple[str, ...]] = {
    "p2us": ("b", "d", "L", "beta", "theta_zero", "rod_spacing", "stroke_min", "stroke_max"),
    "delta": ("R", "r", "la", "lb", "cone", "theta_min", "theta_max", "elbow_socket", "platform_socket"),
}
"""Design variables per family (SI units: m, rad); stroke_* and theta_* set one end of a range."""

FOOTPRINT_TEXT = {"p2us": "base radius b", "delta": "R + la max cos(theta): the elbows' outermost radius"}

OBJECTIVES = ("cube_edge_m", "gci", "footprint_m")


@dataclass(frozen=True)
class Bound:
    """One design variable's range [lower, upper] (SI units)."""

    name: str
    lower: float
    upper: float

    @classmethod
    def parse(cls, text: str, family: str) -> Bound:
        """'b=0.3:0.5' -> Bound('b', 0.3, 0.5) (the sweep's NAME=... syntax)."""
        from kinematics.analyses.sweep import split_param

        names = VARIABLES[family]
        name, parts = split_param(text, names, "NAME=LOWER:UPPER")
        try:
            if len(parts) != 2:
                raise ValueError
            lo, hi = float(parts[0]), float(parts[1])
        except ValueError:
            raise InvalidInputError("--param", f"expected {name}=LOWER:UPPER, got {text!r}") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise InvalidInputError("--param", f"need finite LOWER < UPPER, got {text!r}")
        return cls(name, lo, hi)


@dataclass(frozen=True)
class Settings:
    """How each design is evaluated (see the module docstring)."""

    branch: str = "---"
    kappa_max: float = 10.0
    limits: str = "all"
    cube_cells: int = 40
    gci_samples: int = 4096
    gci_replicates: int = 4
    seed: int = 0
    collisions: dict[str, Any] | None = None
    """Collision options (`analyses.collisions.design_options`): the usable cube is then
    collision-free (each design's URDF generated with these sizes); the GCI stays kinematic."""

    def __post_init__(self) -> None:
        if not (self.kappa_max >= 1 and math.isfinite(self.kappa_max)):
            raise InvalidInputError("kappa_max", f"must be a finite number >= 1, got {self.kappa_max!r}")
        if self.cube_cells < 4:
            raise InvalidInputError("cube_cells", f"need at least 4 grid steps across the box, got {self.cube_cells}")
        if self.gci_samples < 16 or self.gci_replicates < 2:
            raise InvalidInputError("gci_samples", "need at least 16 points and 2 replicates for the GCI, got "
                                    f"{self.gci_samples} x {self.gci_replicates}")


@dataclass(frozen=True)
class Synthesis:
    """The result: the Pareto front (rows of design variables, objectives and the GCI's error),
    every evaluated design (`history`), how it was obtained, and the starting design's objectives
    with its `gap_to_front` (`reference`)."""

    family: str
    names: tuple[str, ...]
    rows: list[dict[str, Any]]
    history: list[dict[str, Any]]
    population: int
    generations: int
    seed: int
    settings: Settings
    branch: str
    kappa_max: float
    seconds: float
    footprint_text: str = ""
    base: dict[str, Any] = field(default_factory=dict)
    reference: dict[str, Any] = field(default_factory=dict)

    @property
    def columns(self) -> tuple[str, ...]:
        return (*self.names, *OBJECTIVES, "gci_error")

    def to_csv(self) -> str:
        """The front as CSV (floats with repr: exact round trip), one row per design."""
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(self.columns)
        for r in self.rows:
            w.writerow([repr(float(r[c])) for c in self.columns])
        return buf.getvalue()

    def as_dict(self) -> dict[str, Any]:
        return {"family": self.family, "variables": list(self.names), "objectives": {
                    "cube_edge_m": "maximise", "gci": "maximise", "footprint_m": f"minimise ({self.footprint_text})"},
                "pareto_front": self.rows, "designs_evaluated": len(self.history),
                "population": self.population, "generations": self.generations, "seed": self.seed,
                "branch": self.branch, "kappa_max": self.kappa_max, "settings": self.settings.__dict__,
                "seconds": self.seconds, "base_design": self.base, "reference": self.reference}


# -- one design ----------------------------------------------------------------------------------
def family_of(mech: Mechanism) -> str:
    """The mechanism's family key if synthesis supports it (UnsupportedRobotError otherwise)."""
    if mech.family not in VARIABLES:
        raise UnsupportedRobotError(mech.name, "dimensional synthesis supports the 3-[P2(US)] (p2us) and the Delta")
    return mech.family


def design(family: str, base: Any, values: dict[str, float]) -> Mechanism:
    """The mechanism of `base` (a family's parameters) with `values` changed (validated by the
    parameters' constructor: InvalidInputError / InvalidDesignError for a degenerate design)."""
    changes: dict[str, Any] = dict(values)
    if family == "p2us":
        from kinematics.mechanisms.p2us.mechanism import P2US

        lo, hi = base.stroke
        if "stroke_min" in changes or "stroke_max" in changes:
            changes["stroke"] = (changes.pop("stroke_min", lo), changes.pop("stroke_max", hi))
        return P2US(base.replace(**changes), "design")
    from kinematics.mechanisms.delta.mechanism import Delta

    lo, hi = base.theta_limits
    if "theta_min" in changes or "theta_max" in changes:
        changes["theta_limits"] = (changes.pop("theta_min", lo), changes.pop("theta_max", hi))
    return Delta(base.replace(**changes), "design")


def footprint(mech: Mechanism) -> float:
    """Footprint radius [m] (module docstring)."""
    P: Any = getattr(mech, "params", None)
    if mech.family == "p2us":
        return float(P.b)
    if mech.family == "delta":
        lo, hi = P.theta_limits
        reach = 1.0 if lo <= 0.0 <= hi else max(math.cos(lo), math.cos(hi))
        return float(P.R + P.la * reach)
    raise UnsupportedRobotError(mech.name, "a footprint is defined for the 3-[P2(US)] and the Delta")


def evaluate(family: str, base: Any, values: dict[str, float], settings: Settings) -> dict[str, Any]:
    """Objectives of one design (a Dask task): cube_edge_m, gci, gci_error, footprint_m, feasible
    (False: degenerate parameters, objectives then 0 and `reason` says why)."""
    from kinematics.analyses.dexterity import dexterity
    from kinematics.analyses.sweep import one_kernel_thread
    from kinematics.analyses.usable import EMPTY, usable

    one_kernel_thread()
    try:
        mech = design(family, base, values)
    except InvalidInputError as exc:
        return {"feasible": False, "reason": str(exc), "cube_edge_m": 0.0, "gci": 0.0, "gci_error": 0.0,
                "footprint_m": 0.0}
    lo, hi = mech.bounding_box(settings.limits)
    step = float(np.max(hi - lo)) / settings.cube_cells
    margin_of = None
    if settings.collisions is not None:
        from kinematics.analyses.collisions import design_checks, margin_builder

        robot, model = design_checks(family, getattr(mech, "params", None), settings.collisions)
        margin_of = margin_builder(mech, robot, model, settings.limits)
    try:
        edge = usable(mech, "cube", branch=settings.branch, kappa_max=settings.kappa_max, limits=settings.limits,
                      step=step, search=False, margin_of=margin_of).size[0]
    except InvalidInputError as exc:
        if exc.problem != EMPTY:
            raise
        edge = 0.0
    branches = None if settings.branch == "union" else [settings.branch]
    d = dexterity(mech, branches, limits=settings.limits, samples=settings.gci_samples,
                  replicates=settings.gci_replicates, seed=settings.seed)
    gci, err = float(d.gci[-1]), float(d.gci_error[-1])
    if not math.isfinite(gci):  # the branch is empty: nothing to condition
        gci, err = 0.0, 0.0
    return {"feasible": True, "reason": "", "cube_edge_m": float(edge), "gci": gci, "gci_error": err,
            "footprint_m": footprint(mech)}


def _task(family: str, base: Any, values: dict[str, float], settings: Settings) -> dict[str, Any]:
    """`evaluate` as a task: KinematicsErrors come back as SweepError (their constructors take data)."""
    try:
        return evaluate(family, base, values, settings)
    except KinematicsError as exc:
        raise SweepError(f"design {values}: {exc}") from None


def non_dominated(F: np.ndarray) -> np.ndarray:
    """Indices of the rows of F (N, k), all minimised, that no other row dominates (<= everywhere,
    < somewhere); duplicates all kept."""
    F = np.asarray(F, dtype=float)
    le = (F[:, None, :] <= F[None, :, :]).all(axis=-1)
    lt = (F[:, None, :] < F[None, :, :]).any(axis=-1)
    dominated = (le & lt).any(axis=0)
    return np.flatnonzero(~dominated)


def _minimised(rows: Sequence[dict[str, Any]]) -> np.ndarray:
    return np.array([[-r["cube_edge_m"], -r["gci"], r["footprint_m"]] for r in rows], dtype=float)


def gap_to_front(front: Sequence[dict[str, Any]], point: dict[str, Any]) -> dict[str, Any]:
    """How far a design is from the front: the additive epsilon indicator on objectives normalised
    by the front's ranges, eps = min over front rows of max over objectives of (f_front - f_point)
    (all minimised). eps < 0: some front design is better in every objective by at least |eps| (of
    the range); eps <= 0 with a tie: dominated or on the front; eps > 0: no front design dominates
    it. Also the front design that achieves it and whether any front row dominates the point."""
    F = _minimised(front)
    p = _minimised([point])[0]
    span = np.ptp(np.vstack([F, p]), axis=0)
    span = np.where(span > 0, span, 1.0)
    diff = ((F - p) / span).max(axis=1)
    k = int(np.argmin(diff))
    dominated = bool(((p >= F).all(axis=1) & (p > F).any(axis=1)).any())
    return {"epsilon": float(diff[k]), "closest": dict(front[k]), "dominated": dominated}


# -- the search ----------------------------------------------------------------------------------
def synthesize(mech: Mechanism, bounds: Sequence[Bound], *, population: int = 16, generations: int = 8,
               seed: int = 0, settings: Settings | None = None, scheduler: str | None = None,
               workers: int | None = None, client: Any = None, progress: bool = False) -> Synthesis:
    """NSGA-II over the given bounds around `mech`'s design; evaluations on Dask (`sweep.connect`:
    an embedded LocalCluster by default, `scheduler` for a running one, or a given `client`)."""
    from kinematics.mechanisms.base import check_mechanism

    check_mechanism(mech, "synthesize")
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.core.problem import Problem
    from pymoo.optimize import minimize

    from kinematics.analyses.sweep import connect, wait_for
    from kinematics.sizes import check_points

    family = family_of(mech)
    base: Any = getattr(mech, "params", None)
    settings = settings or Settings(seed=seed)
    if not bounds:
        first = VARIABLES[family][0]  # the example: the family's own variable, +-20 % about this design's value
        x = getattr(base, first, None)
        example = f"{first}={0.8 * x:.3g}:{1.2 * x:.3g}" if isinstance(x, float) and x > 0 else f"{first}=LOWER:UPPER"
        raise InvalidInputError("--param", f"give at least one, e.g. {example}; variables: {', '.join(VARIABLES[family])}")
    names = tuple(b.name for b in bounds)
    if len(set(names)) != len(names):
        raise InvalidInputError("--param", f"a variable is given twice: {list(names)}")
    for b in bounds:  # as Bound.parse checks the command line's: before any worker starts
        if b.name not in VARIABLES[family]:
            raise UnknownParameterError(b.name, VARIABLES[family])
        if not (math.isfinite(b.lower) and math.isfinite(b.upper) and b.lower < b.upper):
            raise InvalidInputError("--param", f"need finite LOWER < UPPER, got {b.name}={b.lower}:{b.upper}")
    if population < 4 or generations < 1:
        raise InvalidInputError("population", f"need a population >= 4 and generations >= 1, got {population}, "
                                f"{generations}")
    for s in (seed, settings.seed):  # NSGA-II's and the GCI's generators take no negative seed
        if not (isinstance(s, int) and s >= 0):
            raise InvalidInputError("seed", f"must be a whole number >= 0, got {s}")
    check_points("population", float(population) * generations, limit=100_000, unit="design evaluations")
    mech.check_target(settings.branch)
    t0 = time.perf_counter()
    history: list[dict[str, Any]] = []

    with connect(scheduler, workers, client) as cl:
        class _Problem(Problem):  # type: ignore[misc]
            def __init__(self) -> None:
                super().__init__(n_var=len(names), n_obj=3, n_ieq_constr=1,
                                 xl=np.array([b.lower for b in bounds]), xu=np.array([b.upper for b in bounds]))

            def _evaluate(self, X: np.ndarray, out: dict[str, Any], *args: Any, **kwargs: Any) -> None:
                todo = [{n: float(v) for n, v in zip(names, x, strict=True)} for x in X]
                futures = cl.map(_task, [family] * len(todo), [base] * len(todo), todo,
                                 [settings] * len(todo), pure=False)
                wait_for(futures, progress, desc="synthesis", unit="design")
                try:
                    res = cl.gather(futures)
                except KinematicsError:
                    raise
                except Exception as exc:  # noqa: BLE001 - a worker failed: one line, not its traceback
                    raise SweepError(f"a design failed: {type(exc).__name__}: {exc}") from None
                rows = [{**v, **r} for v, r in zip(todo, res, strict=True)]
                history.extend(rows)
                out["F"] = _minimised(rows)
                out["G"] = np.array([[0.0 if r["feasible"] else 1.0] for r in rows])

        result = minimize(_Problem(), NSGA2(pop_size=population), ("n_gen", generations), seed=seed, verbose=False)
        # the design the search started from, for comparison with the front
        reference = cl.submit(_task, family, base, {}, settings, pure=False).result()
    feasible = [r for r in history if r["feasible"]]
    front: list[dict[str, Any]] = []
    if feasible:
        # the front of everything evaluated (NSGA-II's final population can lose a point it met)
        idx = non_dominated(_minimised(feasible))
        seen: set[tuple[float, ...]] = set()
        for k in idx:
            key = tuple(float(feasible[k][n]) for n in names)
            if key not in seen:
                seen.add(key)
                front.append({c: float(feasible[k][c]) for c in (*names, *OBJECTIVES, "gci_error")})
        front.sort(key=lambda r: (-r["cube_edge_m"], -r["gci"], r["footprint_m"]))
    del result
    ref = {c: reference[c] for c in (*OBJECTIVES, "gci_error")}
    if front:
        ref["gap"] = gap_to_front(front, reference)
    return Synthesis(family, names, front, history, population, generations, seed, settings, settings.branch,
                     settings.kappa_max, time.perf_counter() - t0, FOOTPRINT_TEXT[family], mech.parameters(), ref)
