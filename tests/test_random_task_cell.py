"""The cell in the planners' random comparison: tasks drawn clear of it, a colliding task
refused, contacts of a commanded motion, and the table's cell columns on one task."""

import numpy as np
import pytest

from guidedarm.diagrams.cli.command_compare_planners import LoadWaypointsScenario
from guidedarm.diagrams.cli.main import main
from guidedarm.diagrams.studies.random_task_cell import CellFigures, RandomTaskCell
from guidedarm.diagrams.tasks.waypoints import MakePlannerSetup
from guidedarm.systems.planning.planner_baselines import JointTrajectory
from guidedarm.systems.planning.random_waypoint_tasks import MakeRandomWaypointTasks

# The ToF tool 85 mm into the MZ04D's base (docs/planner.md, the cell check before motion).
MZ04D_COLLIDING = np.array([0.0, 0.0708, -0.25, 0.0, -1.5708, 0.0])


@pytest.fixture(scope="module")
def mz04d_cell():
    scenario = LoadWaypointsScenario("mz04d_waypoints", [])
    return RandomTaskCell(scenario, MakePlannerSetup(scenario))


def _Line(q_from: np.ndarray, q_to: np.ndarray, seconds: float) -> JointTrajectory:
    """A straight joint-space line sampled at the planner period (2 ms)."""
    times = np.arange(0.0, seconds + 1e-9, 0.002)
    s = times[:, None] / seconds
    q = q_from + s * (q_to - q_from)
    velocity = np.broadcast_to((q_to - q_from) / seconds, q.shape)
    return JointTrajectory(times, q, velocity, np.zeros_like(q))


def test_tasks_drawn_clear_of_the_cell_and_the_same_tasks_without_it(mz04d_cell):
    kinematics = mz04d_cell.setup.planning.kinematics
    plain = MakeRandomWaypointTasks(kinematics, 3, 5, "near_limit")
    anywhere = MakeRandomWaypointTasks(kinematics, 3, 5, "near_limit", lambda q: True)
    for a, b in zip(plain, anywhere, strict=True):
        np.testing.assert_array_equal(a.q0, b.q0)
        np.testing.assert_array_equal(a.joint_waypoints, b.joint_waypoints)
    clear = MakeRandomWaypointTasks(kinematics, 3, 5, "large", mz04d_cell.Clear)
    for task in clear:
        assert all(mz04d_cell.Clear(q) for q in [task.q0, *task.joint_waypoints])


def test_a_colliding_start_is_refused_and_a_motion_through_the_cell_touches_it(mz04d_cell):
    setup = mz04d_cell.setup
    assert mz04d_cell.Clear(setup.q0) and not mz04d_cell.Clear(MZ04D_COLLIDING)
    task = MakeRandomWaypointTasks(setup.planning.kinematics, 1, 0, "large", mz04d_cell.Clear)[0]
    assert not mz04d_cell.Refused(task)
    task.q0 = MZ04D_COLLIDING
    assert mz04d_cell.Refused(task)
    # home -> the colliding pose and back: it touches; home -> home + 0.1 rad on J1: it does not
    through = _Line(setup.q0, MZ04D_COLLIDING, 1.0)
    assert mz04d_cell.Touches(through)
    clear = _Line(setup.q0, setup.q0 + [0.1, 0, 0, 0, 0, 0], 1.0)
    assert not mz04d_cell.Touches(clear)
    # the columns: the refused task is left out of the others; a None trajectory counts nothing
    tasks = [task, task, task]
    figures = CellFigures(mz04d_cell, tasks, [True, False, False], [through, through, None])
    assert figures["refused"] == 1 and figures["contacts"] == 1 and figures["within_1mm"] == 0


def test_compare_planners_near_limit_table_has_the_cell_columns(capsys):
    """One near-limit rover arm task drawn clear of the cell: the planner is not refused,
    ends within 1 mm without touching the cell, its oscillation rate below the watch's
    bound (5 /s)."""
    args = ["compare-planners", "--random", "1", "--arm", "rover_arm", "--kind", "near_limit"]
    assert main(args) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[1].endswith("refused  in 1 mm  contacts  osc max")
    rows = {line[:22].strip(): line[22:].split() for line in lines[2:]}
    refused, within, contacts, oscillation = rows["acceleration planner"][-4:]
    assert (refused, within, contacts) == ("0", "1", "0")
    assert 0.0 <= float(oscillation) < 5.0
