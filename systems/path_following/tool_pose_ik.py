"""ToolPoseIk: inverse kinematics of a commanded frame pose, one solve per request.

The solver and its constraints live in tool_pose_ik_math.py. The system is a service on a
periodic tick: when the `request` input carries a new id, it solves for `X_WF_desired`
started from the measured joint positions (the robot is stopped there) and holds the answer.
"""

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import BasicVector, Context, LeafSystem, State

from guidedarm.systems.config_checks import POSITIVE, CheckArgument, CheckInstance, CheckVector
from guidedarm.systems.path_following.tool_pose_ik_math import ToolPoseSolver

STATUS_SIZE = 3  # request id solved, success (0/1), solve time (s)


class ToolPoseIk(LeafSystem):
    """Inputs: `X_WF_desired` (RigidTransform, world W), `request` ([id]),
    `position_measured` (rad).

    Outputs: `q_goal` (rad; the last solution, or the measured q before any), `status`
    ([id, success, solve_time_s]), `failure` (str, why the last solve failed, '' if not),
    `X_WF_measured` (RigidTransform: forward kinematics of position_measured).
    """

    def __init__(
        self, solver: ToolPoseSolver, period: float, q_initial: np.ndarray | None = None
    ) -> None:
        """period: the update tick (s); q_initial: the goal held before the first request
        (rad; default the solver plant's default positions), the arm's start position. Bad
        arguments raise ConfigurationError naming them."""
        super().__init__()
        CheckInstance("solver", solver, ToolPoseSolver)
        CheckArgument("period", period, POSITIVE)
        self._solver = solver
        n = len(solver.q_indices)
        self._n = n
        self._desired = self.DeclareAbstractInputPort(
            "X_WF_desired", AbstractValue.Make(RigidTransform())
        )
        self._request = self.DeclareVectorInputPort("request", 1)
        self._position_measured = self.DeclareVectorInputPort("position_measured", n)
        if q_initial is None:
            q_initial = solver.plant.GetPositions(solver.context)
        q_initial = CheckVector("q_initial", q_initial, n)
        initial = np.concatenate([[0.0, 1.0, 0.0], q_initial])
        self._state = self.DeclareDiscreteState(initial)
        self._failure = self.DeclareAbstractState(AbstractValue.Make(""))
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._Update)
        self.DeclareVectorOutputPort(
            "q_goal", n, self.CalcGoal, prerequisites_of_calc={self.xd_ticket()}
        )
        self.DeclareVectorOutputPort(
            "status", STATUS_SIZE, self.CalcStatus, prerequisites_of_calc={self.xd_ticket()}
        )
        self.DeclareAbstractOutputPort(
            "failure",
            lambda: AbstractValue.Make(""),
            self.CalcFailure,
            prerequisites_of_calc={self.xa_ticket()},
        )
        self.DeclareAbstractOutputPort(
            "X_WF_measured",
            lambda: AbstractValue.Make(RigidTransform()),
            self.CalcMeasured,
            prerequisites_of_calc={self._position_measured.ticket()},
        )

    def SetInitialGoal(self, context: Context, q: np.ndarray) -> None:
        """Holds q as the goal before the first request (the arm's start position)."""
        context.get_mutable_discrete_state(self._state).set_value(
            np.concatenate([[0.0, 1.0, 0.0], q])
        )

    def _Update(self, context: Context, state: State) -> None:
        request = self._request.Eval(context)[0]
        current = context.get_discrete_state(self._state).get_value()
        if request <= current[0]:
            return
        q_measured = self._position_measured.Eval(context)
        result = self._solver.Solve(self._desired.Eval(context), q_measured)
        state.get_mutable_discrete_state(self._state).set_value(
            np.concatenate([[request, float(result.success), result.solve_time], result.q])
        )
        state.get_mutable_abstract_state(self._failure).set_value(result.reason)

    def CalcGoal(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state(self._state).get_value()[STATUS_SIZE:])

    def CalcStatus(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state(self._state).get_value()[:STATUS_SIZE])

    def CalcFailure(self, context: Context, output: AbstractValue) -> None:
        output.set_value(context.get_abstract_state(self._failure).get_value())

    def CalcMeasured(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self._solver.ForwardKinematics(self._position_measured.Eval(context)))
