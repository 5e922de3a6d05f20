"""PanelOperation: press a switch on a marker panel with an eye-in-hand camera, the sequence
of Annusewicz-Mistal et al., "Autonomous Manipulator of a Mobile Robot Based on a Vision
System" (section 2.4); its mathematics in panel_operation_math.py.

The sequence, as in the paper: from a start with at least one marker in view, measure the
panel pose; move to the base point in front of the panel (camera `base_distance_m` from
the panel plane, looking straight at the middle of the markers) and measure again; move to
the last measurement point (gripper tip `measure_standoff_m` in front of the chosen switch,
where the markers are still in view) and measure again; move to the approach point (tip
`approach_standoff_m` in front of the cap, on the switch's axis), press straight along the
axis (PressDepth: the switch's full travel past the cap's rest face, deeper when the last
estimate's depth uncertainty asks for it), hold, return to the approach point, retract.
Images are analysed only while the arm stands still (commanded move finished, settle time
over, every joint slower than `stationary_speed`), so moves between points need no speed
limit for the camera's sake.

Each measurement replaces the panel estimate X_WP = X_WC(q) X_CP, with X_WC(q) the camera
pose from the arm's kinematics at the measured joint positions. When no marker is seen (or
the estimator refuses the pose) at a later point, `on_marker_loss` decides: "abort" stops
the arm where it is and reports the failure, "continue" keeps the last valid X_WP (the
arm's own kinematics carry the rest). The start's estimate alone never aims the press: it
was taken far away and in another arm configuration, where the arm's joint offsets do not
cancel. So with "continue" a refused base view is taken again from `retake_distances_m`,
and when none is accepted the sequence stops with a failure naming why.

Moves (`motion`): "joint_trajectory", minimum-jerk joint-space segments between
inverse-kinematics solutions (Drake InverseKinematics, exact tip pose), timed so no joint
exceeds `max_joint_speed`; or "planner", each move a PlannerTask for the acceleration-level
planner (Pająk's, systems/planning/acceleration_planner.py), which ends it when its end
condition holds and which streams the commands itself. The press and its return are moves
of `approach_standoff_m` plus the depth along the switch's axis: short enough that either
motion keeps the tip on the axis (the planner's path on a long move bends sideways by up
to a sixth of its length).
Units: m, rad, s. Frames: W the controller plant's world, P panel, C camera, T gripper tip.
"""

import copy
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import BasicVector, Context, LeafSystem, State

from guidedarm.systems.config_checks import CheckFields, CheckInstance, FieldError
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.marker_pose_estimator_math import (
    MarkerPoseEstimate,
    PanelSpec,
    SwitchSpec,
)
from guidedarm.systems.panel.panel_operation_math import (
    CameraArmKinematics,
    MinimumJerk,
    PanelOperationConfig,
    PanelTargets,
    PlannerFrames,
    PressDepth,
)
from guidedarm.systems.planning.acceleration_planner_math import PlannerTask


@dataclass
class Step:
    """One step: `kind` is measure | move | hold | done; `label` names it in the logs.
    X_PT: a move's tip target (None: the press, whose depth the last estimate sets);
    retake: a step of the base view's retakes, skipped once a close view was accepted."""

    kind: str
    label: str
    X_PT: RigidTransform | None = None
    duration_s: float = 0.0
    retake: bool = False


@dataclass
class SequencerState:
    """The sequencer's abstract state: current step, current move, estimate and logs."""

    step: int = 0
    step_start_s: float = 0.0
    q_from: np.ndarray = field(default_factory=lambda: np.zeros(0))
    q_to: np.ndarray = field(default_factory=lambda: np.zeros(0))
    move_start_s: float = 0.0
    move_end_s: float = 0.0
    task: PlannerTask = field(default_factory=PlannerTask)
    X_WP: RigidTransform | None = None
    measurements: list[dict] = field(default_factory=list)
    q_at: dict[str, list[float]] = field(default_factory=dict)
    t_at: dict[str, float] = field(default_factory=dict)
    failure: str | None = None
    done: bool = False
    close_estimate: bool = False
    depth_std_m: float = 0.0
    press_depth_m: float | None = None
    refused: list[str] = field(default_factory=list)


