"""`kinematics urdf`: write the URDF and loop sidecar of a 3-[P2(US)] or Delta design."""

from __future__ import annotations

import argparse
import math
from typing import Any

from kinematics.cli.args import EXIT_OK, Command, number, positive
from kinematics.cli.report import emit, key_values
from kinematics.errors import InvalidInputError


def register(command: Command) -> None:
    p = command("urdf", cmd_urdf, "write the URDF + loop sidecar of a 3-[P2(US)] (paper B's by default) or "
                                   "Delta design")
    p.add_argument("robot", metavar="ROBOT", choices=["p2us", "delta"], help="the mechanism: p2us or delta")
    p.add_argument("-o", "--output", required=True, metavar="FILE",
                   help="URDF to write; the sidecar goes beside it as NAME.loops.yaml")
    p.add_argument("--design", choices=["table2", "results"], default="table2",
                   help="p2us: the preset the flags below change: table2 (paper B's Table 2, built-in p2us; "
                        "default) or results (the geometry behind its computed results, built-in p2us-results)")
    p.add_argument("--b", type=number, metavar="M", help="base radius [m] (default p2us 0.325, delta 0.2)")
    p.add_argument("--d", type=number, metavar="M", help="platform radius [m] (default p2us 0.028, delta 0.05)")
    p.add_argument("--L", type=number, metavar="M", help="p2us: rod length [m] (default 0.34)")
    p.add_argument("--beta", type=number, metavar="A", help="p2us: rail angle below horizontal [rad] (default 40 deg)")
    p.add_argument("--alpha", type=number, nargs=3, metavar="A", help="limb angles [rad] (default 0, 120, 240 deg)")
    p.add_argument("--stroke", type=number, nargs=2, metavar=("MIN", "MAX"),
                   help="p2us: actuator range [m] (default 0.1 0.6)")
    p.add_argument("--theta", type=number, nargs=2, metavar=("MIN", "MAX"),
                   help="p2us: universal joint theta range [rad] (default -10 100 deg); delta: actuator range "
                        "below the horizontal [rad] (default -40 90 deg)")
    p.add_argument("--phi", type=number, nargs=2, metavar=("MIN", "MAX"),
                   help="p2us: universal joint phi range [rad] (default -70 70 deg)")
    p.add_argument("--theta-zero", type=number, metavar="A",
                   help="p2us: rod elevation below the inward horizontal at theta = 0 [rad] (default 0)")
    p.add_argument("--rod-spacing", type=number, metavar="M",
                   help="parallelogram rod spacing [m] (default p2us 0.05, delta 0.08)")
    p.add_argument("--upper-arm", type=number, metavar="M", help="delta: upper-arm length [m] (default 0.3)")
    p.add_argument("--forearm", type=number, metavar="M", help="delta: forearm (rod) length [m] (default 0.8)")
    p.add_argument("--cone", type=number, metavar="A", help="delta: ball-joint cone half-angle [rad] (default 45 deg)")
    p.add_argument("--elbow-socket", type=number, metavar="A",
                   help="delta: elbow socket axis below the upper arm [rad] (default 90 deg)")
    p.add_argument("--platform-socket", type=number, metavar="A",
                   help="delta: platform socket axis tilt outward from vertical [rad] (default 20 deg)")
    p.add_argument("--degrees", action="store_true", help="angle flags in degrees")
    sizes = p.add_argument_group("collision shapes [m] (recorded in the sidecar's collisions block)")
    for flag, text in SIZE_FLAGS.items():
        sizes.add_argument(f"--{flag.replace('_', '-')}", type=positive, metavar="M", help=text)


SIZE_FLAGS = {
    "rod_radius": "rods' capsule radius (default 0.006)",
    "arm_radius": "p2us: rails', delta: upper arms' capsule radius (default p2us 0.01, delta 0.015)",
    "plate_thickness": "base plate thickness (default 0.02)",
    "plate_overhang": "base plate radius beyond b (p2us) or R (delta) (default p2us 0.03, delta 0.05)",
    "platform_overhang": "platform sphere's radius beyond d (p2us) or r (delta) (default 0.02)",
}


URDF_FLAGS: dict[str, dict[str, str]] = {
    # CLI flag (argparse dest) -> parameter name, per mechanism; angles marked by ANGLES
    "p2us": {"b": "b", "d": "d", "L": "L", "beta": "beta", "alpha": "alpha", "stroke": "stroke",
             "theta": "theta_limits", "phi": "phi_limits", "theta_zero": "theta_zero", "rod_spacing": "rod_spacing"},
    "delta": {"b": "R", "d": "r", "upper_arm": "la", "forearm": "lb", "alpha": "alpha", "theta": "theta_limits",
              "cone": "cone", "elbow_socket": "elbow_socket", "platform_socket": "platform_socket",
              "rod_spacing": "rod_spacing"},
}
ANGLES = {"beta", "alpha", "theta", "phi", "theta_zero", "cone", "elbow_socket", "platform_socket"}


def cmd_urdf(args: argparse.Namespace) -> int:
    """`kinematics urdf p2us|delta [design flags] -o FILE`: write the URDF and its loop sidecar."""
    from kinematics.mechanisms.delta import urdf as delta_urdf
    from kinematics.mechanisms.delta.closed_form import DeltaParams
    from kinematics.mechanisms.p2us import urdf as p2us_urdf

    conv = math.radians if args.degrees else float
    flags = URDF_FLAGS[args.robot]
    for other, names in URDF_FLAGS.items():
        for flag in set(names) - set(flags):
            if getattr(args, flag, None) is not None:
                raise InvalidInputError(f"--{flag.replace('_', '-')}", f"applies to {other} only, not {args.robot}")
    design = getattr(args, "design", "table2")
    if args.robot != "p2us" and design != "table2":
        raise InvalidInputError("--design", f"presets are for p2us only, not {args.robot}")
    changes: dict[str, Any] = {}
    for flag, key in flags.items():
        value = getattr(args, flag)
        if value is None:
            continue
        f = conv if flag in ANGLES else float
        changes[key] = tuple(f(x) for x in value) if isinstance(value, list) else f(value)
    base: Any = p2us_urdf.DESIGNS[design] if args.robot == "p2us" else DeltaParams()
    module: Any = p2us_urdf if args.robot == "p2us" else delta_urdf
    write, read_params = module.write, module.read_params
    params = base.replace(**changes)  # validates every value
    sizes = module.SIZES.replace(**{k: float(getattr(args, k)) for k in SIZE_FLAGS if getattr(args, k, None) is not None})
    urdf_path, side = write(params, args.output, sizes=sizes)
    from kinematics.mechanisms.three_limb.urdf import read_collision_sizes

    back = read_params(urdf_path)
    same = back == params and read_collision_sizes(side, module.SIZES) == sizes
    payload = {"urdf": str(urdf_path), "sidecar": str(side), "parameters": params.as_dict(),
               "collision_sizes": sizes.as_dict(), "round_trip": same}

    def human() -> str:
        return "\n".join([f"wrote {urdf_path}", f"wrote {side}", "parameters (SI; read back "
                          + ("identical" if same else "DIFFERENT") + "):",
                          key_values([*params.as_dict().items(), *sizes.as_dict().items()], None)])

    emit(args, payload, human)
    return EXIT_OK
