"""Design sweeps of the 3-[P2(US)] on Dask: workspace volume, singularity-free fraction and a
global conditioning index per candidate design.

Each design is one task (`evaluate_design`, a pure function of plain numbers), so the sweep runs
unchanged on an embedded `distributed.LocalCluster` or on any cluster given by its scheduler
address. Rows come back in the order of the design grid, and hold no timing, so the CSV is the
same file wherever it ran.

Per design, on the union of the working modes' workspaces (every limit applied):

* volume_m3: `workspace.measure_workspace` at the sweep's step and tolerance;
* singularity_free_fraction: share of the workspace's grid points where both scale-free measures
  (iota_I, iota_II) of the best working mode exceed `sing_tol`;
* conditioning_index: the mean over those grid points of 1/kappa(J) (J = J_q^-1 J_x, kappa its
  2-norm condition number) in the best-conditioned valid mode: Gosselin & Angeles' global
  conditioning index, in [0, 1].

With collisions (`run(collisions=...)`), each design's URDF is generated with the given collision
sizes and the union's collision-free volume is measured too (`analyses.collision_volume`: the
3-[P2(US)]'s collision-free exact columns, no check run): collision_free_volume_m3 and its error
estimate.
"""

from __future__ import annotations

import contextlib
import csv
import io
import itertools
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from kinematics.errors import InvalidInputError, KinematicsError, SweepError, UnknownParameterError
from kinematics.mechanisms.p2us.closed_form import MODES, P2USParams

if TYPE_CHECKING:
    from kinematics.analyses.cells import VolumeEstimate

SWEEPABLE = ("b", "d", "L", "beta", "theta_zero", "rod_spacing", "stroke_min", "stroke_max")
"""Design parameters a sweep may vary (SI units: m, rad)."""

COLUMNS = ("design", *SWEEPABLE, "volume_m3", "volume_lower_m3", "volume_upper_m3",
           "singularity_free_fraction", "conditioning_index", "grid_points_inside")
COLLISION_COLUMNS = ("collision_free_volume_m3", "collision_free_error_m3")
"""Added to every row by a sweep with collisions."""


def split_param(text: str, names: Sequence[str], form: str) -> tuple[str, list[str]]:
    """'NAME=A:B:...' -> (NAME, ['A', 'B', ...]); NAME must be one of `names` (UnknownParameterError),
    `form` shows the expected syntax in the error (InvalidInputError)."""
    name, sep, rng = text.partition("=")
    name = name.strip()
    if not sep:
        raise InvalidInputError("--param", f"expected {form}, got {text!r}")
    if name not in names:
        raise UnknownParameterError(name, tuple(names))
    return name, rng.split(":")


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
        name, parts = split_param(text, SWEEPABLE, "NAME=START:STOP:COUNT")
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


def designs(base: P2USParams, axes: Sequence[Axis], step: float | None = None) -> list[dict[str, float]]:
    """The full grid of designs (the last axis varies fastest), as plain parameter dicts.

    With `step`, the work (designs x grid points of the base design's box at that step) must fit
    the budget of `kinematics.sizes`; it is checked before any design is built.
    """
    from kinematics.sizes import check_points, grid_points

    names = [a.name for a in axes]
    if len(set(names)) != len(names):
        raise InvalidInputError("--param", f"a parameter is given twice: {names}")
    count = math.prod(float(a.count) for a in axes)
    if step is not None:
        from kinematics.mechanisms.p2us.scan import bounding_box

        lo, hi = bounding_box(base)
        check_points("--param", count * grid_points(lo, hi, step),
                     hint=f"{count:,.0f} designs x the grid points at step {step:g} m; sweep fewer designs")
    else:
        check_points("--param", count, unit="designs")
    start = _flat(base)
    out = []
    for combo in itertools.product(*[a.values() for a in axes]):
        d = dict(start)
        d.update({n: float(v) for n, v in zip(names, combo, strict=True)})
        to_params(d)  # validate early, on the client
        out.append(d)
    return out


def _flat(p: P2USParams) -> dict[str, Any]:
    return {"b": p.b, "d": p.d, "L": p.L, "beta": p.beta, "theta_zero": p.theta_zero,
            "rod_spacing": p.rod_spacing, "stroke_min": p.stroke[0], "stroke_max": p.stroke[1],
            "alpha": list(p.alpha), "theta_limits": list(p.theta_limits), "phi_limits": list(p.phi_limits),
            "theta_convention": p.theta_convention, "phi_convention": p.phi_convention}


def to_params(d: dict[str, Any]) -> P2USParams:
    return P2USParams(b=d["b"], d=d["d"], L=d["L"], beta=d["beta"], alpha=tuple(d["alpha"]),
                      stroke=(d["stroke_min"], d["stroke_max"]), theta_limits=tuple(d["theta_limits"]),
                      phi_limits=tuple(d["phi_limits"]), theta_zero=d["theta_zero"], rod_spacing=d["rod_spacing"],
                      theta_convention=d.get("theta_convention", "elevation"),
                      phi_convention=d.get("phi_convention", "tangential"))


