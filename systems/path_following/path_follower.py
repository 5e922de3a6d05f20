"""PathFollower: the step loop of the paper's figure 10 as a LeafSystem.

On a periodic tick it runs a small state machine:
  SENSE  the arm is stopped: read the six ranges (params.readings of them, one per
         reading_period, averaged) and the gripper pose, compute the tool
         pose (23)-(26), estimate the hose point S, and take one step of the paper's
         algorithm (path_following.FollowStep) -> the next gripper pose, a new IK request;
  SOLVE  wait for ToolPoseIk's answer and plan the move; a failure of either while the
         hose is in sight stops the arm and reports the step and why; while lost or
         retrying, the next retry is tried;
  MOVE   a rest-to-rest joint-space move to the IK solution (joint_moves: the tool centre
         cruises at tool_speed, joint speeds and accelerations bounded), then wait until
         the measured joints reach the goal. A retry (path_following's recovery) first
         retraces, in reverse, the poses the tool visited since it last saw the hose (each
         was reached collision-free on the way out), then turns in place: a direct
         joint-space move back could sweep the tool through the hose;
  DONE / FAILED  hold the last goal.
"""

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, NamedTuple

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import BasicVector, Context, EventStatus, LeafSystem, State

from guidedarm.systems.config_checks import POSITIVE, CheckArgument, CheckInstance, CheckVector
from guidedarm.systems.errors import GuidedArmError
from guidedarm.systems.path_following.joint_moves import (
    MotionLimits,
    Move,
    MovePlanner,
    PlanJointMove,
)
from guidedarm.systems.path_following.path_follower_math import (
    RECORD_FIELDS,
    EstimateHose,
    Estimator,
    FollowerConfig,
    FollowerMemory,
    FollowStep,
    GiveUpDirection,
    IsExploring,
    MakeRecord,
    StepResult,
    ToolMount,
)
from guidedarm.systems.tof.detection_grid import DetectionGrid
from guidedarm.systems.tof.known_surfaces import KnownSurfaces
from guidedarm.systems.tof.tof_tool_sensor_math import AverageReadings

SENSE, SOLVE, MOVE, DONE, FAILED = range(5)


class _Visited(NamedTuple):
    """A pose the arm stopped at: joints (rad) and tool centre p_WO (m)."""

    q: np.ndarray
    p_WO: np.ndarray


@dataclass(frozen=True)
class _Loop:
    """The follower's abstract state. trail: the poses since the last one that saw the hose
    (that one first, the current one last).

    Immutable: an update builds a new _Loop with dataclasses.replace and never changes the
    arrays it holds, so the copy Drake makes of the state at every tick can be the object
    itself (a deep copy of the trail and the move cost more than the rest of the tick)."""

    mode: int
    step: int
    q_goal: np.ndarray
    memory: FollowerMemory | None = None
    X_WT_sensed: RigidTransform | None = None
    target: RigidTransform | None = None
    retrace: bool = False
    request: int = 0
    move: Move | None = None
    t0: float = 0.0
    trail: tuple[_Visited, ...] = ()
    samples: tuple[tuple[np.ndarray, np.ndarray], ...] = ()
    sampled_at: float = 0.0
    record: np.ndarray | None = None
    grid: np.ndarray | None = None
    failure: str = ""

    @property
    def stopped(self) -> bool:
        """Whether the run is over (DONE or FAILED)."""
        return self.mode in (DONE, FAILED)

    def __deepcopy__(self, memo: dict) -> "_Loop":
        return self


