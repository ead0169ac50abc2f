"""Robot models: loading URDFs (built-ins, paths, example-robot-data), loop-closure sidecars, Gepetto robot.yaml import, URDF XML helpers.

Modules: `gepetto`, `loops`, `robot`, `urdf_xml`. Public names are re-exported
here and imported on first use, so importing the package stays light.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from kinematics.model.gepetto import (
        FILENAME,
        KEYS,
        LEGACY_KEYS,
        SUBSTITUTIONS,
        GepettoFormatError,
        GepettoSpec,
        find_gepetto,
        gepetto_file_for,
        loop_spec,
        read_gepetto,
        substitute_joints,
    )
    from kinematics.model.loops import (
        FORMAT,
        Closure,
        LoopSpec,
        find_loop_spec,
        load_loop_spec,
        sidecar_for,
    )
    from kinematics.model.robot import (
        BUILTIN,
        ERD_ALIASES,
        URDF_DIR,
        Dof,
        ParserAgreement,
        Robot,
        check_urdf_file,
        erd_catalogue,
        erd_robots_dir,
        load_robot,
        matrix,
        parser_agreement,
        robot_names,
    )
    from kinematics.model.urdf_xml import (
        UrdfBuilder,
        axis_of,
        limit_of,
        num,
        origin_of,
        rot_y,
        rot_z,
        rpy_of,
        vec,
        visual,
    )

_LAZY = {
    "BUILTIN": "robot",
    "Closure": "loops",
    "Dof": "robot",
    "ERD_ALIASES": "robot",
    "FILENAME": "gepetto",
    "FORMAT": "loops",
    "GepettoFormatError": "gepetto",
    "GepettoSpec": "gepetto",
    "KEYS": "gepetto",
    "LEGACY_KEYS": "gepetto",
    "LoopSpec": "loops",
    "ParserAgreement": "robot",
    "Robot": "robot",
    "SUBSTITUTIONS": "gepetto",
    "URDF_DIR": "robot",
    "UrdfBuilder": "urdf_xml",
    "axis_of": "urdf_xml",
    "check_urdf_file": "robot",
    "erd_catalogue": "robot",
    "erd_robots_dir": "robot",
    "find_gepetto": "gepetto",
    "find_loop_spec": "loops",
    "gepetto_file_for": "gepetto",
    "limit_of": "urdf_xml",
    "load_loop_spec": "loops",
    "load_robot": "robot",
    "loop_spec": "gepetto",
    "matrix": "robot",
    "num": "urdf_xml",
    "origin_of": "urdf_xml",
    "parser_agreement": "robot",
    "read_gepetto": "gepetto",
    "robot_names": "robot",
    "rot_y": "urdf_xml",
    "rot_z": "urdf_xml",
    "rpy_of": "urdf_xml",
    "sidecar_for": "loops",
    "substitute_joints": "gepetto",
    "vec": "urdf_xml",
    "visual": "urdf_xml",
}

__all__ = [
    "BUILTIN",
    "ERD_ALIASES",
    "FILENAME",
    "FORMAT",
    "KEYS",
    "LEGACY_KEYS",
    "SUBSTITUTIONS",
    "URDF_DIR",
    "Closure",
    "Dof",
    "GepettoFormatError",
    "GepettoSpec",
    "LoopSpec",
    "ParserAgreement",
    "Robot",
    "UrdfBuilder",
    "axis_of",
    "check_urdf_file",
    "erd_catalogue",
    "erd_robots_dir",
    "find_gepetto",
    "find_loop_spec",
    "gepetto_file_for",
    "limit_of",
    "load_loop_spec",
    "load_robot",
    "loop_spec",
    "matrix",
    "num",
    "origin_of",
    "parser_agreement",
    "read_gepetto",
    "robot_names",
    "rot_y",
    "rot_z",
    "rpy_of",
    "sidecar_for",
    "substitute_joints",
    "vec",
    "visual",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