class PanelOperation(LeafSystem):
    """The paper's panel-operation sequencer for one arm.

    Input ports: `arm_state` ([q; v] of the arm, rad, rad/s), `marker_estimate`
    (MarkerPoseEstimate of the camera; evaluated only when measuring); with motion
    "planner" also `move_done` (the planner's `done`, 1.0 when the current task ended).
    Output port: `position_commanded` (rad; motion "joint_trajectory"), or `planner_task`
    (PlannerTask; motion "planner", needs `planner_frames`). The state (SequencerState) is
    read with GetSequencerState for logs and ground-truth evaluation.
    Output port `X_WP_estimated`: the panel pose X_WP of the latest valid measurement
    (identity before the first), e.g. for diagrams/overlays.
    """

    def __init__(
        self,
        kinematics: CameraArmKinematics,
        panel: PanelSpec,
        switch: SwitchSpec,
        config: PanelOperationConfig,
        planner_frames: PlannerFrames | None = None,
    ) -> None:
        super().__init__()
        CheckInstance("kinematics", kinematics, CameraArmKinematics)
        CheckInstance("panel", panel, PanelSpec)
        CheckFields(panel)
        if not panel.markers:
            raise FieldError("panel", "the panel has no markers")
        CheckInstance("switch", switch, SwitchSpec)
        switch.Validate()
        CheckInstance("config", config, PanelOperationConfig)
        config.Validate()
        CheckInstance("planner_frames", planner_frames, (PlannerFrames, type(None)))
        if config.motion == "planner" and planner_frames is None:
            raise ConfigurationError('motion "planner" needs the planner\'s frames')
        self._planner_frames = planner_frames if config.motion == "planner" else None
        self._kinematics = kinematics
        self._config = config
        self.targets = PanelTargets(panel, switch, config, kinematics.X_CT)
        targets = self.targets
        self._switch = switch
        approach = targets.at_switch(config.approach_standoff_m)
        retakes = []
        for i, distance in enumerate(config.retake_distances_m, start=1):
            retakes += [
                Step("move", f"retake_{i}", targets.base(distance), retake=True),
                Step("measure", f"retake_{i}", retake=True),
            ]
        self.steps = [
            Step("measure", "start"),
            Step("move", "base", targets.base()),
            Step("measure", "base"),
            *retakes,
            Step("move", "switch_point", targets.at_switch(config.measure_standoff_m)),
            Step("measure", "switch_point"),
            Step("move", "approach", approach),
            Step("move", "press"),
            Step("hold", "press", duration_s=config.press_hold_s),
            Step("move", "release", approach),
            Step("move", "retract", targets.at_switch(config.retract_standoff_m)),
            Step("done", "done"),
        ]
        n = kinematics.plant.num_positions()
        self._n = n
        self._arm_state = self.DeclareVectorInputPort("arm_state", 2 * n)
        self._estimate = self.DeclareAbstractInputPort(
            "marker_estimate", AbstractValue.Make(MarkerPoseEstimate(None, [], -1.0, False))
        )
        self._state_index = self.DeclareAbstractState(AbstractValue.Make(SequencerState()))
        self.DeclareInitializationUnrestrictedUpdateEvent(self._Initialize)
        self.DeclarePeriodicUnrestrictedUpdateEvent(config.update_period_s, 0.0, self._Update)
        state_ticket = self.abstract_state_ticket(self._state_index)
        self._move_done = None
        if self._planner_frames is None:
            self.DeclareVectorOutputPort(
                "position_commanded",
                n,
                self.CalcPositionCommanded,
                prerequisites_of_calc={state_ticket, self.time_ticket()},
            )
        else:
            self._move_done = self.DeclareVectorInputPort("move_done", 1)
            self.DeclareAbstractOutputPort(
                "planner_task",
                lambda: AbstractValue.Make(PlannerTask()),
                lambda context, value: value.set_value(self.GetSequencerState(context).task),
                prerequisites_of_calc={state_ticket},
            )
        self.DeclareAbstractOutputPort(
            "X_WP_estimated",
            lambda: AbstractValue.Make(RigidTransform()),
            self.CalcX_WP_estimated,
            prerequisites_of_calc={state_ticket},
        )

    def CalcX_WP_estimated(self, context: Context, value: AbstractValue) -> None:
        """The panel pose X_WP of the latest valid measurement (identity before one)."""
        X_WP = self.GetSequencerState(context).X_WP
        value.set_value(X_WP if X_WP is not None else RigidTransform())

    def GetSequencerState(self, context: Context) -> SequencerState:
        return context.get_abstract_state(self._state_index).get_value()

    def CalcPositionCommanded(self, context: Context, output: BasicVector) -> None:
        s = self.GetSequencerState(context)
        if s.q_to.size == 0:
            output.SetFromVector(self._arm_state.Eval(context)[: self._n])
            return
        duration = s.move_end_s - s.move_start_s
        tau = (context.get_time() - s.move_start_s) / max(duration, 1e-9)
        output.SetFromVector(s.q_from + (s.q_to - s.q_from) * MinimumJerk(tau))

    def _Initialize(self, context: Context, state: State) -> None:
        q = np.array(self._arm_state.Eval(context)[: self._n])
        s = SequencerState(q_from=q, q_to=q.copy(), step_start_s=context.get_time())
        state.get_mutable_abstract_state(self._state_index).set_value(s)

    def _Update(self, context: Context, state: State) -> None:
        s = copy.deepcopy(self.GetSequencerState(context))
        if s.done:
            return
        t = context.get_time()
        x = self._arm_state.Eval(context)
        q, v = np.asarray(x[: self._n]), np.asarray(x[self._n :])
        step = self.steps[s.step]
        if s.move_end_s == np.inf and self._move_done.Eval(context)[0] > 0.5:
            s.move_end_s = t
        moved = t >= s.move_end_s
        # a step after a move counts its settle or hold time from the move's end
        since = max(s.step_start_s, s.move_end_s)
        still = moved and t >= since + self._config.settle_time_s
        still = still and np.max(np.abs(v)) < self._config.stationary_speed
        advance = False
        if step.kind == "measure" and still:
            self._Measure(context, s, step.label, q, t)
            advance = s.failure is None
        elif step.kind == "move" and moved:
            advance = self._StartMove(s, step, q, t)
        elif step.kind == "hold" and moved and t >= since + step.duration_s:
            s.q_at[step.label], s.t_at[step.label] = q.tolist(), t
            advance = True
        elif step.kind == "done" and moved:
            s.q_at["end"], s.t_at["end"] = q.tolist(), t
            s.done = True
        if s.failure is not None:
            s.done = True
            s.q_from, s.q_to, s.move_end_s = q.copy(), q.copy(), min(s.move_end_s, t)
        if advance:
            s.step += 1
            while self.steps[s.step].retake and s.close_estimate:
                s.step += 1
            s.step_start_s = t
        state.get_mutable_abstract_state(self._state_index).set_value(s)

    def _Measure(self, context, s: SequencerState, label: str, q, t: float) -> None:
        estimate: MarkerPoseEstimate = self._estimate.Eval(context)
        record = {
            "point": label,
            "t_s": round(t, 4),
            "valid": bool(estimate.valid),
            "ids": list(estimate.ids),
            "reprojection_error_px": round(float(estimate.reprojection_error_px), 4),
        }
        s.q_at[f"measure_{label}"], s.t_at[f"measure_{label}"] = q.tolist(), t
        if estimate.valid:
            s.X_WP = self._kinematics.X_WC(q) @ estimate.X_CP
            s.close_estimate = label != "start"
            s.depth_std_m = 1e-3 * estimate.std_mm[2] if estimate.std_mm else 0.0
            p_CP = estimate.X_CP.translation()
            record["distance_mm"] = round(1000 * np.linalg.norm(p_CP), 2)
            record["p_CP_mm"] = [round(1000 * v, 3) for v in p_CP]
            s.measurements.append(record)
            return
        if estimate.why_invalid:
            record["why_invalid"] = estimate.why_invalid
            s.refused.append(f"{label}: {estimate.why_invalid}")
        if s.X_WP is None:
            s.failure = f"no marker of the panel in view at the '{label}' point"
        elif self._config.on_marker_loss == "abort":
            s.failure = (
                f"markers lost at the '{label}' point: aborted before pressing "
                "(on_marker_loss: abort)"
            )
        elif s.close_estimate:
            record["used_last_valid_estimate"] = True
        s.measurements.append(record)

    def _StartMove(self, s: SequencerState, step: Step, q: np.ndarray, t: float) -> bool:
        if not (s.close_estimate or step.label == "base" or step.retake):
            s.failure = (
                "the estimator refused every view from the base point and its retakes ("
                + "; ".join(s.refused or ["no marker in view"])
                + "): the press is not aimed with the start's far estimate"
            )
            return False
        s.move_start_s = t
        X_PT = step.X_PT
        if X_PT is None:
            s.press_depth_m = PressDepth(self._switch, s.depth_std_m)
            X_PT = self.targets.at_switch(-s.press_depth_m)
        if self._planner_frames is not None:
            row = self._planner_frames.TaskRow(s.X_WP @ X_PT)
            s.task = PlannerTask(s.task.sequence + 1, row[np.newaxis])
            s.move_end_s = np.inf  # until the planner says the task ended
            return True
        q_start = s.q_to if s.q_to.size else q
        q_goal = self._kinematics.SolveTip(s.X_WP @ X_PT, q_start)
        if q_goal is None:
            s.failure = f"no inverse-kinematics solution for the '{step.label}' pose"
            return False
        largest = float(np.max(np.abs(q_goal - q_start)))
        s.q_from, s.q_to = q_start.copy(), q_goal
        s.move_end_s = t + max(1.875 * largest / self._config.max_joint_speed, 0.2)
        return True
