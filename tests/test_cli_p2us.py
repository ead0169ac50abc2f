"""The CLI on the 3-[P2(US)]: ik, fk, jacobian, info, urdf; exit codes and JSON keys."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from kinematics.cli.app import main
from kinematics.model.robot import URDF_DIR

from .same_text import assert_same_text
from .test_cli import run, run_json

MODELS = Path(__file__).parent / "models"


def test_ik(capsys):
    code, data, _ = run_json(capsys, "ik", "p2us", "--position", "0", "0", "-0.45")
    assert code == 0 and data["reachable"] is True and data["reason"] is None
    assert len(data["solutions"]) == 8
    assert all(set(s) >= {"q", "mode", "within_limits", "violations"} for s in data["solutions"])
    ok = [s["mode"] for s in data["solutions"] if s["within_limits"]]
    assert ok == ["---"]
    assert [lb["limb"] for lb in data["limbs"]] == [1, 2, 3] and all(lb["reachable"] for lb in data["limbs"])
    bad = next(s for s in data["solutions"] if s["mode"] == "+++")
    assert any("stroke" in v for v in bad["violations"])


def test_ik_unreachable_names_the_limb(capsys):
    code, data, err = run_json(capsys, "ik", "p2us", "--position", "0.6", "0", "-0.3")
    assert code == 1 and data["reachable"] is False and err == ""
    assert data["solutions"] == [] and "limb" in data["reason"]
    assert any(not lb["reachable"] and "rail's axis" in lb["reason"] for lb in data["limbs"])
    code, out, _ = run(capsys, "ik", "p2us", "--position", "0.6", "0", "-0.3")
    assert code == 1 and "NOT reachable" in out


def test_fk(capsys):
    code, data, _ = run_json(capsys, "fk", "p2us", "--q", "0.3", "0.25", "0.2")
    assert code == 0 and data["exists"] is True
    assert [s["mode"] for s in data["solutions"]] == ["below", "above"]
    assert all(set(s) >= {"position", "mode", "within_limits"} for s in data["solutions"])
    code, data, _ = run_json(capsys, "fk", "p2us", "--q", "0.1", "1.5", "1.5")
    assert code == 1 and data["exists"] is False and "do not meet" in data["reason"]


def test_fk_then_ik_round_trip(capsys):
    _, fk, _ = run_json(capsys, "fk", "p2us", "--q", "0.3", "0.25", "0.2")
    pos = fk["solutions"][0]["position"]
    _, ik, _ = run_json(capsys, "ik", "p2us", "--position", *map(repr, pos))
    best = min(np.abs(np.array(s["q"]) - [0.3, 0.25, 0.2]).max() for s in ik["solutions"])
    assert best <= 1e-9


def test_jacobian(capsys):
    code, data, _ = run_json(capsys, "jacobian", "p2us", "--position", "0", "0", "-0.45")
    assert code == 0
    assert set(data) >= {"J", "Jx", "Jq", "det_Jx", "det_Jq", "singularity"}
    assert data["singularity"] == "none" and data["mode"] == "---"
    # independent of the report's own algebra: J against central differences of the IK in mode
    # "---" (h = 1e-6 m: truncation ~h^2, rounding ~1e-16/h; atol 1e-8), J_x's rows against the
    # rods C_i - B_i built here from the design (P2USParams defaults = the built-in URDF)
    from kinematics.mechanisms.p2us import closed_form as par

    P, p, m, h = par.P2USParams(), np.array([0.0, 0.0, -0.45]), par.mode_index("---"), 1e-6
    fd = np.stack([(par.ik(P, p + h * e).q[m] - par.ik(P, p - h * e).q[m]) / (2 * h) for e in np.eye(3)], axis=1)
    np.testing.assert_allclose(np.array(data["J"]), fd, atol=1e-8)
    q = par.ik(P, p).q[m]
    rods = p + P.d * P.e - P.b * P.e - q[:, None] * P.w
    np.testing.assert_allclose(np.array(data["Jx"]), rods, atol=1e-12)
    assert data["det_Jx"] == pytest.approx(np.linalg.det(rods), rel=1e-9)
    code, data, _ = run_json(capsys, "jacobian", "p2us", "--position", "0", "0", "-0.45", "--mode", "+++")
    assert code == 0 and data["mode"] == "+++" and data["within_limits"] is False
    code, data, _ = run_json(capsys, "jacobian", "p2us", "--position", "2", "0", "0")
    assert code == 1 and data["reachable"] is False


def test_jacobian_type_one(capsys):
    from kinematics.mechanisms.p2us.closed_form import P2USParams

    P = P2USParams()
    n1 = np.cross(P.w[0], P.t[0])
    n1 = -n1 / np.linalg.norm(n1) if n1[2] > 0 else n1 / np.linalg.norm(n1)
    p = P.base_points[0] + 0.3 * P.w[0] + P.L * n1 - P.d * P.e[0]
    code, data, _ = run_json(capsys, "jacobian", "p2us", "--position", *map(repr, p.tolist()))
    assert code == 0 and data["singularity"] == "type I"


def test_info_shows_parameters(capsys):
    code, data, _ = run_json(capsys, "info", "p2us")
    assert code == 0 and data["parameters"]["L"] == 0.34 and data["parameters"]["b"] == 0.325
    assert data["loops"]["mechanism"] == "3-[P2(US)]" and len(data["loops"]["constraints"]) == 5
    code, out, _ = run(capsys, "info", "p2us")
    assert "loop closures" in out and "rod_spacing" in out


def test_urdf_generator(capsys, tmp_path):
    out = tmp_path / "design.urdf"
    code, data, _ = run_json(capsys, "urdf", "p2us", "-o", str(out), "--L", "0.4", "--beta", "35", "--degrees")
    assert code == 0 and data["round_trip"] is True
    assert Path(data["sidecar"]).exists() and data["parameters"]["L"] == 0.4
    code, info, _ = run_json(capsys, "info", str(out))
    assert info["parameters"]["beta"] == pytest.approx(np.radians(35))
    code, ik, _ = run_json(capsys, "ik", str(out), "--position", "0", "0", "-0.5")
    assert code in (0, 1) and len(ik["limbs"]) == 3
    # default design = the shipped file
    code, _, _ = run_json(capsys, "urdf", "p2us", "-o", str(tmp_path / "p2us.urdf"))
    assert_same_text((tmp_path / "p2us.urdf").read_text(), (URDF_DIR / "p2us.urdf").read_text())


def test_generic_loop_robot_through_pinocchio(capsys):
    code, data, _ = run_json(capsys, "fk", str(MODELS / "fourbar.urdf"), "--q", "0.5")
    assert code == 0 and data["residual"] <= 1e-12 and len(data["position"]) == 3
    code, data, _ = run_json(capsys, "jacobian", str(MODELS / "fourbar.urdf"), "--q", "0.5")
    assert code == 0 and np.array(data["jacobian"]).shape == (6, 1)


def bad_inputs(tmp_path):
    bad_side = tmp_path / "bad.urdf"
    bad_side.write_text((URDF_DIR / "p2us.urdf").read_text())
    (tmp_path / "bad.loops.yaml").write_text(
        (URDF_DIR / "p2us.loops.yaml").read_text().replace("frame1: tip_2_1", "frame1: tip_9_9"))
    return [
        (["ik", "p2us", "--position", "0", "nan", "-0.4"], "finite"),
        (["ik", "p2us", "--position", "0", "-0.4"], "X Y Z"),
        (["fk", "p2us", "--q", "0.3", "0.2"], "3 actuated joints"),
        (["fk", "p2us", "--q", "0.3", "inf", "0.2"], "finite"),
        (["jacobian", "p2us", "--position", "0", "0", "-0.45", "--mode", "++"], "unknown mode"),
        (["jacobian", "p2us"], "X Y Z"),
        (["info", str(bad_side)], "unknown frame 'tip_9_9'"),
        (["ik", str(tmp_path / "nothere.urdf"), "--position", "0", "0", "0"], "no such file"),
        (["urdf", "p2us", "-o", str(tmp_path / "x.urdf"), "--L", "-1"], "positive length"),
        (["urdf", "p2us", "-o", str(tmp_path / "x.urdf"), "--b", "nan"], "must be finite"),
        (["urdf", "p2us", "-o", str(tmp_path / "missing_dir" / "x.urdf")], "does not exist"),
        (["urdf", "scara", "-o", str(tmp_path / "x.urdf")], "invalid choice"),
        (["manipulability", "p2us", "--q", *["0"] * 18], "serial robot"),
    ]


def test_bad_input(capsys, tmp_path):
    for argv, needle in bad_inputs(tmp_path):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code
        out, err = capsys.readouterr()
        assert code == 2, argv
        assert err.count("\n") == 1 and needle in err, (argv, err)
        assert out == ""
    assert not (tmp_path / "x.urdf").exists() and not (tmp_path / "x.loops.yaml").exists()  # nothing half-written


def test_subprocess(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "kinematics", "ik", "p2us", "--position", "0", "0", "-0.45", "--json"],
                          capture_output=True, text=True)
    assert proc.returncode == 0 and json.loads(proc.stdout)["reachable"] is True
    argv, needle = bad_inputs(tmp_path)[6]
    proc = subprocess.run([sys.executable, "-m", "kinematics", *argv], capture_output=True, text=True)
    assert proc.returncode == 2 and needle in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.parametrize(("robot", "q"), [
    # an actuator on its range's end, every other limit held (found by sampling such poses): the
    # IK recovers that actuator a few ulp beyond the end, which must still count as within
    ("p2us", ["0.16754825251120561", "0.1", "0.362677161237863"]),  # stroke's lower end 0.1 m
    ("delta", ["1.5707963267948966", "0.43048459455480026", "0.5028394948183198"]),  # theta's upper end pi/2
])
def test_fk_then_ik_round_trip_on_an_actuator_bound(capsys, robot, q):
    code, fk, _ = run_json(capsys, "fk", robot, "--q", *q)
    below = fk["solutions"][0]
    assert code == 0 and below["within_limits"] is True
    code, ik, _ = run_json(capsys, "ik", robot, "--position", *map(repr, below["position"]))
    back = [s for s in ik["solutions"] if np.abs(np.array(s["q"]) - np.array(q, dtype=float)).max() <= 1e-9]
    assert code == 0 and len(back) == 1 and back[0]["within_limits"] is True and back[0]["violations"] == []
