"""ContinuousFollower: path following without stops (motion `continuous`).

Every servo period it records the measured joints; when the ToF tool's `measured_at`
stamps change (a new reading), it takes the tool pose at the measurement instant (the
joints interpolated at the mean stamp, forward kinematics of T on the controller plant:
motion compensation), estimates the hose centre in T (ranging or grid estimator), adds the
world point to the hose estimate, and updates the mode (follow, search, back up, retry,
done). Then the target pose moves one period along the estimate
(continuous_follower_math.Advance). A DifferentialIkServo turns the target into joint
commands (path_following_diagram.AddPathFollowing wires both).

It reads only `<tof>.ranges`, `<tof>.valid`, `<tof>.measured_at` and
`<arm>.position_measured`, which the simulated and the hardware stations both export, and
the servo's `failure` (a workspace wall reached), which ends the run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame
from pydrake.systems.framework import BasicVector, Context, EventStatus, LeafSystem, State

from guidedarm.systems.config_checks import CheckInstance, CheckVector, FieldError
from guidedarm.systems.path_following.continuous_follower_config import ContinuousConfig
from guidedarm.systems.path_following.continuous_follower_estimate import HoseEstimate, JointHistory
from guidedarm.systems.path_following.continuous_follower_math import (
    BACK,
    DONE,
    FOLLOW,
    Advance,
    OnReading,
    Reference,
    Replaced,
)
from guidedarm.systems.path_following.hose_thickness import Thickness
from guidedarm.systems.path_following.path_follower import StoppedStatus
from guidedarm.systems.path_following.path_follower_math import (
    ESTIMATORS,
    RECORD_FIELDS,
    EstimateHose,
)
from guidedarm.systems.plant_frames import CheckFrame, CheckPlant
from guidedarm.systems.tof.detection_grid import DetectionGrid
from guidedarm.systems.tof.hose_range_model import RADIUS_FIT_SENSORS
from guidedarm.systems.tof.known_surfaces import KnownSurfaces

# The arm this far (m) from the target means it cannot follow (limits, a singularity).
MAX_LAG = 0.025
# An arm whose joints stay within STILL_TOLERANCE (rad) of one another for STALL_TIME (s)
# makes no progress: a search that cannot move (the hose ends at the arm's reach) is over,
# and a follower that cannot move has failed, instead of waiting for max_time.
STILL_TOLERANCE = 1e-3
STALL_TIME = 2.0


@dataclass(frozen=True)
class _Run:
    """The follower's abstract state; never changed in place (see PathFollower's _Loop):
    Replaced (continuous_follower_math) makes the next one."""

    reference: Reference
    estimate: HoseEstimate
    history: JointHistory
    stamp: float = -1.0
    still_q: list[float] | None = None
    still_since: float = 0.0
    step: int = 0
    record: np.ndarray | None = None
    grid: np.ndarray | None = None
    failure: str = ""
    lag: float = 0.0
    thickness: Thickness = field(default_factory=Thickness)

    @property
    def stopped(self) -> bool:
        return self.reference.mode == DONE or bool(self.failure)

    def __deepcopy__(self, memo: dict) -> _Run:
        return self


class ContinuousFollower(LeafSystem):
    """Inputs: `ranges` (6, m), `valid` (6), `measured_at` (6, s; -1 before the first
    reading), `position_measured` (n, rad), `servo_failure` (str, '' while the servo
    follows; anything else ends the run with that reason; unconnected: '').

    Outputs: `X_WT_desired` (RigidTransform of the tool frame T in world W, the target
    for the next period), `step_record` (RECORD_FIELDS of the latest reading: t its
    measurement instant, O the tool centre then, S the hose point, `lost` 1 outside
    FOLLOW, `recovery` the retry in progress, `ended` 1 once done), `detections` and
    `detection_errors` (3 x 3 grid of the latest reading), `mode` ([mode, readings];
    continuous_follower_math's FOLLOW..DONE), `failure` (str).

    plant, tool: the controller plant (positions = the arm's joints) and T on it;
    grid, estimator: the tool's detection grid and `grid` or `ranging`; q_initial: the
    start joints (rad), T on the hose's first point along it; tool_roll: the target's
    roll about x_T (rad); known_surfaces: readings of these (the table) are not hose
    (known_surfaces; None: every reading may be). Bad arguments raise ConfigurationError
    naming them.
    """

    def __init__(
        self,
        config: ContinuousConfig,
        plant: MultibodyPlant,
        tool: Frame,
        grid: DetectionGrid,
        estimator: str,
        q_initial: np.ndarray,
        tool_roll: float = 0.0,
        known_surfaces: KnownSurfaces | None = None,
    ) -> None:
        super().__init__()
        CheckInstance("config", config, ContinuousConfig)
        config.Validate()
        CheckPlant("plant", plant)
        CheckFrame("tool", tool, plant)
        CheckInstance("grid", grid, DetectionGrid)
        if estimator not in ESTIMATORS:
            raise FieldError(
                "estimator", f"must be one of {', '.join(ESTIMATORS)}, got {estimator!r}"
            )
        q_initial = CheckVector("q_initial", q_initial, plant.num_positions())
        if estimator == "grid":
            # The grid estimator's points are the grid's (spacing apart): a jump of one
            # spacing is its resolution, not an outlier.
            config = replace(config, gate=max(config.gate, grid.spacing))
        self._config, self._plant, self._tool = config, plant, tool
        self._grid, self._estimator = grid, estimator
        # Detection grids for a hose thicker by a multiple of hose_thickness.QUANTUM.
        self._thicker_grids = {0.0: grid}
        self._plant_context = plant.CreateDefaultContext()
        n = len(q_initial)
        X_WT = self._ToolPose(q_initial)
        history = JointHistory(config.history).With(0.0, q_initial)
        start = _Run(Reference.Start(X_WT, tool_roll), HoseEstimate.Start(X_WT), history)
        self._known = known_surfaces
        self._ranges = self.DeclareVectorInputPort("ranges", 6)
        self._valid = self.DeclareVectorInputPort("valid", 6)
        self._measured_at = self.DeclareVectorInputPort("measured_at", 6)
        self._position = self.DeclareVectorInputPort("position_measured", n)
        self._servo_failure = self.DeclareAbstractInputPort("servo_failure", AbstractValue.Make(""))
        self._run = self.DeclareAbstractState(AbstractValue.Make(start))
        # The target pose, kept beside the run (its Pose()) so that the servo reads it every
        # period from the state, without a call into Python.
        self._target = self.DeclareAbstractState(AbstractValue.Make(start.reference.Pose()))
        # The latest reading's record and grid (the run's record and grid, -1 and 0 before
        # the first), kept as vectors for the loggers to read from the state.
        self._record = self.DeclareDiscreteState(np.full(len(RECORD_FIELDS), -1.0))
        self._detections = self.DeclareDiscreteState(9)
        self._detection_errors = self.DeclareDiscreteState(9)
        self.DeclarePeriodicUnrestrictedUpdateEvent(config.servo_period, 0.0, self._Update)
        state_only = {self.xa_ticket()}
        self.DeclareStateOutputPort("X_WT_desired", self._target)
        self.DeclareStateOutputPort("step_record", self._record)
        self.DeclareStateOutputPort("detections", self._detections)
        self.DeclareStateOutputPort("detection_errors", self._detection_errors)
        self.DeclareVectorOutputPort("mode", 2, self._CalcMode, prerequisites_of_calc=state_only)
        self.DeclareAbstractOutputPort(
            "failure",
            lambda: AbstractValue.Make(""),
            lambda c, o: o.set_value(self.Loop(c).failure),
            prerequisites_of_calc=state_only,
        )

    def Loop(self, context: Context) -> _Run:
        """The current state (reference, estimate, readings as `step`, failure)."""
        return context.get_abstract_state(self._run).get_value()

    def Stopped(self, context: Context) -> bool:
        """Whether the run is over (the hose's end found, or a failure)."""
        return self.Loop(context).stopped

    def _ToolPose(self, q: np.ndarray) -> RigidTransform:
        self._plant.SetPositions(self._plant_context, q)
        return self._tool.CalcPoseInWorld(self._plant_context)

    def _Update(self, context: Context, state: State) -> EventStatus:
        run = previous = self.Loop(context)
        if run.stopped:
            return EventStatus.DidNothing()
        t = context.get_time()
        q = self._position.Eval(context)
        run = self._Stall(run, run.history.With(t, q), q, t)
        stamps = self._measured_at.Eval(context)
        # The mean as sum / 6 (numpy's mean's value) and the min over floats: numpy's
        # per-call overhead counts at the servo rate.
        stamp = float(stamps.sum()) / len(stamps)
        if min(stamps.tolist()) >= 0 and stamp > run.stamp + 1e-9:
            run = self._Read(context, run, stamp)
        servo_failure = (
            self._servo_failure.Eval(context) if self._servo_failure.HasValue(context) else ""
        )
        if servo_failure:
            run = _CannotFollow(run, f"the servo stopped the arm at t = {t:.2f} s: {servo_failure}")
        if not run.failure:
            cap = run.thickness.SpeedCap(run.reference.s, self._config)
            reference = Advance(
                run.reference, run.estimate, self._config.servo_period, self._config, run.lag, cap
            )
            run = Replaced(run, reference=reference)
        state.get_mutable_abstract_state(self._run).set_value(run)
        state.get_mutable_abstract_state(self._target).set_value(run.reference.Pose())
        if run.record is not previous.record:  # a reading
            discrete = state.get_mutable_discrete_state()
            discrete.set_value(self._record, run.record)
            discrete.set_value(self._detections, run.grid[:9])
            discrete.set_value(self._detection_errors, run.grid[9:])
        return StoppedStatus(self, run.stopped)

    def _Stall(self, run: _Run, history: JointHistory, q: np.ndarray, t: float) -> _Run:
        """run with `history`, tracking how long the joints have stayed still; after
        STALL_TIME a search ends (DONE: the hose's end as far as the arm can reach) and
        following fails."""
        # Compared as floats: numpy's per-call overhead counts at the servo rate.
        q_list = q.tolist()
        if run.still_q is None or any(
            abs(a - b) > STILL_TOLERANCE for a, b in zip(q_list, run.still_q, strict=True)
        ):
            return Replaced(run, history=history, still_q=q_list, still_since=t)
        run = Replaced(run, history=history)
        if t - run.still_since < STALL_TIME:
            return run
        return _CannotFollow(
            run,
            f"the arm has not moved for {STALL_TIME:.0f} s at t = {t:.2f} s while following: "
            "joint limits, the workspace or a singularity hold it",
        )

    def _Read(self, context: Context, run: _Run, stamp: float) -> _Run:
        """One new reading: motion compensation, the hose point, the estimate, the mode."""
        ranges = self._ranges.Eval(context).copy()
        valid = self._valid.Eval(context) > 0.5
        X_WT = self._ToolPose(run.history.At(stamp))
        if self._known is not None:  # the table and other known surfaces are not hose
            valid = self._known.HoseReadings(X_WT, ranges, valid)
        p_WO = X_WT.translation()
        axis_T = run.estimate.AxisInTool(X_WT, self._config)
        thickness = self._Thickness(run, X_WT, ranges, valid, axis_T)
        grid = self._GridFor(thickness.excess)
        S_W, S_W_plain = self._HosePoint(grid, ranges, valid, X_WT, axis_T)
        estimate = run.estimate
        if thickness.excess and S_W is not None:
            # A reading the fit would reject with the thicker radius and take with the
            # hose's own: the section ended, or began before the fit could follow it.
            s = estimate.ToolCoordinate(X_WT)
            if estimate.IsOutlier(s, S_W, self._config):
                plain = self._HosePoint(self._grid, ranges, valid, X_WT, axis_T)
                if plain[0] is not None and not estimate.IsOutlier(s, plain[0], self._config):
                    S_W, S_W_plain = plain
        # Backing up retraces the estimated trail: readings taken backwards would run the
        # fit's path coordinate backwards and drag the trail's end (the target) with it.
        if run.reference.mode != BACK:
            estimate = estimate.WithReading(X_WT, S_W, self._config, S_W_plain)
        reference = OnReading(run.reference, estimate, X_WT, self._config)
        if not estimate.IsDetected():
            S_W = None
        detected, errors = self._grid.Detect(ranges, valid)
        range_list, valid_list = ranges.tolist(), valid.tolist()
        # One array from floats (RECORD_FIELDS): numpy's per-piece overhead counts.
        S = S_W if S_W is not None else p_WO
        record = np.array(
            [
                run.step,
                stamp,
                *p_WO.tolist(),
                *S.tolist(),
                float(S_W is not None),
                0.0,
                float(reference.mode != FOLLOW),
                reference.retry,
                reference.recoveries,
                float(reference.mode == DONE),
                0.0,
                *range_list,
                *valid_list,
            ],
            float,
        )
        # The arm's lag behind the target, |p| as np.linalg.norm's sqrt(p . p).
        p = self._ToolPose(run.history.At(context.get_time())).translation() - run.reference.r
        lag = math.sqrt(float(p.dot(p)))
        run = Replaced(
            run,
            reference=reference,
            estimate=estimate,
            thickness=thickness,
            stamp=stamp,
            step=run.step + 1,
            record=record,
            grid=np.concatenate((detected, errors), axis=None).astype(float),
            lag=lag,
        )
        closest, sensor = min(
            ((r, k) for k, (r, v) in enumerate(zip(range_list, valid_list, strict=True)) if v),
            default=(math.inf, 0),
        )
        if closest < self._config.min_range:
            return Replaced(
                run,
                failure=f"the hose came within {1000 * closest:.0f} mm of sensor {sensor + 1} at "
                f"reading {run.step - 1} (t = {stamp:.2f} s; continuous.min_range "
                f"{1000 * self._config.min_range:.0f} mm): the tool is at the hose, in a bend "
                "tighter than it can follow; stopped",
            )
        if lag > MAX_LAG:
            run = _CannotFollow(
                run,
                f"the arm fell {1000 * lag:.0f} mm behind the target at reading {run.step - 1} "
                f"(t = {context.get_time():.2f} s): joint limits or a singularity",
            )
        return run

    def _HosePoint(
        self,
        grid: DetectionGrid,
        ranges: np.ndarray,
        valid: np.ndarray,
        X_WT: RigidTransform,
        axis_T: np.ndarray | None,
    ) -> tuple[np.ndarray | None, np.ndarray | None]:
        """(S_W, S_W_plain): the hose centre (W) the estimator finds with `grid`'s radius,
        modelling the hose along axis_T when known, and the same for a hose perpendicular
        to the detection plane (which feeds the axis fit); None when it sees no hose."""
        S_T, _ = EstimateHose(grid, self._estimator, ranges, valid)
        S_W = S_W_plain = None if S_T is None else X_WT @ np.asarray(S_T, float)
        if S_T is not None and axis_T is not None:
            S_T, _ = EstimateHose(grid, self._estimator, ranges, valid, axis_T)
            S_W = None if S_T is None else X_WT @ np.asarray(S_T, float)
        return S_W, S_W_plain

    def _Thickness(
        self,
        run: _Run,
        X_WT: RigidTransform,
        ranges: np.ndarray,
        valid: np.ndarray,
        axis_T: np.ndarray | None,
    ) -> Thickness:
        """The hose's thickness after this reading (hose_thickness): its radius measured
        when enough sensors see it, at the tool's path coordinate."""
        if self._config.thickening_min <= 0:
            return run.thickness
        if np.count_nonzero(valid) < RADIUS_FIT_SENSORS:
            excess = 0.0  # a section thicker than the hose would reach the flank cones too
        else:
            radius = self._grid.RadiusEstimate(ranges, valid, axis_T)
            excess = None if radius is None else radius - self._grid.hose_radius
        s = run.estimate.ToolCoordinate(X_WT)
        return run.thickness.With(s, excess, self._config)

    def _GridFor(self, excess: float) -> DetectionGrid:
        """The detection grid of a hose `excess` (m) thicker than the tool's."""
        grid = self._thicker_grids.get(excess)
        if grid is None:
            grid = replace(self._grid, hose_radius=self._grid.hose_radius + excess)
            self._thicker_grids[excess] = grid
        return grid

    def _CalcMode(self, context: Context, output: BasicVector) -> None:
        run = self.Loop(context)
        output.SetFromVector([run.reference.mode, run.step])


def _CannotFollow(run: _Run, why: str) -> _Run:
    """The arm cannot go where the target is (it stalls, lags MAX_LAG behind, or the servo
    stops it at the workspace): while following, the run fails with `why`; during a search
    or back-up past the latest estimate, the hose ends there as far as the arm can reach
    (DONE; a search mid-hose then fails on its coverage)."""
    if run.reference.mode == FOLLOW:
        return Replaced(run, failure=why)
    return Replaced(run, reference=Replaced(run.reference, mode=DONE, v=0.0))
