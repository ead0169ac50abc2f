"""The CLI on the Delta: ik, fk, jacobian, info, mobility, urdf; exit codes and JSON keys."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from kinematics.cli.app import main
from kinematics.mechanisms.delta import closed_form as dl
from kinematics.model.robot import URDF_DIR

from .test_cli import run, run_json

HOME = ("0", "0", "-0.85")


def test_ik(capsys):
    code, data, _ = run_json(capsys, "ik", "delta", "--position", *HOME)
    assert code == 0 and data["reachable"] is True and data["reason"] is None
    assert len(data["solutions"]) == 8
    assert [s["mode"] for s in data["solutions"] if s["within_limits"]] == ["---"]
    # independent: limb 1's angle puts its elbow at l_b from the platform joint (definition)
    q1 = next(s for s in data["solutions"] if s["mode"] == "---")["q"][0]
    elbow = np.array([0.2 + 0.3 * math.cos(q1), 0.0, -0.3 * math.sin(q1)])
    assert abs(np.linalg.norm(np.array([0.05, 0.0, -0.85]) - elbow) - 0.8) <= 1e-12
    code, out, _ = run(capsys, "ik", "delta", "--position", *HOME)
    assert code == 0 and "q1 [rad]" in out


def test_ik_unreachable_names_the_limb(capsys):
    code, data, err = run_json(capsys, "ik", "delta", "--position", "2", "0", "-0.8")
    assert code == 1 and data["reachable"] is False and err == "" and data["solutions"] == []
    assert all(not lb["reachable"] and "forearm" in lb["reason"] for lb in data["limbs"])
    # reachable but outside every limit: a cone or the actuator range is named
    code, data, _ = run_json(capsys, "ik", "delta", "--position", "0", "0", "-0.5")
    assert code == 1 and data["solutions"] and "every working mode breaks a limit" in data["reason"]
    assert any("elbow ball joint" in v for s in data["solutions"] for v in s["violations"])


def test_fk_and_round_trip(capsys):
    code, data, _ = run_json(capsys, "fk", "delta", "--q", "10", "20", "30", "--degrees")
    assert code == 0 and data["exists"] is True
    assert [s["mode"] for s in data["solutions"]] == ["below", "above"]
    below = data["solutions"][0]
    assert below["within_limits"] is True and below["position"][2] < 0
    _, ik, _ = run_json(capsys, "ik", "delta", "--position", *map(repr, below["position"]))
    best = min(np.abs(np.array(s["q"]) - np.radians([10, 20, 30])).max() for s in ik["solutions"])
    assert best <= 1e-9


def test_jacobian(capsys):
    code, data, _ = run_json(capsys, "jacobian", "delta", "--position", *HOME)
    assert code == 0 and data["mode"] == "---" and data["singularity"] == "none"
    assert set(data) >= {"J", "Jx", "Jq", "det_Jx", "det_Jq", "measures"}
    P, p, m, h = dl.DeltaParams(), np.array([0.0, 0.0, -0.85]), dl.mode_index("---"), 1e-6
    fd = np.stack([(dl.ik(P, p + h * e).q[m] - dl.ik(P, p - h * e).q[m]) / (2 * h) for e in np.eye(3)], axis=1)
    np.testing.assert_allclose(np.array(data["J"]), fd, atol=1e-8)  # h^2 truncation, 1e-16/h rounding
    code, out, _ = run(capsys, "jacobian", "delta", "--position", *HOME)
    assert "min |n.b|" in out
    # type II: the forearms vertical (elbows straight above the platform joints, theta = 120 deg)
    z = -0.3 * math.sin(math.radians(120)) - 0.8
    code, data, _ = run_json(capsys, "jacobian", "delta", "--position", "0", "0", repr(z), "--mode", "+++")
    assert code == 0 and data["singularity"] == "type II" and data["within_limits"] is False


def test_info_and_mobility(capsys):
    code, data, _ = run_json(capsys, "info", "delta")
    assert code == 0 and data["parameters"]["lb"] == 0.8 and data["parameters"]["R"] == 0.2
    assert data["loops"]["mechanism"] == "3-RUU Delta" and len(data["loops"]["constraints"]) == 5
    code, data, _ = run_json(capsys, "mobility", "delta")
    assert code == 0 and data["screw"]["translations"] == 3 and data["screw"]["rotations"] == 0
    code, data, _ = run_json(capsys, "mobility", "delta", "--position", "0.1", "0", "-0.8")
    assert code == 0 and data["numeric"]["mobility"] == 3 and "mode ---" in data["configuration"]


def test_urdf_generator(capsys, tmp_path):
    out = tmp_path / "design.urdf"
    code, data, _ = run_json(capsys, "urdf", "delta", "-o", str(out), "--forearm", "0.9", "--cone", "40", "--degrees")
    assert code == 0 and data["round_trip"] is True and Path(data["sidecar"]).exists()
    code, info, _ = run_json(capsys, "info", str(out))
    assert info["parameters"]["lb"] == 0.9 and info["parameters"]["cone"] == pytest.approx(math.radians(40))
    code, _, _ = run_json(capsys, "urdf", "delta", "-o", str(tmp_path / "delta.urdf"))
    assert (tmp_path / "delta.urdf").read_text() == (URDF_DIR / "delta.urdf").read_text()
    assert (tmp_path / "delta.loops.yaml").read_text() == (URDF_DIR / "delta.loops.yaml").read_text()


@pytest.mark.parametrize(("argv", "needle"), [
    (["urdf", "delta", "--L", "0.4"], "applies to p2us only"),
    (["urdf", "p2us", "--forearm", "0.4"], "applies to delta only"),
    (["urdf", "delta", "--alpha", "0", "0", "1"], "alpha: limbs 1 and 2 coincide"),
    (["urdf", "delta", "--cone", "95", "--degrees"], "cone half-angle must be within (0, 90) degrees; got 95.0"),
    (["urdf", "delta", "--forearm", "-1"], "positive length"),
    (["ik", "delta", "--position", "0", "0"], "X Y Z"),
    (["fk", "delta", "--q", "0.1", "0.2"], "3 actuated joints"),
    (["jacobian", "delta", "--position", *HOME, "--mode", "+"], "unknown mode"),
])
def test_bad_input(capsys, tmp_path, argv, needle):
    if argv[0] == "urdf":
        argv = [*argv, "-o", str(tmp_path / "x.urdf")]
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and err.count("\n") == 1 and needle in err, (argv, err)
    assert not list(tmp_path.iterdir())  # nothing half-written
