"""Design sweeps of the 3-[P2(US)] on Dask: workspace volume, singularity-free fraction and a
global conditioning index per candidate design.

Each design is one task (`evaluate_design`, a pure function of plain numbers), so the sweep runs
unchanged on an embedded `distributed.LocalCluster` or on any cluster given by its scheduler
address. Rows come back in the order of the design grid, and hold no timing, so the CSV is the
same file wherever it ran.

Per design, on the union of the working modes' workspaces (every limit applied):

* volume_m3: `workspace.p2us_workspace` at the sweep's step and tolerance;
* singularity_free_fraction: share of the workspace's grid points where both scale-free measures
  (iota_I, iota_II) of the best working mode exceed `sing_tol`;
* conditioning_index: the mean over those grid points of 1/kappa(J) (J = J_q^-1 J_x, kappa its
  2-norm condition number) in the best-conditioned valid mode: Gosselin & Angeles' global
  conditioning index, in [0, 1].
"""

from __future__ import annotations

import csv
import io
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import InvalidInputError, UnknownParameterError
from .parallel import MODES, P2USParams

SWEEPABLE = ("b", "d", "L", "beta", "theta_zero", "rod_spacing", "stroke_min", "stroke_max")
"""Design parameters a sweep may vary (SI units: m, rad)."""

COLUMNS = ("design", *SWEEPABLE, "volume_m3", "volume_lower_m3", "volume_upper_m3",
           "singularity_free_fraction", "conditioning_index", "grid_points_inside")


@dataclass(frozen=True)
class Axis:
    """One swept parameter: `count` values evenly from `start` to `stop` (inclusive)."""

    name: str
    start: float
    stop: float
    count: int

    @classmethod
    def parse(cls, text: str) -> Axis:
        """'b=0.25:0.40:16' -> Axis('b', 0.25, 0.40, 16); 'L=0.34' is a single value."""
        name, sep, rng = text.partition("=")
        name = name.strip()
        if not sep:
            raise InvalidInputError("--param", f"expected NAME=START:STOP:COUNT, got {text!r}")
        if name not in SWEEPABLE:
            raise UnknownParameterError(name, SWEEPABLE)
        parts = rng.split(":")
        try:
            if len(parts) == 1:
                v = float(parts[0])
                return cls(name, v, v, 1)
            if len(parts) != 3:
                raise ValueError
            start, stop, count = float(parts[0]), float(parts[1]), int(parts[2])
        except ValueError:
            raise InvalidInputError("--param", f"expected {name}=START:STOP:COUNT, got {text!r}") from None
        if count < 1 or not (math.isfinite(start) and math.isfinite(stop)):
            raise InvalidInputError("--param", f"need finite START, STOP and COUNT >= 1, got {text!r}")
        return cls(name, start, stop, count)

    def values(self) -> np.ndarray:
        return np.linspace(self.start, self.stop, self.count)


def designs(base: P2USParams, axes: Sequence[Axis]) -> list[dict[str, float]]:
    """The full grid of designs (the last axis varies fastest), as plain parameter dicts."""
    names = [a.name for a in axes]
    if len(set(names)) != len(names):
        raise InvalidInputError("--param", f"a parameter is given twice: {names}")
    start = _flat(base)
    out = []
    for combo in itertools.product(*[a.values() for a in axes]):
        d = dict(start)
        d.update({n: float(v) for n, v in zip(names, combo, strict=True)})
        to_params(d)  # validate early, on the client
        out.append(d)
    return out


def _flat(p: P2USParams) -> dict[str, float]:
    return {"b": p.b, "d": p.d, "L": p.L, "beta": p.beta, "theta_zero": p.theta_zero,
            "rod_spacing": p.rod_spacing, "stroke_min": p.stroke[0], "stroke_max": p.stroke[1],
            "alpha": list(p.alpha), "theta_limits": list(p.theta_limits), "phi_limits": list(p.phi_limits)}


def to_params(d: dict[str, Any]) -> P2USParams:
    return P2USParams(b=d["b"], d=d["d"], L=d["L"], beta=d["beta"], alpha=tuple(d["alpha"]),
                      stroke=(d["stroke_min"], d["stroke_max"]), theta_limits=tuple(d["theta_limits"]),
                      phi_limits=tuple(d["phi_limits"]), theta_zero=d["theta_zero"], rod_spacing=d["rod_spacing"])


