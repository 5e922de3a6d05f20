"""Path following on another arm: the UR10e of `ur10e_path_following` holding the ToF tool
follows a hose 0.62-0.68 m from its base, beyond the Nachi cell's walls, from the scenario
file; hose CSVs and walls are in the arm's base frame wherever that base stands."""

import json

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.parsing import LoadModelDirectivesFromString

from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.station.kinematic_station import MakeKinematicStation
from guidedarm.diagrams.tasks.path_following.setup import MakeSetup
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.scene.hose_geometry import ReadCenterline, WriteCenterline

SCENARIO = "ur10e_path_following"


@pytest.mark.slow
def test_the_ur10e_follows_a_hose_beyond_the_nachi_cell(tmp_path):
    task, scenario, _ = LoadScenario(SCENARIO, [])
    hose = ReadCenterline(scenario.path)
    reach = np.hypot(hose[:, 0], hose[:, 1])
    assert reach.min() >= 0.6 and reach.max() <= 0.7 and reach.max() > 0.55 + 0.1
    summary = task.run(scenario, RunContext(out_dir=tmp_path, quiet=True))
    assert summary["success"], summary["failure"]
    assert summary["executor"] == "station"
    assert summary["coverage"] >= 0.95
    assert summary["collisions"] == 0
    # Measured (grid, noise seed 0): tracking 4.83 / 13.08 mm, detected 3.76 / 11.18 mm.
    assert summary["tracking_error_max_mm"] <= 25.0
    assert summary["detected_path_error_max_mm"] <= 16.0


def test_a_hose_outside_the_workspace_is_refused(run_cli, tmp_path):
    """The same hose within the paper's walls (x, y in [-0.55, 0.55]): one line naming
    `workspace`, before any run."""
    code, _, err = run_cli(
        "run",
        SCENARIO,
        "--out",
        tmp_path,
        "--set",
        "workspace.x=[-0.55, 0.55]",
        "--set",
        "workspace.y=[-0.55, 0.55]",
    )
    assert code == 2
    assert len(err.strip().splitlines()) == 1
    assert "is outside the workspace (x [-0.55, 0.55], y [-0.55, 0.55]" in err
    assert "widen `workspace`" in err


def test_path_csv_and_set_work_on_the_ur10e(run_cli, tmp_path):
    """The first 0.3 m of the far hose as a CSV, the ranging estimator, kinematically."""
    csv = tmp_path / "far.csv"
    WriteCenterline(ReadCenterline("ur10e_far_hose")[:60], csv)
    code, _, err = run_cli(
        "run",
        SCENARIO,
        "--out",
        tmp_path / "out",
        "--path-csv",
        csv,
        "--set",
        "estimator=ranging",
        "--set",
        "executor=kinematic",
    )
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert code == 0, err + str(summary["failure"])
    assert summary["estimator"] == "ranging" and summary["executor"] == "kinematic"
    assert summary["coverage"] >= 0.95 and summary["collisions"] == 0
    assert summary["tracking_error_max_mm"] <= 12.0


_SHIFTED_UR10E = """
directives:
- add_model:
    name: ur10e
    file: package://guidedarm/ur10e/ur10e.urdf
- add_weld:
    parent: world
    child: ur10e::base_link
    X_PC:
      translation: [0.4, -0.3, 0.05]
      rotation: !Rpy { deg: [0.0, 0.0, 30.0] }
- add_model:
    name: worktable
    file: package://guidedarm/scenes/worktable.sdf
- add_weld:
    parent: world
    child: worktable::table
- add_directives:
    file: package://guidedarm/directives/tof_gripper.dmd.yaml
- add_weld:
    parent: ur10e::tool0
    child: gripper::gripper_base
"""


def test_hose_csvs_are_in_the_base_frame_wherever_the_base_stands(tmp_path):
    """The UR10e moved 0.4 m, -0.3 m, 0.05 m and turned 30 deg in the world: the hose, its
    geometry and the start pose move with its base, and at the start the centre sensors
    see the hose's surface 45 mm away (55 mm to the tool centre, less the 10 mm radius)."""
    _, scenario, _ = LoadScenario(SCENARIO, [])
    scenario.station.directives = LoadModelDirectivesFromString(_SHIFTED_UR10E).directives
    setup = MakeSetup(scenario, tmp_path)
    X_WB = RigidTransform(RollPitchYaw(0, 0, np.pi), [0, 0, 0])  # ur10e::base in base_link
    X_WB = RigidTransform(RollPitchYaw(0, 0, np.radians(30)), [0.4, -0.3, 0.05]) @ X_WB
    np.testing.assert_allclose(setup.X_WB.GetAsMatrix4(), X_WB.GetAsMatrix4(), atol=1e-12)
    np.testing.assert_allclose(setup.centerline, X_WB.multiply(setup.centerline_B.T).T)
    np.testing.assert_allclose(setup.centerline_B, ReadCenterline("ur10e_far_hose"))
    station = MakeKinematicStation(setup.station)
    context = station.CreateDefaultContext()
    station.GetInputPort("ur10e.position_commanded").FixValue(context, setup.q_start)
    sensor = station.GetSubsystemByName("tof.sensor")
    ranges = sensor.TrueRanges(sensor.GetMyContextFromRoot(context))
    np.testing.assert_allclose(ranges[[1, 4]], 0.045, atol=0.002)
    X_WT = setup.mount.ToolPose(setup.solver.ForwardKinematics(setup.q_start))
    np.testing.assert_allclose(X_WT.translation(), setup.centerline[0], atol=0.0006)
