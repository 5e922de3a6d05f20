"""Reach and clearance checked before a path-following run: a hose beyond the arm's reach,
or nearer a workspace wall than the ToF tool's clearance, is refused in one line naming the
point; the reach bound holds in every configuration."""

from __future__ import annotations

import numpy as np
import pytest

from guidedarm.diagrams.station.station_plant import GetArmInstance
from guidedarm.diagrams.tasks.path_following.setup import MakeSetup
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.path_following.hose_reach import (
    CalcArmReach,
    LowestToolPoint,
    ToolClearance,
    ToolPoints,
)
from guidedarm.systems.plant_frames import GetScopedFrame


@pytest.fixture(scope="module")
def mz04d_setup():
    _, scenario, _ = LoadScenario("path_following", [])
    return MakeSetup(scenario)


def test_the_reach_bound_is_the_catalogue_reach(mz04d_setup):
    plant = mz04d_setup.solver.plant
    arm = GetArmInstance(plant, "mz04d")
    flange = plant.GetJointByName("joint6", arm).frame_on_child()
    # Nachi's catalogue: 541 mm from the J2 axis to the wrist centre; the flange 72 mm on.
    reach = CalcArmReach(plant, arm, flange, np.zeros(3)).reach
    assert reach == pytest.approx(0.5411 + 0.072, abs=1e-4)


def test_no_configuration_takes_the_tool_centre_beyond_the_reach(mz04d_setup):
    solver = mz04d_setup.solver
    plant = solver.plant
    reach = CalcArmReach(plant, GetArmInstance(plant, "mz04d"), solver.frame, solver.p_FQ)
    context = plant.CreateDefaultContext()
    lower, upper = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
    rng = np.random.default_rng(0)
    distances = []
    for _ in range(300):
        plant.SetPositions(context, rng.uniform(lower, upper))
        p_WO = solver.frame.CalcPoseInWorld(context).multiply(solver.p_FQ)
        distances.append(np.linalg.norm(p_WO - reach.p_WS))
    assert max(distances) <= reach.reach
    assert max(distances) > 0.9 * reach.reach  # a bound, not a guess far above


def test_the_tool_clearance_is_its_farthest_sensor(mz04d_setup):
    plant = mz04d_setup.solver.plant
    tool = GetScopedFrame(plant, "tof_tool::tof_tool", "tool")
    # The sensors sit 55 mm out on two arms, 22 mm apart along them.
    assert ToolClearance(plant, tool) == pytest.approx(np.hypot(0.055, 0.022), abs=1e-9)


def _StraightHose(path, start, end):
    points = np.linspace(start, end, 40)
    path.write_text("x,y,z\n" + "".join(f"{x:.4f},{y:.4f},{z:.4f}\n" for x, y, z in points))
    return path


@pytest.mark.parametrize(
    "end, extra, message",
    [
        (
            (0.545, 0.1, 0.1),
            [],
            "hose point 39 [0.545, 0.1, 0.1] (m, base frame) is 5 mm from the workspace's x "
            "upper wall (0.55 m); the ToF tool needs 59 mm of clearance",
        ),
        (
            (0.90, 0.1, 0.1),
            ["--set", "workspace.x=[-0.55, 1.2]"],
            "hose point 39 [0.9, 0.1, 0.1] (m, base frame) is 0.937 m from mz04d's shoulder, "
            "beyond its reach of 0.873 m to the tool centre",
        ),
    ],
)
def test_a_hose_the_arm_cannot_follow_is_refused_before_any_motion(
    run_cli, tmp_path, end, extra, message
):
    hose = _StraightHose(tmp_path / "hose.csv", (0.30, 0.1, 0.1), end)
    code, _, err = run_cli(
        "run", "path_following", "--path-csv", hose, *extra, "--out", tmp_path / "run"
    )
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "run" / "summary.json").exists()


def test_the_rolled_tool_lifts_both_arms_above_the_hose(mz04d_setup):
    """ToolPoints: the tool's bodies and the corners of its collision boxes. Unrolled, the
    side arm's end hangs 34 mm below the hose's centre; rolled -45 deg, the lowest parts
    are sensor 3's and sensor 4's boards, (0.055 - 0.032) / sqrt(2) = 16.3 mm above it."""
    solver = mz04d_setup.solver
    tool = GetScopedFrame(solver.plant, "tof_tool::tof_tool", "tool")
    points = ToolPoints(solver.plant, solver.context, tool)
    bodies = points[np.linalg.norm(points, axis=1) > 1e-9]  # O itself holds no body
    flat = np.array([[0.3, y, 0.1] for y in np.linspace(-0.05, 0.05, 11)])
    for roll_deg, lowest in ((0.0, -0.034), (-45.0, 0.023 / np.sqrt(2))):
        _, z = LowestToolPoint(flat, bodies, np.radians(roll_deg))
        assert z - 0.1 == pytest.approx(lowest, abs=1e-9)
    # Rolled the other way the side arm swings down instead.
    assert LowestToolPoint(flat, bodies, np.radians(45.0))[1] - 0.1 < -0.07
