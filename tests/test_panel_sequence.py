"""The panel sequencer's decisions on refused views and the press depth (PanelOperation fed
with chosen estimates, without a camera or a station: the arm stands at its start)."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from guidedarm.diagrams.tasks.panel_operation.builder import MakeCameraArmKinematics
from guidedarm.diagrams.tasks.panel_operation.run import PreparePanelOperation
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.markers.marker_pose_estimator_math import MarkerPoseEstimate, SwitchSpec
from guidedarm.systems.panel.panel_operation import PanelOperation
from guidedarm.systems.panel.panel_operation_math import PressDepth

REFUSED = "the corners ask for k1 = 0.031 +- 0.002, the camera file has 0.000"


@pytest.fixture(scope="module")
def cell():
    _, scenario, _ = LoadScenario("panel_operation", ["operation.motion=joint_trajectory"])
    prepared = PreparePanelOperation(scenario)
    kinematics = MakeCameraArmKinematics(
        prepared.station, scenario.arm, scenario.camera, scenario.tip_frame
    )
    return scenario, prepared, kinematics


def _Sequence(cell, accepted: set[str], depth_std_mm: float = 0.0):
    """Runs the sequencer with the arm at its start: the views at the points in `accepted`
    (and the start's) see the panel where it is, every other view is refused by the
    camera-model check (a pose with its reason, not valid). Returns the final state."""
    scenario, prepared, kinematics = cell
    sequencer = PanelOperation(
        kinematics, prepared.panel, prepared.panel.switches[1], scenario.operation
    )
    builder = DiagramBuilder()
    builder.AddSystem(sequencer)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = sequencer.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    q = prepared.q_start
    sequencer.GetInputPort("arm_state").FixValue(context, np.concatenate([q, 0 * q]))
    X_CP = kinematics.X_WC(q).inverse() @ prepared.cell.X_WP
    seen = MarkerPoseEstimate(X_CP, [7, 42], 0.1, True, [0.05, 0.05, depth_std_mm], [0.1] * 3)
    refused = MarkerPoseEstimate(X_CP, [7, 42], 1.2, False, why_invalid=REFUSED)
    port = sequencer.GetInputPort("marker_estimate")
    port.FixValue(context, seen)
    simulator.Initialize()
    state = sequencer.GetSequencerState(context)
    while not state.done and simulator.get_context().get_time() < 60.0:
        step = sequencer.steps[state.step]
        view = seen if step.label in accepted | {"start"} else refused
        port.FixValue(context, view)
        simulator.AdvanceTo(simulator.get_context().get_time() + 0.01)
        state = sequencer.GetSequencerState(context)
    return state


def test_refused_close_views_never_lead_to_a_press_from_the_far_estimate(cell):
    """The base view and both retakes refused: the sequence stops before moving towards
    the switch, naming why, instead of pressing with the start's estimate."""
    state = _Sequence(cell, accepted=set())
    points = [m["point"] for m in state.measurements]
    assert points == ["start", "base", "retake_1", "retake_2"]
    assert state.failure.startswith("the estimator refused every view from the base point")
    assert "not aimed with the start's far estimate" in state.failure and REFUSED in state.failure
    assert "measure_switch_point" not in state.q_at and state.press_depth_m is None
    assert not any(m.get("used_last_valid_estimate") for m in state.measurements)


def test_a_refused_base_view_is_taken_again_from_farther_away(cell):
    """The base view refused, the first retake accepted: the second retake is skipped and
    the switch is pressed; the last estimate's depth uncertainty (2 mm standard deviation)
    deepens the press beyond the switch's full travel, to on-travel + 3 sigma."""
    state = _Sequence(cell, accepted={"retake_1", "switch_point"}, depth_std_mm=2.0)
    assert state.failure is None and state.done
    points = [m["point"] for m in state.measurements]
    assert points == ["start", "base", "retake_1", "switch_point"]
    assert state.measurements[1]["why_invalid"] == REFUSED
    assert state.press_depth_m == pytest.approx(0.004 + 3 * 0.002)
    assert {"press", "end"} <= set(state.q_at)


def test_press_depth_is_the_switch_travel_unless_the_estimate_is_less_certain():
    switch = SwitchSpec(name="s", travel_m=0.008, on_travel_m=0.004)
    assert PressDepth(switch, 0.0) == 0.008
    assert PressDepth(switch, 0.001) == 0.008  # 3 sigma within the 4 mm margin
    assert PressDepth(switch, 0.002) == pytest.approx(0.010)
