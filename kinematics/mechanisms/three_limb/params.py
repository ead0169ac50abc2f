"""The parts of a three-limb design both families share: limb angles alpha_i, the limb frames
e_i, t_i, validation, and the plain-dict and `replace` conveniences."""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any, TypeVar

import numpy as np

from kinematics.errors import InvalidDesignError, InvalidInputError

_Design = TypeVar("_Design", bound="LimbDesign")


def check_pair(name: str, pair: tuple[float, float], lo_bound: float = -math.inf) -> None:
    """Raise InvalidInputError unless `pair` is a finite range lower < upper, lower >= lo_bound."""
    lo, hi = pair
    if not (math.isfinite(lo) and math.isfinite(hi) and lo_bound <= lo < hi):
        bound = f" (>= {lo_bound:g})" if lo_bound > -math.inf else ""
        raise InvalidInputError(name, f"need finite lower < upper{bound}, got {pair}")


class LimbDesign:
    """Mixin for the frozen parameter dataclasses of the three-limb families.

    Limb i has the horizontal unit vectors e_i = (cos a_i, sin a_i, 0) (outward) and
    t_i = (-sin a_i, cos a_i, 0) (tangential); rows of `e` and `t`, shape (3, 3).
    """

    alpha: tuple[float, float, float]

    def check_common(self, lengths: tuple[str, ...], angles: tuple[str, ...]) -> None:
        """Positive finite `lengths` [m], finite `angles` [rad], three finite limb angles that
        differ modulo 360 degrees (InvalidInputError, InvalidDesignError)."""
        for name in lengths:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise InvalidInputError(name, f"must be a positive length [m], got {value}")
        for name in angles:
            if not math.isfinite(getattr(self, name)):
                raise InvalidInputError(name, "must be finite")
        if len(self.alpha) != 3 or not all(math.isfinite(a) for a in self.alpha):
            raise InvalidInputError("alpha", f"need three finite limb angles, got {self.alpha}")
        for i, j in ((0, 1), (1, 2), (0, 2)):
            # angular distance mod 2 pi; 1e-9 rad: limbs closer than ~1e-9 m apart on a 1 m base
            if abs(math.remainder(self.alpha[i] - self.alpha[j], 2 * math.pi)) < 1e-9:
                raise InvalidDesignError("alpha", [float(f"{math.degrees(a):.10g}") for a in self.alpha],
                                         f"limbs {i + 1} and {j + 1} coincide (limb angles in degrees "
                                         "must differ modulo 360)")

    def as_dict(self) -> dict[str, Any]:
        """Plain dict of the parameters (tuples as lists), SI units."""
        fields = dataclasses.asdict(self)  # type: ignore[call-overload]
        return {k: list(v) if isinstance(v, tuple) else v for k, v in fields.items()}

    def replace(self: _Design, **changes: Any) -> _Design:
        """A copy with some parameters changed (`dataclasses.replace`, validated by `__post_init__`)."""
        return dataclasses.replace(self, **changes)  # type: ignore[type-var]

    @functools.cached_property
    def e(self) -> np.ndarray:
        """Outward unit vectors e_i, rows of shape (3, 3)."""
        a = np.asarray(self.alpha)
        return np.stack([np.cos(a), np.sin(a), np.zeros(3)], axis=-1)

    @functools.cached_property
    def t(self) -> np.ndarray:
        """Tangential unit vectors t_i, rows of shape (3, 3)."""
        a = np.asarray(self.alpha)
        return np.stack([-np.sin(a), np.cos(a), np.zeros(3)], axis=-1)
