"""Comparing a generated model file with the shipped one: the same text, numbers to rounding.

Generators print every number as the shortest text that reads back as the same float, and a few are the
end of a chain of trigonometry and 3 x 3 products whose last bits depend on the machine's SIMD path
(NumPy picks its sin/cos and matmul kernels by CPU). A byte comparison would then fail on one
machine and pass on another; the files' content is what matters, so the text outside numbers must
match exactly and each number to 1e-12 relative (plus 1e-15 absolute, for values that are rounding
noise around 0) — thousands of ulps, and far below any geometric tolerance of the models.
"""

from __future__ import annotations

import re

NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


def assert_same_text(got: str, want: str, rtol: float = 1e-12, atol: float = 1e-15) -> None:
    """Fail unless `got` and `want` are the same text with their numbers equal to rtol / atol."""
    g_num, w_num = NUMBER.findall(got), NUMBER.findall(want)
    assert NUMBER.sub("#", got) == NUMBER.sub("#", want), "the texts differ outside their numbers"
    assert len(g_num) == len(w_num)
    for k, (a, b) in enumerate(zip(g_num, w_num, strict=True)):
        x, y = float(a), float(b)
        assert abs(x - y) <= atol + rtol * max(abs(x), abs(y)), f"number {k}: {a} != {b}"
