"""Paper B's singularity scan of the 3-[P2(US)]: the 512 actuator triples of its section 5, each
assembly mode classified (type I / II / III) and checked against every limit."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np

from kinematics.mechanisms.p2us.closed_form import (
    SINGULAR_TOL,
    SINGULARITY_TYPES,
    P2USParams,
    classify,
    fk,
    ik,
    jacobians,
)


def paper_scan(params: P2USParams, n: int = 8, tol: float | None = None) -> dict[str, Any]:
    """Paper B's scan: n^3 actuator triples over the strokes (8^3 = 512), FK in both assembly modes,
    each pose classified by the Gosselin-Angeles type and checked against every limit.

    Returns counts per type (all poses and those within limits) and the poses themselves.
    """
    q1 = np.linspace(*params.stroke, n)
    q = np.array(list(itertools.product(q1, q1, q1)))
    res = fk(params, q)
    rows = []
    counts: dict[str, dict[str, int]] = {}
    for a in range(res.p.shape[-2]):
        ok = res.exists & np.all(np.isfinite(res.p[:, a]), axis=-1)
        p = res.p[ok, a]
        qa = q[ok]
        jac = jacobians(params, p, qa)
        kinds = classify(jac.iota_I, jac.iota_II, SINGULAR_TOL if tol is None else tol)
        sol = ik(params, p)
        # the mode in which p's IK reproduces q, then its limits
        match = np.all(np.isclose(sol.q, qa[:, None, :], atol=1e-9, rtol=0), axis=-1)
        within = np.any(match & sol.within_limits, axis=-1)
        for pk, qk, kk, wk, ik1, ik2 in zip(p, qa, kinds, within, jac.iota_I, jac.iota_II, strict=True):
            name = SINGULARITY_TYPES[int(kk)]
            rows.append({"q": qk.tolist(), "position": pk.tolist(), "assembly": a, "type": name,
                         "within_limits": bool(wk), "iota_I": float(ik1), "iota_II": float(ik2)})
            c = counts.setdefault(name, {"all": 0, "within_limits": 0})
            c["all"] += 1
            c["within_limits"] += int(wk)
    iota = np.array([[r["iota_I"], r["iota_II"]] for r in rows])
    return {"actuator_triples": len(q), "poses": len(rows), "tolerance": SINGULAR_TOL if tol is None else tol,
            "counts": counts, "min_iota_I": float(iota[:, 0].min()), "min_iota_II": float(iota[:, 1].min()),
            "rows": rows}
