"""Real roots of polynomials of degree <= 6 inside an interval, compiled with Numba (for the
Delta's exact columns, `kinematics.mechanisms.delta.exact`).

Coefficients are stored lowest first in arrays of length DEG + 1. `real_roots` first counts the
sign variations of the Bernstein coefficients on the interval (Descartes' rule for that basis: none
means no root, one exactly one); otherwise the derivatives' sign-changing roots, found from the
highest derivative down, split the interval into pieces where the polynomial is monotone, and
each piece with a sign change holds exactly one root, found by Newton's iteration safeguarded by
bisection. Every root found carries its rounding error 32 eps sum_k |a_k s^k| / |p'(s)| (at least
ROOT_ERROR), large only near a double root.
"""

from __future__ import annotations

import math

from numba import njit

__all__ = ["DEG", "ROOT_ERROR", "bernstein_variations", "end_error", "horner", "monotone_root", "poly_mul",
           "poly_value", "quadratic_roots", "real_roots"]

DEG = 6
"""Highest degree handled (coefficient arrays have DEG + 1 entries)."""

ROOT_ERROR = 1e-14
"""Least error [m] charged per root (its own rounding)."""

_EPS = 2.220446049250313e-16


@njit(cache=True)
def poly_mul(a, b, out):  # pragma: no cover - compiled
    """out = a * b (coefficients, lowest first; every array of length DEG + 1, product degree <= DEG)."""
    out[:] = 0.0
    for i in range(DEG + 1):
        if a[i] != 0.0:
            for j in range(DEG + 1 - i):
                out[i + j] += a[i] * b[j]


@njit(cache=True)
def horner(c, n, s):  # pragma: no cover - compiled
    """(p(s), sum |c_k s^k|) for the polynomial c[0:n + 1]."""
    v = 0.0
    w = 0.0
    a = abs(s)
    for k in range(n, -1, -1):
        v = v * s + c[k]
        w = w * a + abs(c[k])
    return v, w


@njit(cache=True)
def end_error(c, n, z, lo, hi):  # pragma: no cover - compiled
    """Rounding error [m] of the root z of c[0:n + 1]: 32 eps sum_k |c_k z^k| / |p'(z)|, within
    [ROOT_ERROR, hi - lo]."""
    _f, w = horner(c, n, z)
    d = 0.0
    for k in range(n, 0, -1):
        d = d * z + k * c[k]
    return min(max(32.0 * _EPS * w / abs(d), ROOT_ERROR), hi - lo) if d != 0.0 else hi - lo


@njit(cache=True)
def poly_value(c, n, s):  # pragma: no cover - compiled
    """p(s) for the polynomial c[0:n + 1]."""
    v = 0.0
    for k in range(n, -1, -1):
        v = v * s + c[k]
    return v


@njit(cache=True)
def monotone_root(c, n, a, b, fa, fb):  # pragma: no cover - compiled
    """The root of c[0:n + 1] in [a, b], where it is monotone with a sign change (fa = p(a),
    fb = p(b)): Newton's iteration from the secant's root, bisecting whenever a step leaves the
    bracket; once a step is below 1e-9 (1 + |x|) one more converges quadratically to the rounding level."""
    x = a - fa * (b - a) / (fb - fa)
    if not a < x < b:
        x = 0.5 * (a + b)
    last = False
    for _ in range(200):
        f = c[n]
        d = 0.0
        for k in range(n - 1, -1, -1):
            d = d * x + f
            f = f * x + c[k]
        if f == 0.0:
            return x
        if (f < 0.0) == (fa < 0.0):
            a, fa = x, f
        else:
            b = x
        xn = x - f / d if d != 0.0 else 0.5 * (a + b)
        if not a <= xn <= b:
            xn = 0.5 * (a + b)
        if last or b - a <= 4e-16 * (1.0 + abs(x)):
            return xn
        last = abs(xn - x) <= 1e-9 * (1.0 + abs(x))
        x = xn
    return x


