"""AccelerationPlanner: the seed-001 planner as a 500 Hz streaming source of joint commands.

Like a program streaming servoJ targets to a UR controller, the planner integrates its own
commanded state (q, qd) from the acceleration law of systems/acceleration_planning.py and
reads the arm's measured state once, at initialization, to start where the arm is. Closing
the loop on the measured state instead would feed the servo's tracking lag into the
acceleration-level law (which differentiates it twice), so the commanded accelerations
would no longer be the continuous, limited ones the method guarantees.
"""

from __future__ import annotations

from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from guidedarm.systems.acceleration_planning import AccelerationPlanning, PlannerState


class AccelerationPlanner(LeafSystem):
    """Streams commanded joint positions, velocities and accelerations at the planner rate.

    Input port: `joint_state` ([q; v] of the arm, rad and rad/s), read at initialization.
    Output ports (commanded, for the arm's 6 joints): `position_commanded` (rad),
    `velocity_commanded` (rad/s), `acceleration_commanded` (rad/s^2, the value held over
    the last step), `scaling_coefficient` (c), and `planner_state` (the full
    PlannerState vector: q, qd, qdd, t, c, c_hat0, t0, waypoint index, sigma, inside,
    done time; for logging). After the task has ended the law keeps running, so the
    commands settle smoothly on the final location instead of stopping with a jump.
    Errors of the law (PlanningError: singular arm, infeasible scaling) propagate out of
    the simulator's AdvanceTo.
    """

    def __init__(self, planning: AccelerationPlanning) -> None:
        super().__init__()
        self._planning = planning
        n = 6
        size = 3 * n + PlannerState.SIZE_EXTRA
        self.DeclareVectorInputPort("joint_state", 2 * n)
        self._state_index = self.DeclareDiscreteState(size)
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

    @property
    def planning(self) -> AccelerationPlanning:
        return self._planning

    def _MakeSlice(self, start: int, size: int):
        def calc(context: Context, output: BasicVector) -> None:
            value = context.get_discrete_state(self._state_index).get_value()
            output.SetFromVector(value[start : start + size])

        return calc

    def _Initialize(self, context: Context, discrete_state: DiscreteValues) -> None:
        q0 = self.get_input_port(0).Eval(context)[:6]
        state = self._planning.InitialState(q0, context.get_time())
        discrete_state.set_value(self._state_index, state.ToVector())

    def _Update(self, context: Context, discrete_state: DiscreteValues) -> None:
        state = PlannerState.FromVector(context.get_discrete_state(self._state_index).get_value())
        discrete_state.set_value(self._state_index, self._planning.Step(state).ToVector())
