"""Comparing two URDFs as the models Pinocchio builds from them, and two sidecars as parsed YAML.

A regenerated model file may be written differently (layout, number text) and still be the same
model: what must not move is every joint's type, axis, placement and limits and every frame's
parent and placement, as the parser reads them. 1e-15 [m, rad, and unitless rotation entries]:
a few ulps of the O(1) numbers involved, so only rounding in the last bit passes.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import yaml

TOL = 1e-15


def _joint_axis(joint: pin.JointModel) -> tuple[float, ...]:
    """The axis Pinocchio keeps for a joint (unaligned revolute/prismatic), else () (the axis of
    an aligned joint is in its short name, RX/RY/RZ/PX/...)."""
    try:
        return tuple(np.asarray(joint.extract().axis, dtype=float))
    except AttributeError:
        return ()


def model_differences(urdf_a: str, urdf_b: str, tol: float = TOL) -> list[str]:
    """What differs between the Pinocchio models of two URDF texts (empty when the same to tol)."""
    a, b = pin.buildModelFromXML(urdf_a), pin.buildModelFromXML(urdf_b)
    out: list[str] = []
    if list(a.names) != list(b.names) or list(a.parents) != list(b.parents):
        return [f"joints differ: {list(a.names)} / {list(b.names)}"]
    for j in range(1, a.njoints):
        name = a.names[j]
        ja, jb = a.joints[j], b.joints[j]
        if ja.shortname() != jb.shortname() or ja.idx_q != jb.idx_q:
            out.append(f"joint {name}: type {ja.shortname()} / {jb.shortname()}")
        axa, axb = _joint_axis(ja), _joint_axis(jb)
        if len(axa) != len(axb) or np.abs(np.subtract(axa, axb)).max(initial=0.0) > tol:
            out.append(f"joint {name}: axis {axa} / {axb}")
        d = np.abs(a.jointPlacements[j].homogeneous - b.jointPlacements[j].homogeneous).max()
        if d > tol:
            out.append(f"joint {name}: placement differs by {d:.3g}")
    for what in ("lowerPositionLimit", "upperPositionLimit", "effortLimit", "velocityLimit"):
        va, vb = np.asarray(getattr(a, what)), np.asarray(getattr(b, what))
        if va.shape != vb.shape or np.abs(va - vb).max(initial=0.0) > tol:
            out.append(f"{what}: {va} / {vb}")
    fa, fb = [f.name for f in a.frames], [f.name for f in b.frames]
    if fa != fb:
        return [*out, f"frames differ: {sorted(set(fa) ^ set(fb))}"]
    for f, g in zip(a.frames, b.frames, strict=True):
        if (f.parentJoint, f.parentFrame, f.type) != (g.parentJoint, g.parentFrame, g.type):
            out.append(f"frame {f.name}: parent or type differs")
        d = np.abs(f.placement.homogeneous - g.placement.homogeneous).max()
        if d > tol:
            out.append(f"frame {f.name}: placement differs by {d:.3g}")
    return out


def assert_same_model(urdf_a: str, urdf_b: str, tol: float = TOL) -> None:
    """Fail, listing what differs, unless the two URDF texts build the same Pinocchio model."""
    diff = model_differences(urdf_a, urdf_b, tol)
    assert not diff, "\n".join(diff)


def _same_data(a: object, b: object, tol: float, where: str) -> list[str]:
    if isinstance(a, float) or isinstance(b, float):
        ok = isinstance(a, (int, float)) and isinstance(b, (int, float)) and abs(a - b) <= tol
        return [] if ok else [f"{where}: {a!r} / {b!r}"]
    if isinstance(a, dict) and isinstance(b, dict):
        if list(a) != list(b):
            return [f"{where}: keys {list(a)} / {list(b)}"]
        return [d for k in a for d in _same_data(a[k], b[k], tol, f"{where}.{k}")]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for k, (x, y) in enumerate(zip(a, b, strict=True)) for d in _same_data(x, y, tol, f"{where}[{k}]")]
    return [] if a == b else [f"{where}: {a!r} / {b!r}"]


def assert_same_yaml(text_a: str, text_b: str, tol: float = TOL) -> None:
    """Fail unless two YAML texts parse to the same data: the same keys in the same order, the
    same strings, and floats equal to tol (the reference configuration's last bits may depend on
    the machine's SIMD path, as `same_text` explains)."""
    diff = _same_data(yaml.safe_load(text_a), yaml.safe_load(text_b), tol, "sidecar")
    assert not diff, "\n".join(diff)