def one_kernel_thread() -> int:
    """Inside a Dask worker, limit the Numba kernels of the calling thread to one thread (the
    cluster already runs one task per core: cores x cores threads otherwise); returns the
    thread count the kernels now use. Outside a worker, nothing changes."""
    import numba

    try:
        from distributed import get_worker

        get_worker()
    except (ImportError, ValueError):
        return int(numba.get_num_threads())
    numba.set_num_threads(1)
    return int(numba.get_num_threads())


def collision_free(params: P2USParams, step: float, rtol: float | None, collisions: dict[str, Any]
                   ) -> dict[str, float]:
    """The union's collision-free volume [m^3] of a design and its error estimate
    (`analyses.collisions.design_checks`: the design's URDF with `collisions`' sizes)."""
    from kinematics.analyses.collision_volume import measure_collision_workspace
    from kinematics.analyses.collisions import design_checks
    from kinematics.mechanisms.p2us.mechanism import P2US

    robot, model = design_checks("p2us", params, collisions)
    cw = measure_collision_workspace(P2US(params), robot, step=step, rtol=rtol, check=False, watch=0,
                                     collision_model=model)
    return {"collision_free_volume_m3": cw.workspace.total, "collision_free_error_m3": cw.workspace.error}


def evaluate_design(design: dict[str, Any], step: float, rtol: float | None, sing_tol: float,
                    collisions: dict[str, Any] | None = None) -> dict[str, float]:
    """Volume, singularity-free fraction and conditioning index of one design (a Dask task), and
    with `collisions` (`collision_free`) its collision-free volume."""
    from kinematics.mechanisms.p2us.scan import bounding_box, scan

    one_kernel_thread()
    from kinematics.analyses.workspace import measure_workspace
    from kinematics.mechanisms.p2us.closed_form import ik, jacobians
    from kinematics.mechanisms.p2us.mechanism import P2US
    from kinematics.sizes import cell_centres

    params = to_params(design)
    ws = measure_workspace(P2US(params), step=step, rtol=rtol, progress=False, engine="cells")
    cells = cast("VolumeEstimate", ws.result)
    lo, hi = bounding_box(params)
    pts = cell_centres(lo, hi, step)
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
    extra = {} if collisions is None else collision_free(params, step, rtol, collisions)
    return {
        **extra,
        "volume_m3": ws.total,
        "volume_lower_m3": float(cells.lower[-1]),
        "volume_upper_m3": float(cells.upper[-1]),
        "singularity_free_fraction": free / len(p) if len(p) else 0.0,
        "conditioning_index": gci,
        "grid_points_inside": len(p),
    }


def run(axes: Sequence[Axis], base: P2USParams | None = None, *, step: float = 0.02, rtol: float | None = 1e-2,
        sing_tol: float = 0.05, scheduler: str | None = None, workers: int | None = None,
        client: Any = None, progress: bool = False, collisions: dict[str, Any] | None = None
        ) -> list[dict[str, Any]]:
    """Evaluate every design on Dask; rows in design order.

    Args:
        scheduler: address of a running dask scheduler (e.g. tcp://10.0.0.5:8786); None starts an
            embedded LocalCluster (one single-threaded worker process per core).
        client: an existing distributed.Client (overrides scheduler).
        workers: worker processes of the embedded cluster (default: the cores).
        collisions: also each design's collision-free volume (`collision_free`'s dict).
    """
    todo = designs(base or P2USParams(), axes, step)
    futures: list[Any] = []
    with connect(scheduler, workers, client) as client:
        futures = client.map(_task, todo, step=step, rtol=rtol, sing_tol=sing_tol, collisions=collisions, pure=True)
        wait_for(futures, progress)
        try:
            results = client.gather(futures)
        except Exception as exc:  # noqa: BLE001 - a task failed: name the design, not the worker's traceback
            failed = next((k for k, f in enumerate(futures) if f.status == "error"), None)
            where = f"design {failed} ({_describe(todo[failed], axes)})" if failed is not None else "a design"
            lines = str(exc).splitlines()
            why = lines[0] if lines else ""
            raise SweepError(f"{where}: {why}" if isinstance(exc, KinematicsError)
                             else f"{where} failed: {type(exc).__name__}: {why}") from None
    return [{"design": k, **{n: d[n] for n in SWEEPABLE}, **r}
            for k, (d, r) in enumerate(zip(todo, results, strict=True))]


