"""Summary metrics and plots of one `panel_operation` run (ground truth from the simulation;
frames as in systems/markers/marker_pose_estimator_math.py: W world, P panel, C camera,
T gripper tip)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex
from pydrake.systems.framework import Context
from pydrake.systems.primitives import VectorLogSink

from guidedarm.diagrams.plots import PlotJointSeries
from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.tasks.common.cell_collisions import CellCollisions
from guidedarm.diagrams.tasks.common.planner_builder import SymmetricLimit
from guidedarm.diagrams.tasks.common.trajectory_csv import (
    JOINT_MOTION_METRICS,
    JointMotionMetrics,
    TrajectoryLogs,
    WriteTrajectoryCsv,
)
from guidedarm.diagrams.tasks.panel_operation.scenario import PanelOperationScenario
from guidedarm.systems.markers.marker_pose_estimator_math import PanelSpec
from guidedarm.systems.panel.panel_operation import PanelOperation, SequencerState
from guidedarm.systems.panel.panel_operation_math import CameraArmKinematics, PressDepth


class OperationRun(Protocol):
    """What the report reads of a built run (PanelOperationRun): the scenario and the
    run's outputs, the true plant and its panel and arm instances, the sequencer, the
    controller's kinematics, the panel's pose X_WP, and the logs the run added."""

    scenario: PanelOperationScenario
    context: RunContext
    plant: MultibodyPlant
    panel: PanelSpec
    panel_instance: ModelInstanceIndex
    arm_instance: ModelInstanceIndex
    sequencer: PanelOperation
    kinematics: CameraArmKinematics
    X_WP: RigidTransform
    joint_log: VectorLogSink
    true_log: VectorLogSink
    trajectory_logs: TrajectoryLogs
    collisions: CellCollisions


def PlotPanelOperation(run: OperationRun, state: SequencerState, context: Context) -> None:
    """joints.png (measured joints) and tip_distance.png (tip to panel plane, with the
    instants at which images were analysed)."""
    import matplotlib.pyplot as plt  # after guidedarm.diagrams.plots chose Agg

    log = run.joint_log.FindLog(context)
    times, q = log.sample_times(), log.data()
    if times.size < 2:
        return
    run.context.save_figure(PlotJointSeries(times, {"measured": q}, "q (rad)"), "joints")
    X_PW = run.X_WP.inverse()
    depth = [
        1e3 * (X_PW @ run.kinematics.X_WT(q[:, i])).translation()[2] for i in range(times.size)
    ]
    figure, axes = plt.subplots(figsize=(7, 3))
    axes.plot(times, depth, label="tip in front of the panel plane")
    for record in state.measurements:
        axes.axvline(record["t_s"], color="g" if record["valid"] else "r", linestyle="--")
    axes.set_xlabel("t (s)")
    axes.set_ylabel("z of the tip in P (mm)")
    axes.set_title("panel operation: dashed = image analysed (green valid, red lost)")
    axes.grid(True, alpha=0.3)
    run.context.save_figure(figure, "tip_distance")


# The numbers of PanelOperationMetrics's summary (TaskDefinition.metrics); a measurement
# record's distance_mm, p_CP_mm and estimate_error_mm exist when its estimate was valid.
PANEL_OPERATION_METRICS = {
    "switch": ("index", "the switch to press (1-based, the panel file's order)"),
    "switch_pressed": (
        "index",
        "the switch whose cap travelled past its on-travel (a list when several, null when none)",
    ),
    "switch_travel_mm.#": ("mm", "each switch cap's travel into the panel at the end"),
    "base_position_error_mm": (
        "mm",
        "distance of the camera, at the base point, from where it should be (truth)",
    ),
    "base_camera_distance_mm": (
        "mm",
        "the camera's true distance from the panel at the base point",
    ),
    "press_error_mm.x": ("mm", "|error| of the tip at the press along P's x axis (truth)"),
    "press_error_mm.y": ("mm", "|error| of the tip at the press along P's y axis"),
    "press_error_mm.z": ("mm", "|error| of the tip at the press along P's z axis (depth)"),
    "press_tip_W_mm.#": ("mm", "the tip's position at the press, world frame"),
    "press_target_W_mm.#": ("mm", "the press target's true position, world frame"),
    "true_base_position_error_mm": (
        "mm",
        "base_position_error_mm of the true camera (the true arm and camera mount)",
    ),
    "true_press_error_mm.x": ("mm", "press_error_mm.x of the true tip (the true arm)"),
    "true_press_error_mm.y": ("mm", "press_error_mm.y of the true tip"),
    "true_press_error_mm.z": ("mm", "press_error_mm.z of the true tip"),
    "true_press_tip_W_mm.#": ("mm", "the true tip's position at the press, world frame"),
    "measurements.#.t_s": ("s", "simulated time of each image analysed"),
    "measurements.#.ids.#": ("id", "the marker ids found in that image"),
    "measurements.#.reprojection_error_px": ("px", "its PnP's RMS corner reprojection error"),
    "measurements.#.distance_mm": ("mm", "its estimated camera distance from P (valid only)"),
    "measurements.#.p_CP_mm.#": ("mm", "its estimated position of P in the camera frame C"),
    "measurements.#.estimate_error_mm": (
        "mm",
        "that estimate's distance from P seen from where the controller believes the camera is",
    ),
    "measurements.#.true_estimate_error_mm": (
        "mm",
        "that estimate's distance from P seen from the true camera",
    ),
    "lost_measurements": ("count", "images analysed without a valid marker pose"),
    **JOINT_MOTION_METRICS,
    "sim_time_s": ("s", "simulated time of the run"),
}


def PanelOperationMetrics(
    run: OperationRun,
    state: SequencerState,
    context: Context,
    planner_failure: str | None = None,
) -> dict[str, Any]:
    """The summary metrics of a finished run (see the task's module docstring), from the
    sequencer's state and the simulation's ground truth."""
    scenario = run.scenario
    plant_context = run.plant.GetMyContextFromRoot(context)
    travels = [
        -run.plant.GetJointByName(s.name, run.panel_instance).get_translation(plant_context)
        for s in run.panel.switches
    ]
    pressed = [
        i + 1
        for i, (s, travel) in enumerate(zip(run.panel.switches, travels, strict=True))
        if travel >= s.on_travel_m
    ]
    failure = planner_failure or state.failure
    if failure is None and not state.done:
        failure = f"the sequence did not finish within {scenario.time_limit_s} s"
    if failure is None and pressed != [scenario.switch]:
        failure = f"pressed switches {pressed}, expected [{scenario.switch}]"
    targets = run.sequencer.targets
    X_PW = run.X_WP.inverse()
    base_error = base_distance = true_base_error = None
    if "measure_base" in state.q_at:
        X_PC = X_PW @ run.kinematics.X_WC(np.array(state.q_at["measure_base"]))
        X_PC_target = targets.base() @ run.kinematics.X_CT.inverse()
        base_error = _mm(np.linalg.norm(X_PC.translation() - X_PC_target.translation()))
        base_distance = _mm(X_PC.translation()[2])
        X_PC_true = X_PW @ _TrueArm(run, context, state, "measure_base").X_WC
        true_base_error = _mm(np.linalg.norm(X_PC_true.translation() - X_PC_target.translation()))
    press = {}
    depth = state.press_depth_m
    if depth is None:  # not pressed: the depth of an estimate without uncertainty
        depth = PressDepth(run.panel.switches[scenario.switch - 1], 0.0)
    target = targets.at_switch(-depth).translation()
    target_W = run.X_WP @ targets.at_switch(-depth)
    if "press" in state.q_at:
        believed = run.kinematics.X_WT(np.array(state.q_at["press"]))
        true = _TrueArm(run, context, state, "press").X_WT
        for prefix, X_WT in (("", believed), ("true_", true)):
            p_PT = (X_PW @ X_WT).translation()
            errors = (_mm(abs(e)) for e in p_PT - target)
            press[f"{prefix}press_error_mm"] = dict(zip("xyz", errors, strict=True))
            press[f"{prefix}press_tip_W_mm"] = [_mm(v) for v in X_WT.translation()]
    for record in state.measurements:
        if "p_CP_mm" in record:
            label = f"measure_{record['point']}"
            p_CP_estimated = 1e-3 * np.array(record["p_CP_mm"])
            X_WC = run.kinematics.X_WC(np.array(state.q_at[label]))
            p_CP = (X_WC.inverse() @ run.X_WP).translation()
            record["estimate_error_mm"] = _mm(np.linalg.norm(p_CP_estimated - p_CP))
            X_WC_true = _TrueArm(run, context, state, label).X_WC
            p_CP_true = (X_WC_true.inverse() @ run.X_WP).translation()
            record["true_estimate_error_mm"] = _mm(np.linalg.norm(p_CP_estimated - p_CP_true))
    lost = [m for m in state.measurements if not m["valid"]]
    motion = _WriteTrajectory(run, context)
    return {
        "success": failure is None,
        "switch": scenario.switch,
        "switch_pressed": pressed[0] if len(pressed) == 1 else (pressed or None),
        "switch_travel_mm": [_mm(t) for t in travels],
        "base_position_error_mm": base_error,
        "base_camera_distance_mm": base_distance,
        "press_error_mm": press.get("press_error_mm"),
        "press_tip_W_mm": press.get("press_tip_W_mm"),
        "press_target_W_mm": [_mm(v) for v in target_W.translation()],
        "true_base_position_error_mm": true_base_error,
        "true_press_error_mm": press.get("true_press_error_mm"),
        "true_press_tip_W_mm": press.get("true_press_tip_W_mm"),
        "measurements": state.measurements,
        "lost_measurements": len(lost),
        **motion,
        "marker_loss": scenario.operation.on_marker_loss if lost else None,
        "failure": failure,
        "sim_time_s": round(context.get_time(), 3),
    }


def _WriteTrajectory(run: OperationRun, context: Context) -> dict[str, Any]:
    """Writes the run's trajectory.csv; returns its JointMotionMetrics (the planner's
    acceleration limits as the oscillation measure's scale, whatever the motion) and the
    measured arm's contact episodes with the cell or itself (cell_contacts)."""
    scenario = run.scenario
    period = scenario.station.arms[scenario.arm].control_period
    times, q, qd, qdd, q_meas = run.trajectory_logs.Samples(context, period)
    WriteTrajectoryCsv(run.context, times, q, qd, qdd, q_meas)
    plant, instance = run.plant, run.arm_instance
    limits = (
        plant.GetPositionsFromArray(instance, plant.GetPositionLowerLimits()),
        plant.GetPositionsFromArray(instance, plant.GetPositionUpperLimits()),
    )
    acceleration = SymmetricLimit(
        scenario.planner.max_joint_acceleration, "planner.max_joint_acceleration"
    )
    metrics = JointMotionMetrics(q, qdd, limits, acceleration, period)
    # the measured arm every 20 ms (10 control periods)
    return {**metrics, "cell_contacts": run.collisions.CountContacts(q_meas[::10])}


@dataclass
class _ArmPose:
    """The tip T and camera C of the arm in W (true or believed)."""

    X_WT: RigidTransform
    X_WC: RigidTransform


def _TrueArm(run: OperationRun, context: Context, state: SequencerState, label: str):
    """The true tip and camera poses when the sequencer recorded `label`: the true arm
    joints (the true-state log's sample nearest that instant) through the arm's
    kinematics, the camera moved by its mount error (station.errors)."""
    log = run.true_log.FindLog(context)
    k = int(np.argmin(np.abs(log.sample_times() - state.t_at[label])))
    positions = log.data()[: run.plant.num_positions(), k]
    q = run.plant.GetPositionsFromArray(run.arm_instance, positions)
    camera = run.scenario.station.errors.cameras.get(run.scenario.camera)
    X_CnC = camera.X_mount_error.GetDeterministicValue() if camera else RigidTransform()
    return _ArmPose(run.kinematics.X_WT(q), run.kinematics.X_WC(q) @ X_CnC)


def _mm(value: float) -> float:
    return round(1000.0 * float(value), 3)
