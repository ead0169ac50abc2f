"""Reading a URDF file: XML checks with messages that say what is wrong, the Pinocchio model
(fixed base), and the joint ranges the file does not give."""

from __future__ import annotations

import os
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pinocchio as pin

from kinematics.errors import ModelFileError

__all__ = ["build_model", "check_urdf_file", "missing_range_sides", "read_urdf"]


@contextmanager
def _quiet_stderr() -> Iterator[list[str]]:
    """Capture C-level stderr (urdfdom prints parse errors there) into the yielded list."""
    captured: list[str] = []
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        saved = os.dup(2)
        os.dup2(tmp.fileno(), 2)
        try:
            yield captured
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            captured.append(tmp.read().decode(errors="replace"))


def check_urdf_file(path: str | os.PathLike[str]) -> ET.Element:
    """Return the parsed XML root of a URDF file, or raise `ModelFileError` saying what is wrong."""
    p = Path(path)
    if not p.exists():
        raise ModelFileError(p, "no such file")
    if not p.is_file():
        raise ModelFileError(p, "not a file")
    try:
        root = ET.parse(p).getroot()
    except ET.ParseError as exc:
        raise ModelFileError(p, f"malformed XML ({exc})") from None
    except OSError as exc:
        raise ModelFileError(p, f"cannot read ({exc.strerror})") from None
    if root.tag != "robot":
        raise ModelFileError(p, f"not a URDF: root element is <{root.tag}>, expected <robot>")
    return root


def build_model(path: str | os.PathLike[str]) -> pin.Model:
    """Parse a URDF with Pinocchio (fixed base); malformed files raise `ModelFileError`."""
    return read_urdf(path)[0]


def read_urdf(path: str | os.PathLike[str]) -> tuple[pin.Model, ET.Element]:
    """The Pinocchio model (fixed base) of a URDF file and its checked XML tree, the file read
    once by each parser; malformed files raise `ModelFileError`."""
    root = check_urdf_file(path)
    with _quiet_stderr() as log:
        try:
            model = pin.buildModelFromUrdf(str(path))
        except (ValueError, RuntimeError) as exc:
            err: Exception | None = exc
        else:
            err = None
    if err is not None:
        detail = next((ln.strip() for ln in log[0].splitlines() if "Error" in ln), str(err))
        raise ModelFileError(path, f"Pinocchio cannot parse it: {detail}")
    return model, root


def missing_range_sides(root: ET.Element) -> dict[str, tuple[bool, bool]]:
    """Revolute and prismatic joints of a URDF tree whose `<limit>` lacks `lower` or `upper`, or
    gives an empty range (lower = upper): name -> (lower missing, upper missing).

    The URDF format defaults a missing side to 0, which Pinocchio follows; models exported without
    ranges (Gepetto's write `<limit effort velocity/>`) mean "no range given", so the toolkit reads
    such a side as unbounded instead. An explicit lower = upper (example-robot-data's
    double_pendulum writes `lower="0" upper="0"` with zero effort and velocity) is the same
    placeholder written out: a joint that cannot move would be `fixed`, so both sides count as
    not given rather than as a range of zero width."""
    out = {}
    for joint in root.findall("joint"):
        if joint.get("type") not in ("revolute", "prismatic"):
            continue
        limit = joint.find("limit")
        sides = (limit is None or limit.get("lower") is None, limit is None or limit.get("upper") is None)
        if limit is not None and not any(sides) and _number(limit.get("lower")) == _number(limit.get("upper")):
            sides = (True, True)
        if any(sides):
            out[joint.get("name") or ""] = sides
    return out


def _number(text: str | None) -> float | None:
    try:
        return float(text) if text is not None else None
    except ValueError:
        return None