@contextlib.contextmanager
def connect(scheduler: str | None = None, workers: int | None = None, client: Any = None) -> Iterator[Any]:
    """A distributed.Client for the block: `client` itself when given (left open), else one on the
    scheduler at `scheduler` (e.g. tcp://10.0.0.5:8786), else on an embedded LocalCluster of
    `workers` single-threaded processes (default: the cores); what it opened, it closes (Ctrl-C
    held until closed)."""
    from kinematics.chunks import default_workers
    from kinematics.sizes import check_points

    if workers is not None:
        check_points("--workers", workers, limit=4 * default_workers(), unit="worker processes",
                     hint="at most 4 per core")
    if client is not None:
        yield client
        return
    from distributed import Client

    own = None
    try:
        if scheduler is None:
            # a half-started cluster cannot be closed cleanly: Ctrl-C waits for the start
            with _interrupts_deferred(), _children_quiet():
                own = local_cluster(workers or default_workers())
            client = Client(own)
        else:
            try:
                client = Client(scheduler, timeout="10s")
            except Exception as exc:  # noqa: BLE001 - bad address, refused, timeout: all one answer
                raise InvalidInputError("--scheduler", f"cannot reach {scheduler!r}: "
                                        f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}") from None
        yield client
    finally:
        with _interrupts_deferred():
            if client is not None:
                client.close()
            if own is not None:
                own.close()


@contextlib.contextmanager
def _interrupts_deferred() -> Iterator[None]:
    """Hold Ctrl-C (SIGINT) until the block is done, then raise KeyboardInterrupt; in the main
    thread only (elsewhere signals cannot be handled, and the block runs as is). A terminal's
    Ctrl-C reaches the worker processes too, so a block that fails after one is interrupted."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: pending.append(signum))
    try:
        yield
    except Exception:
        if pending:
            raise KeyboardInterrupt from None
        raise
    finally:
        signal.signal(signal.SIGINT, previous)
    if pending:
        raise KeyboardInterrupt


@contextlib.contextmanager
def _children_quiet() -> Iterator[None]:
    """Processes started in the block write their stderr to /dev/null: a terminal's Ctrl-C reaches
    the worker processes as well, and each would print a traceback; their errors reach the
    caller through the client instead."""
    import os

    try:
        saved = os.dup(2)
    except OSError:  # no stderr descriptor
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


def local_cluster(workers: int) -> Any:
    """The embedded cluster: `workers` single-threaded worker processes whose Numba kernels use
    one thread each (NUMBA_NUM_THREADS is read when Numba starts; cores x cores threads
    otherwise); no dashboards (the scheduler's HTTP routes go to a free local port, not 8787);
    worker logs only for what breaks the cluster (a task's error reaches the caller instead)."""
    import logging

    from distributed import LocalCluster

    return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                        worker_dashboard_address=None, scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                        silence_logs=logging.CRITICAL, env={"NUMBA_NUM_THREADS": "1"})


def wait_for(futures: list[Any], progress: bool, desc: str = "sweep", unit: str = "design") -> None:
    """Wait for every future (or the first error) by polling from this thread: no gather runs in
    the background, so an interrupt leaves nothing pending for the client to report at close."""
    import time

    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(futures), desc=desc, unit=unit, delay=1.0, leave=False)
    try:
        done = 0
        while done < len(futures):
            states = [f.status for f in futures]
            if "error" in states or "cancelled" in states:
                return
            now = states.count("finished")
            if bar is not None:
                bar.update(now - done)
            done = now
            if done < len(futures):
                time.sleep(0.05)
    finally:
        if bar is not None:
            bar.close()


def _task(design: dict[str, Any], step: float, rtol: float | None, sing_tol: float,
          collisions: dict[str, Any] | None = None) -> dict[str, float]:
    """`evaluate_design` as a task: its KinematicsErrors come back as a SweepError with the same
    message (the subclasses' constructors take data, so they do not survive pickling)."""
    try:
        return evaluate_design(design, step, rtol, sing_tol, collisions)
    except KinematicsError as exc:
        raise SweepError(str(exc)) from None


def _describe(design: dict[str, Any], axes: Sequence[Axis]) -> str:
    return ", ".join(f"{a.name}={design[a.name]:g}" for a in axes)


def to_csv(rows: Sequence[dict[str, Any]]) -> str:
    """The sweep table as CSV; floats written with repr (shortest exact round trip)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    columns = columns_of(rows)
    w.writerow(columns)
    for r in rows:
        w.writerow([repr(float(r[c])) if isinstance(r[c], float) else r[c] for c in columns])
    return buf.getvalue()


def columns_of(rows: Sequence[dict[str, Any]]) -> tuple[str, ...]:
    """The table's columns: `COLUMNS`, and `COLLISION_COLUMNS` when the rows have them."""
    return (*COLUMNS, *COLLISION_COLUMNS) if rows and COLLISION_COLUMNS[0] in rows[0] else COLUMNS