@njit(cache=True)
def bernstein_variations(c, n, lo, hi, bz):  # pragma: no cover - compiled
    """Sign variations of c[0:n + 1]'s Bernstein coefficients on [lo, hi] (bz: a buffer), or -1
    when one is too near zero to count: by Descartes' rule for the Bernstein basis, 0 means no
    root in (lo, hi) and 1 exactly one."""
    for k in range(n + 1):  # Taylor shift to lo (repeated synthetic division)
        bz[k] = c[k]
    for j in range(n):
        for k in range(n - 1, j - 1, -1):
            bz[k] += lo * bz[k + 1]
    w = hi - lo
    f = 1.0
    for k in range(n + 1):
        bz[k] *= f
        f *= w
    # monomial -> Bernstein: b_i = sum_{k <= i} C(i, k) / C(n, k) a_k, in place from the top
    big = 0.0
    for i in range(n, -1, -1):
        acc = 0.0
        cik = 1.0  # C(i, k)
        cnk = 1.0  # C(n, k)
        for k in range(i + 1):
            acc += cik / cnk * bz[k]
            cik = cik * (i - k) / (k + 1)
            cnk = cnk * (n - k) / (k + 1)
        bz[n + 1 + i] = acc
        big = max(big, abs(acc))
    v = 0
    for i in range(n + 1):
        b = bz[n + 1 + i]
        if abs(b) <= 1e-11 * big:
            return -1
        if i > 0 and (b < 0.0) != (bz[n + i] < 0.0):
            v += 1
    return v


@njit(cache=True)
def real_roots(c, lo, hi, out, err, ids, n_out, cid, work, crit):  # pragma: no cover - compiled
    """Append the real roots of the polynomial c (length DEG + 1) inside (lo, hi) to out[n_out:]
    (with their rounding errors in err, tagged cid); returns the new count. work (DEG + 1,
    DEG + 1), crit (DEG + 2, 2 DEG + 2): buffers. The Bernstein coefficients' sign variations
    settle the usual cases (no root, one root); otherwise the derivatives' roots split [lo, hi]
    into monotone pieces."""
    n = DEG
    scale = 0.0
    for k in range(DEG + 1):
        scale = max(scale, abs(c[k]))
    while n > 0 and abs(c[n]) <= 1e-14 * scale:
        n -= 1
    if n == 0:
        return n_out
    v = bernstein_variations(c, n, lo, hi, crit[DEG + 1])
    if v == 0:
        return n_out
    # work[k]: the k-th derivative of c
    for k in range(DEG + 1):
        work[0, k] = c[k] if k <= n else 0.0
    for j in range(1, n):
        for k in range(n - j + 1):
            work[j, k] = work[j - 1, k + 1] * (k + 1)
    # crit[j]: lo, the sign-changing roots of derivative j in (lo, hi), hi; from the constant
    # derivative n (no root) down to c itself
    top = n - 1 if v != 1 else 0  # exactly one root: bracket it by [lo, hi] directly
    crit[top + 1, 0], crit[top + 1, 1] = lo, hi
    m = 0  # number of interior points at level j + 1
    for j in range(top, -1, -1):
        deg = n - j
        cnt = 0
        crit[j, 0] = lo
        for q in range(m + 1):
            a, b = crit[j + 1, q], crit[j + 1, q + 1]
            fa = poly_value(work[j], deg, a)
            fb = poly_value(work[j], deg, b)
            if fa == 0.0 or fb == 0.0 or (fa < 0.0) == (fb < 0.0):
                continue
            cnt += 1
            crit[j, cnt] = monotone_root(work[j], deg, a, b, fa, fb)
        crit[j, cnt + 1] = hi
        m = cnt
    for q in range(1, m + 1):
        out[n_out] = crit[0, q]
        err[n_out] = end_error(c, n, crit[0, q], lo, hi)
        ids[n_out] = cid
        n_out += 1
    return n_out


@njit(cache=True)
def quadratic_roots(c, lo, hi, out, err, ids, n_out, cid):  # pragma: no cover - compiled
    """`real_roots` for c[0] + c[1] s + c[2] s^2 (c[2] != 0), by the quadratic formula in its
    cancellation-free form."""
    a, b, cc = c[2], c[1], c[0]
    disc = b * b - 4.0 * a * cc
    if not disc > 0.0:  # no root or a double one (a tangency: no sign change)
        return n_out
    sq = math.sqrt(disc)
    q = -0.5 * (b + sq if b >= 0.0 else b - sq)  # |q| >= sqrt(disc) / 2 > 0
    for k in range(2):
        z = q / a if k == 0 else cc / q
        if lo < z < hi:
            out[n_out] = z
            err[n_out] = end_error(c, 2, z, lo, hi)
            ids[n_out] = cid
            n_out += 1
    return n_out
