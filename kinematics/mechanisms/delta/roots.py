"""Real roots of polynomials of degree <= 6 inside an interval, compiled with Numba (for the
Delta's exact columns, `kinematics.mechanisms.delta.exact`).

Coefficients are stored lowest first in arrays of length DEG + 1. `real_roots` works on the
Bernstein coefficients on the interval: by Descartes' rule for that basis an interval whose
coefficients have no sign variation holds no root and one with a single variation exactly one,
found by Newton's iteration safeguarded by bisection (`monotone_root`); any other interval is
halved (de Casteljau) until one of these holds or it is narrower than 1e-13 (1 + |s|). Every root
found carries its rounding error 32 eps sum_k |a_k s^k| / |p'(s)| (at least ROOT_ERROR, and at
least the interval's width where halving stopped), large only near a double root.

Numba caches a kernel that calls these functions with the caller's module: after editing this
file, delete the callers' cache (`__pycache__/exact.*.nb*`) or touch their modules.
"""

from __future__ import annotations

import math

from numba import njit

__all__ = ["DEG", "ROOT_ERROR", "bernstein_variations", "end_error", "horner", "monotone_root", "poly_mul",
           "poly_value", "quadratic_roots", "real_roots", "roots_of_quadratic"]

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
    x = a - fa * (b - a) / (fb - fa) if fb != fa else 0.5 * (a + b)
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
def _variations(B, n):  # pragma: no cover - compiled
    """Sign variations of B[0:n + 1], or -1 when a coefficient is too near zero to count."""
    big = 0.0
    for i in range(n + 1):
        big = max(big, abs(B[i]))
    v = 0
    for i in range(n + 1):
        if abs(B[i]) <= 1e-11 * big:
            return -1
        if i > 0 and (B[i] < 0.0) != (B[i - 1] < 0.0):
            v += 1
    return v


@njit(cache=True)
def real_roots(c, lo, hi, out, err, ids, n_out, cid, work, stack):  # pragma: no cover - compiled
    """Append the real roots of the polynomial c (length DEG + 1) inside (lo, hi) to out[n_out:]
    (with their rounding errors in err, tagged cid); returns the new count. work (DEG + 1,
    DEG + 1), stack (S, 2 DEG + 2): buffers (S >= 64). Bernstein subdivision: an interval whose
    coefficients have no sign variation holds no root, one with one variation exactly one (found
    by `monotone_root`); any other is halved (de Casteljau) down to a width of 1e-13 (1 + |s|), where
    an odd sign change counts as one root at its middle (its error: at least that width) and an even
    one (a tangency) as none."""
    n = DEG
    scale = 0.0
    for k in range(DEG + 1):
        scale = max(scale, abs(c[k]))
    while n > 0 and abs(c[n]) <= 1e-14 * scale:
        n -= 1
    if n == 0:
        return n_out
    if bernstein_variations(c, n, lo, hi, stack[0]) == 0:
        return n_out
    for i in range(n + 1):  # the Bernstein coefficients on [lo, hi], then the interval
        stack[0, i] = stack[0, n + 1 + i]
    stack[0, DEG + 1], stack[0, DEG + 2] = lo, hi
    top = 1
    while top > 0:
        top -= 1
        B = stack[top]
        a, b = B[DEG + 1], B[DEG + 2]
        v = _variations(B, n)
        if v == 0:
            continue
        small = b - a <= 1e-13 * (1.0 + abs(a)) or top + 2 > stack.shape[0]
        width = 0.0
        if v == 1:  # (every coefficient nonzero)
            z = monotone_root(c, n, a, b, poly_value(c, n, a), poly_value(c, n, b))
        elif small:  # the root's position is known to the interval's width
            if B[0] * B[n] < 0.0:
                z = 0.5 * (a + b)
            elif B[n] == 0.0 and B[0] != 0.0:  # exactly at b (a halving point)
                z = b
            else:
                continue
            width = b - a
        else:  # halve: de Casteljau at 1/2, the right half into row top + 1, the left in place
            R = stack[top + 1]
            for i in range(n + 1):
                work[0, i] = B[i]
            for j in range(1, n + 1):
                for i in range(n + 1 - j):
                    work[j, i] = 0.5 * (work[j - 1, i] + work[j - 1, i + 1])
            for i in range(n + 1):
                B[i] = work[i, 0]
                R[i] = work[n - i, i]
            m = 0.5 * (a + b)
            B[DEG + 2] = m
            R[DEG + 1], R[DEG + 2] = m, b
            top += 2
            continue
        if lo < z < hi:
            out[n_out] = z
            err[n_out] = max(end_error(c, n, z, lo, hi), width)
            ids[n_out] = cid
            n_out += 1
    return n_out


@njit(cache=True)
def quadratic_roots(c, lo, hi, out, err, ids, n_out, cid):  # pragma: no cover - compiled
    """`real_roots` for c[0] + c[1] s + c[2] s^2 (c[2] != 0), by the quadratic formula in its
    cancellation-free form."""
    return roots_of_quadratic(c[2], c[1], c[0], c, 2, lo, hi, out, err, ids, n_out, cid)


@njit(cache=True)
def roots_of_quadratic(a, b, cc, c, deg, lo, hi, out, err, ids, n_out, cid):  # pragma: no cover - compiled
    """The simple roots in (lo, hi) of a s^2 + b s + cc (a != 0), in the cancellation-free form of
    the quadratic formula, appended to out / ids with their errors measured on the polynomial c of
    degree deg they are roots of (the quadratic itself, or a quartic it factors); returns the count."""
    disc = b * b - 4.0 * a * cc
    if not disc > 0.0:  # no root or a double one (a tangency: no sign change)
        return n_out
    sq = math.sqrt(disc)
    q = -0.5 * (b + sq if b >= 0.0 else b - sq)  # |q| >= sqrt(disc) / 2 > 0
    for k in range(2):
        z = q / a if k == 0 else cc / q
        if lo < z < hi:
            out[n_out] = z
            err[n_out] = end_error(c, deg, z, lo, hi)
            ids[n_out] = cid
            n_out += 1
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