class PathFollower(LeafSystem):
    """Inputs: `ranges` (6, m), `valid` (6), `X_WF_measured` (RigidTransform of the gripper
    in world W), `position_measured` (n, rad), `ik_status` ([id, success, time]), `q_goal` (n, rad),
    `ik_failure` (str).

    Outputs: `X_WF_desired` (RigidTransform), `request` ([id]), `position_commanded` (n, rad),
    `step_record` (RECORD_FIELDS of the latest step), `detections` and `detection_errors`
    (the 3 x 3 grid of the latest reading, row-major), `mode` ([mode, step]), `failure`.
    """

    def __init__(
        self,
        params: FollowerConfig,
        estimator: Estimator,
        mount: ToolMount,
        grid: DetectionGrid,
        q_initial: np.ndarray,
        motion: MotionLimits,
        period: float,
        plan_move: MovePlanner | None = None,
        tool_roll: float = 0.0,
        known_surfaces: KnownSurfaces | None = None,
    ) -> None:
        """params: the follower's parameters, resolved here for `estimator` (`grid` or
        `ranging`, the hose estimator of every reading). plan_move: how moves are made
        (default: joint_moves.PlanJointMove with `motion`; e.g. planner_moves.PlannerMoves);
        motion's settle limits apply either way. tool_roll: the tool's roll about x_T at
        every step (rad); known_surfaces: readings of these (the table) are not hose
        (None: every reading may be). Bad arguments raise ConfigurationError naming them."""
        super().__init__()
        CheckInstance("params", params, FollowerConfig)
        CheckInstance("mount", mount, ToolMount)
        CheckInstance("grid", grid, DetectionGrid)
        q_initial = CheckVector("q_initial", q_initial)
        CheckInstance("motion", motion, MotionLimits)
        motion.Validate()
        CheckArgument("period", period, POSITIVE)
        CheckInstance("plan_move", plan_move, (Callable, type(None)))
        params = params.Resolved(estimator)
        self._estimator = estimator
        self._params, self._mount, self._grid, self._motion = params, mount, grid, motion
        self._period, self._tool_roll, self._known = period, tool_roll, known_surfaces
        self._plan_move = plan_move or (lambda q, p: PlanJointMove(q, p, motion))
        n = len(q_initial)
        self._ranges = self.DeclareVectorInputPort("ranges", 6)
        self._valid = self.DeclareVectorInputPort("valid", 6)
        self._X_WG = self.DeclareAbstractInputPort(
            "X_WF_measured", AbstractValue.Make(RigidTransform())
        )
        self._position_measured = self.DeclareVectorInputPort("position_measured", n)
        self._ik_status = self.DeclareVectorInputPort("ik_status", 3)
        self._ik_goal = self.DeclareVectorInputPort("q_goal", n)
        self._ik_failure = self.DeclareAbstractInputPort("ik_failure", AbstractValue.Make(""))
        self._loop = self.DeclareAbstractState(
            AbstractValue.Make(_Loop(SENSE, 0, np.asarray(q_initial, float)))
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._Update)
        state_only = {self.xa_ticket()}
        self.DeclareAbstractOutputPort(
            "X_WF_desired",
            lambda: AbstractValue.Make(RigidTransform()),
            self._CalcTarget,
            prerequisites_of_calc=state_only,
        )
        self.DeclareVectorOutputPort(
            "request", 1, self._CalcRequest, prerequisites_of_calc=state_only
        )
        self.DeclareVectorOutputPort(
            "position_commanded",
            n,
            self._CalcCommand,
            prerequisites_of_calc={self.xa_ticket(), self.time_ticket()},
        )
        DeclareStepOutputs(self, self.Loop)
        self.DeclareVectorOutputPort("mode", 2, self._CalcMode, prerequisites_of_calc=state_only)
        self.DeclareAbstractOutputPort(
            "failure",
            lambda: AbstractValue.Make(""),
            self._CalcFailure,
            prerequisites_of_calc=state_only,
        )

    def Loop(self, context: Context) -> _Loop:
        """The current loop state (mode, step, failure, ...)."""
        return context.get_abstract_state(self._loop).get_value()

    def Stopped(self, context: Context) -> bool:
        """Whether the run is over (DONE or FAILED)."""
        return self.Loop(context).stopped

    def _Update(self, context: Context, state: State) -> EventStatus:
        loop = self.Loop(context)
        t = context.get_time()
        if loop.mode == SENSE:
            loop = self._Sense(context, loop, t)
        elif loop.mode == SOLVE:
            loop = self._Solve(context, loop, t)
        elif loop.mode == MOVE:
            loop = self._Move(context, loop, t)
        else:
            return EventStatus.DidNothing()
        state.get_mutable_abstract_state(self._loop).set_value(loop)
        return StoppedStatus(self, loop.stopped)

    def _Sense(self, context: Context, loop: _Loop, t: float) -> _Loop:
        params = self._params
        if not loop.samples or t >= loop.sampled_at + params.reading_period - 1e-9:
            sample = (self._ranges.Eval(context).copy(), self._valid.Eval(context) > 0.5)
            loop = replace(loop, samples=(*loop.samples, sample), sampled_at=t)
        if len(loop.samples) < params.readings:
            return loop
        ranges, valid = AverageReadings(loop.samples)
        loop = replace(loop, samples=())
        X_WT = self._mount.ToolPose(self._X_WG.Eval(context))
        if self._known is not None:
            valid = self._known.HoseReadings(X_WT, ranges, valid)
        memory = loop.memory or FollowerMemory.Start(X_WT, params, self._tool_roll)
        S_T, centre_only = EstimateHose(self._grid, self._estimator, ranges, valid)
        result = FollowStep(X_WT, S_T, centre_only, memory, params)
        detected, errors = self._grid.Detect(ranges, valid)
        here = _Visited(loop.q_goal, X_WT.translation())
        loop = replace(
            loop,
            trail=loop.trail + (here,) if IsExploring(result.memory) else (here,),
            memory=result.memory,
            X_WT_sensed=X_WT,
            record=MakeRecord(loop.step, t, X_WT, result, ranges, valid),
            grid=np.concatenate([detected.ravel(), errors.ravel()]).astype(float),
        )
        return self._Request(loop, result)

    def _Request(self, loop: _Loop, result: StepResult) -> _Loop:
        if result.ended:
            return replace(loop, mode=DONE)
        if loop.step + 1 >= self._params.max_steps:
            return replace(
                loop, mode=FAILED, failure=f"step limit ({self._params.max_steps}) reached"
            )
        return replace(
            loop,
            mode=SOLVE,
            memory=result.memory,
            target=self._mount.GripperPose(result.X_WT_next),
            retrace="recovery" in result.info,
            request=loop.request + 1,
        )

    def _Solve(self, context: Context, loop: _Loop, t: float) -> _Loop:
        status = self._ik_status.Eval(context)
        if status[0] < loop.request:
            return loop
        record = loop.record.copy()
        record[RECORD_FIELDS.index("ik_time")] += status[2]
        loop = replace(loop, record=record)
        if status[1] < 0.5:
            reason = self._ik_failure.Eval(context)
            return self._Refused(loop, f"IK failed at step {loop.step}: {reason}")
        q_goal = self._ik_goal.Eval(context).copy()
        back = loop.trail[-2::-1] if loop.retrace else ()
        stops = [loop.trail[-1], *back]
        waypoints = [v.q for v in stops] + [q_goal]
        target = self._mount.ToolPose(loop.target).translation()
        try:
            move = self._plan_move(waypoints, [v.p_WO for v in stops] + [target])
        except GuidedArmError as e:
            return self._Refused(loop, f"move failed at step {loop.step}: {e}")
        trail = loop.trail[:1] if loop.retrace else loop.trail
        return replace(loop, mode=MOVE, move=move, q_goal=move.goal, t0=t, trail=trail)

    def _Refused(self, loop: _Loop, failure: str) -> _Loop:
        """The arm cannot go where the step asks: while lost or retrying, the next retry;
        with the hose in sight, stop with `failure`."""
        if IsExploring(loop.memory):
            return self._Request(loop, GiveUpDirection(loop.X_WT_sensed, loop.memory, self._params))
        return replace(loop, mode=FAILED, failure=failure)

    def _Move(self, context: Context, loop: _Loop, t: float) -> _Loop:
        end = loop.t0 + max(loop.move.duration, self._period)
        if t < end:
            return loop
        error = np.max(np.abs(self._position_measured.Eval(context) - loop.q_goal))
        if error < self._motion.settle_tolerance or t > end + self._motion.settle_timeout:
            return replace(loop, mode=SENSE, step=loop.step + 1)
        return loop

    def _CalcTarget(self, context: Context, output: AbstractValue) -> None:
        target = self.Loop(context).target
        output.set_value(target if target is not None else RigidTransform())

    def _CalcRequest(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector([self.Loop(context).request])

    def _CalcCommand(self, context: Context, output: BasicVector) -> None:
        loop = self.Loop(context)
        if loop.mode != MOVE:
            output.SetFromVector(loop.q_goal)
            return
        output.SetFromVector(loop.move.Position(context.get_time() - loop.t0))

    def _CalcMode(self, context: Context, output: BasicVector) -> None:
        loop = self.Loop(context)
        output.SetFromVector([loop.mode, loop.step])

    def _CalcFailure(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self.Loop(context).failure)


def StoppedStatus(follower: LeafSystem, stopped: bool) -> EventStatus:
    """A follower's update status: ReachedTermination once the run is over (the hose's end
    found, or a failure), which ends the Simulator's AdvanceTo at this update's time."""
    if stopped:
        return EventStatus.ReachedTermination(follower, "follower stopped")
    return EventStatus.Succeeded()


def DeclareStepOutputs(system: LeafSystem, loop: Callable[[Context], Any]) -> None:
    """Declares a follower's `step_record` (RECORD_FIELDS of the latest step or reading; -1
    before the first) and `detections`, `detection_errors` (the 3 x 3 grid of the latest
    reading, row-major; 0 before the first), read from loop(context).record and .grid
    (a (18,) array, detections then errors) of the system's abstract state."""

    def record(context: Context, output: BasicVector) -> None:
        value = loop(context).record
        output.SetFromVector(value if value is not None else np.full(len(RECORD_FIELDS), -1.0))

    def grid(start: int):
        def calc(context: Context, output: BasicVector) -> None:
            value = loop(context).grid
            output.SetFromVector(value[start : start + 9] if value is not None else np.zeros(9))

        return calc

    state_only = {system.xa_ticket()}
    system.DeclareVectorOutputPort(
        "step_record", len(RECORD_FIELDS), record, prerequisites_of_calc=state_only
    )
    for name, start in (("detections", 0), ("detection_errors", 9)):
        system.DeclareVectorOutputPort(name, 9, grid(start), prerequisites_of_calc=state_only)
