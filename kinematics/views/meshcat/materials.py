"""Colours and materials as meshcat takes them: RGB in 0..1 as a CSS colour or a 0xRRGGBB
integer, and a points material with an opacity."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any


def css_colour(rgb: Sequence[float]) -> str:
    """RGB in 0..1 as a CSS colour "#rrggbb"."""
    return f"#{hex_colour(rgb):06x}"


def hex_colour(rgb: Sequence[float]) -> int:
    """RGB in 0..1 (clipped) as the integer 0xRRGGBB meshcat's materials take."""
    r, g, b = (round(255 * max(0.0, min(1.0, c))) for c in rgb[:3])
    return (r << 16) | (g << 8) | b


def points_material(size: float, opacity: float) -> Any:
    """meshcat's PointsMaterial, with the opacity 0.3.2's lacks."""
    import meshcat.geometry as mg

    material = mg.PointsMaterial(size=size)
    plain = material.lower
    material.lower = lambda data: {**plain(data), "opacity": opacity, "transparent": opacity < 1}
    return material
