"""AccelerationPlanner: Pająk's acceleration-level planner as a 500 Hz source of joint commands.

Like a program streaming servoJ targets to a UR controller, the planner integrates its own
commanded state (q, qd) from the acceleration law of
systems/planning/acceleration_planner_math.py and reads the arm's measured state once, at
initialization, to start where the arm is. Closing the loop on the measured state instead
would feed the servo's tracking lag into the acceleration-level law (which differentiates it
twice), so the commanded accelerations would no longer be the continuous, limited ones the
method guarantees.

With `accept_tasks` the planner takes new tasks while running (re-planning after each
measurement of a sensor-guided sequence): each new PlannerTask restarts the law from the
current commanded state, which keeps q, qd continuous, and c restarts from 0 as at the
start of the paper's task, so the commanded accelerations stay continuous too.

Every waypoint's reachability is checked by inverse kinematics before any motion: at
construction for fixed waypoints, when a task arrives for tasks given while running.
diagrams/tasks/common/planner_builder.py (MakeAccelerationPlanner) builds one for a station.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from guidedarm.systems.config_checks import CheckInstance, CheckVector
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.planning.acceleration_planner_math import (
    AccelerationPlanning,
    PlannerState,
    PlannerTask,
    PlanningError,
)
from guidedarm.systems.planning.waypoint_ik import SolveWaypointIk


class AccelerationPlanner(LeafSystem):
    """Streams commanded joint positions, velocities and accelerations at the planner rate.

    Input port: `arm_state` ([q; v] of the arm, rad and rad/s), read at initialization.
    Output ports (commanded, for the arm's 6 joints): `position_commanded` (rad),
    `velocity_commanded` (rad/s), `acceleration_commanded` (rad/s^2, the value held over
    the last step), `scaling_coefficient` (c), and `planner_state` (the full
    PlannerState vector: q, qd, qdd, t, c, c_hat0, t0, waypoint index, sigma, inside, braking,
    done time; for logging). After the task has ended the law keeps running, so the
    commands settle smoothly on the final location instead of stopping with a jump.
    Errors of the law (PlanningError: the paper's mode at a singular arm or an infeasible
    scaling) propagate out of the simulator's AdvanceTo.

    Fixed waypoints are solved by inverse kinematics at construction, from q_guess (rad;
    default: the plant's default positions of the arm): a waypoint out of reach raises
    ConfigurationError naming it, and the solutions serve the robust mode's joint-space
    blend near singularities (`planning.joint_waypoints`).

    With accept_tasks=True: the waypoints given at construction are not used; the planner
    holds the arm at rest until a task arrives on the abstract input port `task`
    (PlannerTask, waypoints in the planning's base frame). A new sequence number first
    checks every waypoint's reachability by inverse kinematics from the current command
    (PlanningError naming the waypoint, before any motion towards it), then restarts the
    law. Output `done`: 1.0 when the task on the `task` port has ended (TCP within the
    tolerances of its final location) or no task was given, else 0.0.
    """

    def __init__(
        self,
        planning: AccelerationPlanning,
        accept_tasks: bool = False,
        q_guess: np.ndarray | None = None,
    ) -> None:
        super().__init__()
        CheckInstance("planning", planning, AccelerationPlanning)
        CheckInstance("accept_tasks", accept_tasks, bool)
        if q_guess is not None:
            q_guess = CheckVector("q_guess", q_guess, 6)
        if not accept_tasks:
            kinematics = planning.kinematics
            if q_guess is None:
                plant = kinematics.plant
                q_guess = plant.GetPositions(plant.CreateDefaultContext(), kinematics.instance)
            margin = planning.parameters.joint_limit_margin
            joints = SolveWaypointIk(kinematics, planning.waypoints, q_guess, margin=margin)
            planning = planning.WithWaypoints(planning.waypoints, joints)
        self._planning = planning
        n = 6
        size = 3 * n + PlannerState.SIZE_EXTRA
        self.DeclareVectorInputPort("arm_state", 2 * n)
        self._state_index = self.DeclareDiscreteState(size)
        self._task_port = None
        self._task_planning: tuple[int, AccelerationPlanning] = (-1, planning)
        if accept_tasks:
            self._task_port = self.DeclareAbstractInputPort(
                "task", AbstractValue.Make(PlannerTask())
            )
            self._sequence_index = self.DeclareDiscreteState(np.array([-1.0]))
        period = planning.parameters.time_step
        self.DeclareInitializationDiscreteUpdateEvent(self._Initialize)
        # Offset 0: the update at t_k computes the command for t_k + period, so discrete
        # systems sampling the outputs at t_k (the station's servo interpolator) read the
        # command for t_k, without a period of lag.
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._Update)
        ticket = {self.xd_ticket()}
        for name, start in (
            ("position_commanded", 0),
            ("velocity_commanded", n),
            ("acceleration_commanded", 2 * n),
        ):
            self.DeclareVectorOutputPort(
                name, n, self._MakeSlice(start, n), prerequisites_of_calc=ticket
            )
        self.DeclareVectorOutputPort(
            "scaling_coefficient", 1, self._MakeSlice(3 * n + 1, 1), prerequisites_of_calc=ticket
        )
        self.DeclareVectorOutputPort(
            "planner_state", size, self._MakeSlice(0, size), prerequisites_of_calc=ticket
        )
        if accept_tasks:
            self.DeclareVectorOutputPort(
                "done",
                1,
                self._CalcDone,
                prerequisites_of_calc={self.xd_ticket(), self._task_port.ticket()},
            )

    @property
    def planning(self) -> AccelerationPlanning:
        return self._planning

    def RouteThroughJointSpaceFrom(
        self, index: int, joint_waypoints: np.ndarray | None = None
    ) -> None:
        """Routes the planner's task through joint space from waypoint `index` (0-based),
        towards `joint_waypoints` (rad; None: the planner's own IK solutions;
        AccelerationPlanning.WithJointSpaceFrom), e.g. where the dry run before motion
        found the Cartesian motion colliding; before the simulation starts, and not with
        accept_tasks (each new task is planned afresh)."""
        if self._task_port is not None:
            raise ConfigurationError("a planner that accepts tasks routes each task afresh")
        self._planning = self._planning.WithJointSpaceFrom(index, joint_waypoints)
        self._task_planning = (-1, self._planning)

    def _MakeSlice(self, start: int, size: int):
        def calc(context: Context, output: BasicVector) -> None:
            value = context.get_discrete_state(self._state_index).get_value()
            output.SetFromVector(value[start : start + size])

        return calc

    def _Initialize(self, context: Context, discrete_state: DiscreteValues) -> None:
        q0 = self.get_input_port(0).Eval(context)[:6]
        state = self._planning.InitialState(q0, context.get_time())
        discrete_state.set_value(self._state_index, state.ToVector())
        if self._task_port is not None:
            discrete_state.set_value(self._sequence_index, [-1.0])

    def _Update(self, context: Context, discrete_state: DiscreteValues) -> None:
        state = PlannerState.FromVector(context.get_discrete_state(self._state_index).get_value())
        if self._task_port is None:
            discrete_state.set_value(self._state_index, self._planning.Step(state).ToVector())
            return
        task = self._Task(context)
        running = round(context.get_discrete_state(self._sequence_index).get_value()[0])
        if task.sequence != running:
            planning = self._StartTask(task, state)
            state = planning.Restart(state)
            discrete_state.set_value(self._sequence_index, [float(task.sequence)])
        elif running >= 0:
            planning = self._PlanningFor(task, state)
        else:  # no task yet: hold at rest
            state.t += self._planning.parameters.time_step
            discrete_state.set_value(self._state_index, state.ToVector())
            return
        discrete_state.set_value(self._state_index, planning.Step(state).ToVector())

    def _Task(self, context: Context) -> PlannerTask:
        if not self._task_port.HasValue(context):
            return PlannerTask()
        return self._task_port.Eval(context)

    def _StartTask(self, task: PlannerTask, state: PlannerState) -> AccelerationPlanning:
        try:
            planning = self._planning.WithWaypoints(task.waypoints)
            margin = planning.parameters.joint_limit_margin
            joints = SolveWaypointIk(
                planning.kinematics, planning.waypoints, state.q, margin=margin
            )
            planning = planning.WithWaypoints(planning.waypoints, joints)
        except ConfigurationError as e:
            raise PlanningError(f"planner task {task.sequence} refused: {e}") from None
        self._task_planning = (task.sequence, planning)
        return planning

    def _PlanningFor(self, task: PlannerTask, state: PlannerState) -> AccelerationPlanning:
        # A cache of the running task's planning, made when the task started; a context
        # that did not start it here (e.g. a copy) solves the waypoints again from state.
        if self._task_planning[0] != task.sequence:
            self._task_planning = (task.sequence, self._StartTask(task, state))
        return self._task_planning[1]

    def _CalcDone(self, context: Context, output: BasicVector) -> None:
        task = self._Task(context)
        running = round(context.get_discrete_state(self._sequence_index).get_value()[0])
        state = PlannerState.FromVector(context.get_discrete_state(self._state_index).get_value())
        ended = task.sequence < 0 or (task.sequence == running and state.done)
        output.SetFromVector([1.0 if ended else 0.0])
