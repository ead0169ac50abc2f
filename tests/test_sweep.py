"""Design sweeps: the metrics of a row against an independent computation of the same design, task
errors as one SweepError naming the design, and one Numba thread per Dask worker."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.analyses import sweep as sw
from kinematics.analyses.workspace import volume_monte_carlo
from kinematics.errors import InvalidInputError, SweepError
from kinematics.mechanisms.p2us.closed_form import MODES, P2USParams, ik
from kinematics.mechanisms.p2us.mechanism import P2US


@pytest.fixture(scope="module")
def client():
    from distributed import Client

    with Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=None) as c:
        yield c


def _reference(params: P2USParams, step: float, sing_tol: float) -> dict[str, float]:
    """The sweep's per-design metrics from their definitions, by other means than `evaluate_design`:
    inside = some working mode within every limit by the NumPy closed-form IK (not the Numba scan);
    J = dq/dp by central differences of that IK (not the analytic J_q^-1 J_x); the rod directions
    n_i are J's rows normalised (q_i' = r_i . p' / (r_i . w_i), so row i is parallel to r_i)."""
    from kinematics.mechanisms.p2us.scan import bounding_box

    lo, hi = bounding_box(params)
    axes = [np.arange(lo[k] + step / 2, hi[k], step) for k in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    sol = ik(params, pts)
    inside = sol.within_limits.any(axis=1)
    p, valid = pts[inside], sol.within_limits[inside]
    h = 1e-6  # central differences: truncation ~ h^2 |q'''| ~ 1e-12, rounding ~ eps/h ~ 1e-10
    J = np.empty((len(p), len(MODES), 3, 3))
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        J[..., k] = (ik(params, p + e, limits=False).q - ik(params, p - e, limits=False).q) / (2 * h)
    best = np.zeros(len(p))
    free = np.zeros(len(p), bool)
    for i in range(len(p)):
        for m in np.flatnonzero(valid[i]):
            best[i] = max(best[i], 1.0 / np.linalg.cond(J[i, m]))
            n = J[i, m] / np.linalg.norm(J[i, m], axis=1, keepdims=True)
            iota_I = np.min(np.abs(np.sum(n * params.w, axis=1)))
            iota_II = abs(np.linalg.det(n))
            free[i] |= iota_I > sing_tol and iota_II > sing_tol
    return {"grid_points_inside": len(p), "conditioning_index": float(best.mean()),
            "singularity_free_fraction": float(free.mean())}


def test_sweep_rows_match_an_independent_computation(client):
    step = 0.04
    axes = [sw.Axis.parse("b=0.30:0.34:2")]
    rows = sw.run(axes, step=step, rtol=1e-2, client=client)
    assert [r["design"] for r in rows] == [0, 1] and [r["b"] for r in rows] == pytest.approx([0.30, 0.34])
    rng = np.random.default_rng(11)
    for row in rows:
        params = P2USParams().replace(b=row["b"])
        ref = _reference(params, step, sing_tol=0.05)
        assert row["grid_points_inside"] == ref["grid_points_inside"] > 50
        # 1/kappa and the iotas are smooth where they are evaluated; FD error ~1e-9 (see above)
        assert row["conditioning_index"] == pytest.approx(ref["conditioning_index"], abs=1e-7)
        assert row["singularity_free_fraction"] == pytest.approx(ref["singularity_free_fraction"], abs=1e-12)
        assert 0 < row["conditioning_index"] < 1 and 0 < row["singularity_free_fraction"] <= 1
        # volume: Monte Carlo through the NumPy IK; 4 standard errors plus the requested 1 %
        mc, se = volume_monte_carlo(P2US(params), 200_000, rng)
        assert abs(row["volume_m3"] - mc) <= 4 * se + 0.01 * mc
        assert row["volume_lower_m3"] <= row["volume_m3"] <= row["volume_upper_m3"]
    assert rows[0]["volume_m3"] != rows[1]["volume_m3"]  # the swept parameter reaches the design


def test_failing_task_is_one_error_naming_the_design(client):
    with pytest.raises(SweepError, match=r"^design 0 \(b=0\.3\): rtol: needs [\d,]+ points, over the") as info:
        sw.run([sw.Axis.parse("b=0.3")], step=0.05, rtol=1e-12, client=client)
    assert "\n" not in str(info.value)


def test_sizes_checked_before_any_design():
    with pytest.raises(InvalidInputError, match=r"needs 10,000,000,000 designs, over the 200,000,000 limit"):  # 1e5 x 1e5
        sw.designs(P2USParams(), [sw.Axis.parse("b=0.3:0.4:100000"), sw.Axis.parse("d=0.02:0.03:100000")])
    with pytest.raises(InvalidInputError, match="--workers: gives 0 worker processes; at least 1 is needed"):
        sw.run([sw.Axis.parse("b=0.3")], workers=0)


def test_one_kernel_thread_in_a_worker_only(client):
    import numba

    before = numba.get_num_threads()
    assert client.submit(sw.one_kernel_thread, pure=False).result() == 1  # a worker thread of this process
    assert numba.get_num_threads() == before  # the limit is the worker thread's, not the caller's
    assert sw.one_kernel_thread() == before  # outside a worker nothing changes


@pytest.mark.slow
def test_embedded_cluster_workers_see_one_numba_thread():
    import numba
    from distributed import Client

    with sw.local_cluster(2) as cluster, Client(cluster) as c:
        # a plain task, before any call of ours: the worker process started with one thread
        counts = c.run(numba.get_num_threads)
        assert len(counts) == 2 and set(counts.values()) == {1}
        assert c.submit(numba.get_num_threads, pure=False).result() == 1
