"""One guidance control step (force in, joint command out) against the 1 kHz budget, with the
Pinocchio calls the same step would make measured side by side in one run.

Goal: p99 <= 50 us (a twentieth of the 1 ms period). Run: python benchmarks/bench_guidance_step.py
"""

from __future__ import annotations

import time

import numpy as np
import pinocchio as pin

from kinematics.guidance.controller import Controller, GuidanceParams, ScaraKinematics, SerialKinematics
from kinematics.mechanisms.scara.closed_form import ScaraParams
from kinematics.model.robot import load_robot


def timings(fn, n: int) -> np.ndarray:
    out = np.empty(n)
    clock = time.perf_counter_ns
    for i in range(n):
        t = clock()
        fn(i)
        out[i] = clock() - t
    return out / 1e3  # us


def row(name: str, us: np.ndarray) -> str:
    p50, p99, mx = np.percentile(us, 50), np.percentile(us, 99), us.max()
    return f"  {name:<52} p50 {p50:7.2f} us   p99 {p99:7.2f} us   max {mx:8.1f} us"


def main() -> None:
    n = 20000
    robot = load_robot("scara")
    sp = ScaraParams.from_robot(robot)
    kin = ScaraKinematics(sp)
    q0 = kin.ik(np.array([0.55, 0.05]), np.array([0.0, -1.0]))
    forces = np.zeros((n, 2))
    forces[:, 0] = 6.0 * np.sin(np.linspace(0, 20, n)) ** 2  # pushing and easing off

    ctrl = Controller(kin, GuidanceParams(), q0)
    step = timings(lambda i: ctrl.step(forces[i]), n)
    ctrl = Controller(kin, GuidanceParams(), q0)
    ellipse = timings(lambda i: kin.ellipse(ctrl.q), n)
    ik = timings(lambda i: kin.ik(ctrl.x, ctrl.q), n)

    model, data = robot.model, robot.model.createData()
    fid = robot.frame_id()
    q = np.asarray(q0)
    pin_fk = timings(lambda i: pin.framesForwardKinematics(model, data, q), n)
    pin_jac = timings(lambda i: pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED), n)

    gen = SerialKinematics(robot)
    ctrl_g = Controller(gen, GuidanceParams(), q0)
    gen_forces = np.concatenate([forces, np.zeros((n, 1))], axis=1)
    step_pin = timings(lambda i: ctrl_g.step(gen_forces[i]), 5000)

    print(f"guidance control step, SCARA, {n:,} steps (1 kHz budget: 1000 us; goal p99 <= 50 us)")
    print(row("full step, closed forms (ScaraKinematics)", step))
    print(row("  of which: ellipse radii + direction (closed form)", ellipse))
    print(row("  of which: IK with limits (closed form)", ik))
    print(row("Pinocchio framesForwardKinematics", pin_fk))
    print(row("Pinocchio computeFrameJacobian", pin_jac))
    print(row("full step, generic Pinocchio path (SerialKinematics)", step_pin))
    print(f"  ratio p99 generic / closed-form step: {np.percentile(step_pin, 99) / np.percentile(step, 99):.1f} x")


if __name__ == "__main__":
    main()