def evaluate_design(design: dict[str, Any], step: float, rtol: float | None, sing_tol: float) -> dict[str, float]:
    """Volume, singularity-free fraction and conditioning index of one design (a Dask task)."""
    from .p2us_scan import bounding_box, scan
    from .parallel import ik, jacobians
    from .workspace import p2us_workspace

    params = to_params(design)
    ws = p2us_workspace(params, step=step, rtol=rtol, progress=False, engine="cells")
    lo, hi = bounding_box(params)
    axes = [np.arange(lo[k] + step / 2, hi[k], step) for k in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    inside = scan(params, pts).margin.max(axis=1) >= 0
    p = pts[inside]
    free = 0
    gci = 0.0
    if len(p):
        sol = ik(params, p)
        best = np.zeros(len(p))
        best_free = np.zeros(len(p), bool)
        for m in range(len(MODES)):
            ok = sol.within_limits[:, m]
            if not ok.any():
                continue
            jac = jacobians(params, p[ok], sol.q[ok, m])
            sv = np.linalg.svd(jac.J, compute_uv=False)
            inv_kappa = np.where(sv[:, 0] > 0, sv[:, -1] / np.where(sv[:, 0] > 0, sv[:, 0], 1.0), 0.0)
            is_free = (jac.iota_I > sing_tol) & (jac.iota_II > sing_tol)
            better = inv_kappa > best[ok]
            idx = np.flatnonzero(ok)
            best[idx[better]] = inv_kappa[better]
            best_free[idx] |= is_free
        free = int(best_free.sum())
        gci = float(best.mean())
    return {
        "volume_m3": ws.total,
        "volume_lower_m3": float(ws.result.lower[-1]),
        "volume_upper_m3": float(ws.result.upper[-1]),
        "singularity_free_fraction": free / len(p) if len(p) else 0.0,
        "conditioning_index": gci,
        "grid_points_inside": int(len(p)),
    }


def run(axes: Sequence[Axis], base: P2USParams | None = None, *, step: float = 0.02, rtol: float | None = 1e-2,
        sing_tol: float = 0.05, scheduler: str | None = None, workers: int | None = None,
        client: Any = None, progress: bool = True) -> list[dict[str, Any]]:
    """Evaluate every design on Dask; rows in design order.

    Args:
        scheduler: address of a running dask scheduler (e.g. tcp://10.0.0.5:8786); None starts an
            embedded LocalCluster (one single-threaded worker process per core).
        client: an existing distributed.Client (overrides scheduler).
        workers: worker processes of the embedded cluster (default: the cores).
    """
    from .chunks import default_workers

    todo = designs(base or P2USParams(), axes)
    own = None
    own_client = client is None
    try:
        if own_client:
            from distributed import Client, LocalCluster

            if scheduler is None:
                own = LocalCluster(n_workers=workers or default_workers(), threads_per_worker=1,
                                   processes=True, dashboard_address=None)
                client = Client(own)
            else:
                try:
                    client = Client(scheduler, timeout="10s")
                except (OSError, TimeoutError) as exc:
                    raise InvalidInputError("--scheduler", f"cannot reach {scheduler}: {exc}") from None
        futures = client.map(evaluate_design, todo, step=step, rtol=rtol, sing_tol=sing_tol, pure=True)
        if progress:
            from distributed import as_completed
            from tqdm import tqdm

            with tqdm(total=len(futures), desc="sweep", unit="design", delay=1.0, leave=False) as bar:
                for _ in as_completed(futures):
                    bar.update(1)
        results = client.gather(futures)
    finally:
        if own_client and client is not None:
            client.close()
        if own is not None:
            own.close()
    return [{"design": k, **{n: d[n] for n in SWEEPABLE}, **r} for k, (d, r) in enumerate(zip(todo, results))]


def to_csv(rows: Sequence[dict[str, Any]]) -> str:
    """The sweep table as CSV; floats written with repr (shortest exact round trip)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(COLUMNS)
    for r in rows:
        w.writerow([repr(float(r[c])) if isinstance(r[c], float) else r[c] for c in COLUMNS])
    return buf.getvalue()
