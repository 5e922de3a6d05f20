"""Inverse kinematics of a commanded frame pose with the constraints of Wawrzyniak et al.
(section 3.2).

One solve is a Drake InverseKinematics program on the arm's joints, started from the
previous joint positions (as the paper's Matlab solver was):
  - the frame's point Q (the tool centre O for the path follower) within
    position_tolerance of where the target pose puts it; the frame's orientation as close
    to the target as the arm allows (a cost, as the paper's weighted generalised IK), and
    never farther than orientation_tolerance_deg; when no solution within that tolerance
    exists without a reconfiguration (near the reach limit, or near a wrist singularity
    where a small turn of the tool needs a large wrist turn that swings the tool), the
    solve is repeated allowing a shortfall of up to shortfall_tolerance_deg: the tool
    keeps its position on the path and turns less than asked, and the next step, computed
    from the measured pose, asks again;
  - no step rotates the frame by 90 deg or more about any axis (no tool reversal): the
    angle between the new and the current orientation stays below max_step_rotation_deg;
  - a downward tool: the frame's `down_axis` stays within max_tilt_deg of world -z;
  - the origin of every body the arm moves stays inside the workspace, the cell's virtual
    walls as a box in the arm's base frame B (the paper's controller walls and IK bounds);
  - joint limits (InverseKinematics' bounds);
  - the joint-space move from the previous q keeps the frame within max_swing of the
    straight line between its two poses: a solution on another branch (a wrist or elbow
    flip) would swing the tool through the hose on the way, so it is not taken;
  - a joint whose range exceeds a full turn takes the 2 pi multiple nearest its previous
    position: the same pose reached with the last joint a turn further would spin the
    tool once around the hose;
  - a small cost on the distance to the previous joint positions keeps the same branch;
  - with the plant's geometry at hand (a Diagram connecting the plant to its SceneGraph), a
    solution in which the arm touches itself (the gripper on the forearm at a sharp wrist
    bend: joint limits from the pendant allow it, the parts do not) is solved again with
    every pair of the arm's collision geometries kept self_clearance apart. The simulated
    arm, like the real one, stops at such a contact short of its goal; the follower then
    read its next step from a tool that had not moved, walked backwards along the hose for
    seven steps and turned round onto it (random_17, noise seed 21). Only those solutions
    are solved again, so every other one is the same as without the geometry.
"""

import math
import time
from dataclasses import dataclass, field

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame, ModelInstanceIndex
from pydrake.solvers import MathematicalProgram, MathematicalProgramResult, SnoptSolver, Solve
from pydrake.systems.framework import Diagram

from guidedarm.systems.config_checks import (
    CheckFields,
    CheckInstance,
    CheckVector,
    InRange,
    NonNegative,
    Positive,
)
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.path_following.workspace import WorkspaceConfig
from guidedarm.systems.plant_frames import CheckFrame, CheckModelInstance, CheckPlant


@dataclass
class ToolPoseIkConfig:
    """The IK's tolerances, constraints and costs (see the module docstring); the walls are
    a WorkspaceConfig (systems/path_following/workspace.py), given to the solver beside this.

    position_tolerance: of the frame's point Q (m).
    orientation_tolerance_deg: largest orientation error of a solution (deg).
    shortfall_tolerance_deg: the orientation tolerance of the second solve (deg); 0
        disables it.
    orientation_cost_weight: weight of the orientation-error cost.
    max_step_rotation_deg: largest rotation of the frame in one step (deg).
    max_tilt_deg: largest angle between the frame's down_axis and world -z (deg).
    down_axis: the frame's axis that should point down.
    max_swing: largest distance of the frame from the straight line between two
        consecutive poses during the joint move (m); inf turns the swing check off.
    joint_cost_weight: weight of the stay-near-the-previous-q cost.
    retries: perturbed restarts after a failed solve.
    self_clearance: distance kept between the arm's own collision geometries when a
        solution touching itself is solved again (m).
    """

    position_tolerance: float = Positive(0.0005)
    orientation_tolerance_deg: float = Positive(0.5)
    shortfall_tolerance_deg: float = NonNegative(45.0)
    orientation_cost_weight: float = NonNegative(10.0)
    max_step_rotation_deg: float = InRange(0.0, 180.0, 89.0, low_open=True)
    max_tilt_deg: float = InRange(0.0, 180.0, 85.0)
    down_axis: list[float] = field(default_factory=lambda: [0.0, 0.0, 1.0])
    max_swing: float = Positive(0.025, allow_inf=True)
    joint_cost_weight: float = NonNegative(0.01)
    retries: int = 3
    self_clearance: float = Positive(0.001)

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad limit."""
        CheckFields(self)
        if len(self.down_axis) != 3 or not np.linalg.norm(self.down_axis) > 0:
            raise ConfigurationError(f"down_axis must be a nonzero 3-vector, got {self.down_axis}")


@dataclass(frozen=True)
class IkResult:
    """q (rad, the arm's joints), success, solve time (s), and why it failed ('' if not)."""

    q: np.ndarray
    success: bool
    solve_time: float
    reason: str


class ToolPoseSolver:
    """IK of `frame` (a frame of `plant`) for the arm `instance`; see the module docstring."""

    def __init__(
        self,
        plant: MultibodyPlant,
        instance: ModelInstanceIndex,
        frame: Frame,
        limits: ToolPoseIkConfig,
        p_FQ: np.ndarray | None = None,
        workspace: WorkspaceConfig | None = None,
        X_WB: RigidTransform | None = None,
        diagram: Diagram | None = None,
    ) -> None:
        """p_FQ: the point of the frame held on target (m, frame F; default its origin).
        With the tool centre there, an orientation shortfall turns the tool about its centre
        and leaves it on the path; about the gripper's origin it would move the centre
        sideways by the tool's length times the shortfall. workspace: the walls (default the
        paper's cell) in the arm's base frame B, whose pose in the world is X_WB (default the
        identity). diagram: a Diagram holding `plant` connected to its SceneGraph; with it,
        solutions in which the arm touches itself are solved again
        keeping its parts apart (module docstring)."""
        CheckPlant("plant", plant)
        CheckModelInstance("instance", instance, plant)
        CheckFrame("frame", frame, plant)
        CheckInstance("limits", limits, ToolPoseIkConfig)
        CheckInstance("workspace", workspace, (WorkspaceConfig, type(None)))
        CheckInstance("X_WB", X_WB, (RigidTransform, type(None)))
        limits.Validate()
        self.plant = plant
        self.frame = frame
        self.limits = limits
        self.workspace = workspace or WorkspaceConfig()
        self.workspace.Validate()
        self.X_WB = X_WB or RigidTransform()
        self.p_FQ = np.zeros(3) if p_FQ is None else CheckVector("p_FQ", p_FQ, 3)
        CheckInstance("diagram", diagram, (Diagram, type(None)))
        self._geometry = diagram is not None
        if self._geometry:
            # The plant's context belongs to the diagram's, and the plant to the diagram.
            self._diagram, self._root = diagram, diagram.CreateDefaultContext()
            self.context = plant.GetMyMutableContextFromRoot(self._root)
        else:
            self.context = plant.CreateDefaultContext()
        self._q_start = plant.GetPositions(self.context).copy()
        joints = plant.GetJointIndices(instance)
        self.q_indices = np.array(
            [
                plant.get_joint(j).position_start()
                for j in joints
                if plant.get_joint(j).num_positions()
            ]
        )
        if plant.num_positions() != len(self.q_indices):
            raise ConfigurationError(
                "tool pose IK needs a plant whose only joints are the arm's "
                f"({plant.num_positions()} positions, the arm has {len(self.q_indices)})"
            )
        self._lower = plant.GetPositionLowerLimits()
        self._upper = plant.GetPositionUpperLimits()
        moved = plant.GetBodiesKinematicallyAffectedBy(list(joints))
        self._bodies = [plant.get_body(b) for b in moved]
        self._solver = SnoptSolver() if SnoptSolver().available() else None

    def ForwardKinematics(self, q: np.ndarray) -> RigidTransform:
        """X_WF of the frame at joint positions q."""
        self.plant.SetPositions(self.context, q)
        return self.frame.CalcPoseInWorld(self.context)

    def Reaches(self, X_WF_desired: RigidTransform, q: np.ndarray) -> bool:
        """Whether q already holds the frame's point Q within position_tolerance (per axis)
        and the frame within orientation_tolerance_deg of X_WF_desired (plus the solver's
        own slack: its solutions lie on those bounds)."""
        X_WF = self.ForwardKinematics(q)
        offset = np.abs(X_WF @ self.p_FQ - X_WF_desired @ self.p_FQ)
        turn = X_WF.rotation().inverse().multiply(X_WF_desired.rotation()).ToAngleAxis().angle()
        return bool(
            np.all(offset <= self.limits.position_tolerance + 1e-9)
            and math.degrees(turn) <= self.limits.orientation_tolerance_deg + 1e-6
        )

    def Swing(self, q_from: np.ndarray, q_to: np.ndarray) -> float:
        """Largest distance (m) of the frame from the straight line between its end poses
        along the joint-space interpolation from q_from to q_to."""
        a = self.ForwardKinematics(q_from).translation()
        b = self.ForwardKinematics(q_to).translation()
        worst = 0.0
        for s in (0.25, 0.5, 0.75):
            p = self.ForwardKinematics(q_from + s * (q_to - q_from)).translation()
            worst = max(worst, float(np.linalg.norm(p - (a + s * (b - a)))))
        return worst

    def NearestTurn(self, q: np.ndarray, q_previous: np.ndarray) -> np.ndarray:
        """q with each joint moved by whole turns (2 pi) as near q_previous as its limits
        allow; the frame's pose does not change."""
        turns = np.round((q_previous - q) / (2 * math.pi))
        shifted = q + 2 * math.pi * turns
        inside = (shifted >= self._lower) & (shifted <= self._upper)
        return np.where(inside, shifted, q)

    def Solve(self, X_WF_desired: RigidTransform, q_previous: np.ndarray) -> IkResult:
        """Joint positions putting the frame at X_WF_desired, started from q_previous."""
        start = time.perf_counter()
        lim = self.limits
        tolerances = [lim.orientation_tolerance_deg]
        if lim.shortfall_tolerance_deg > lim.orientation_tolerance_deg:
            tolerances.append(lim.shortfall_tolerance_deg)
        reasons = []
        for tolerance in tolerances:
            q_new, reason = self._Solve(X_WF_desired, q_previous, tolerance)
            if (
                q_new is not None
                and self.TouchesItself(q_new)
                and not self.TouchesItself(q_previous)
            ):
                q_new, reason = self._Solve(X_WF_desired, q_previous, tolerance, True)
            if q_new is not None:
                return IkResult(q_new, True, time.perf_counter() - start, "")
            reasons.append(reason)
        # The first reason names what the requested pose itself violates.
        elapsed = time.perf_counter() - start
        return IkResult(np.asarray(q_previous, float), False, elapsed, reasons[0])

    def TouchesItself(self, q: np.ndarray) -> bool:
        """Whether two of the arm's collision geometries (those its model does not filter)
        penetrate each other at q; False without the plant's geometry."""
        if not self._geometry:
            return False
        self.plant.SetPositions(self.context, q)
        return self.plant.get_geometry_query_input_port().Eval(self.context).HasCollisions()

    def _Solve(
        self,
        X_WF_desired: RigidTransform,
        q_previous: np.ndarray,
        orientation_tolerance: float,
        apart: bool = False,
    ) -> tuple[np.ndarray | None, str]:
        """(q, '') of one program with the given orientation tolerance (deg), or (None, why);
        apart: the arm's geometries kept self_clearance apart."""
        lim = self.limits
        X_WF_now = self.ForwardKinematics(q_previous)
        if apart:
            ik = InverseKinematics(self.plant, self.context, with_joint_limits=True)
        else:
            ik = InverseKinematics(self.plant, with_joint_limits=True)
        q = ik.q()
        world = self.plant.world_frame()
        p = X_WF_desired @ self.p_FQ
        tol = lim.position_tolerance
        described = [
            (
                ik.AddPositionConstraint(self.frame, self.p_FQ, world, p - tol, p + tol),
                "target position",
            ),
            (
                ik.AddOrientationConstraint(
                    world,
                    X_WF_desired.rotation(),
                    self.frame,
                    RotationMatrix(),
                    math.radians(orientation_tolerance),
                ),
                "target orientation",
            ),
            (
                ik.AddOrientationConstraint(
                    world,
                    X_WF_now.rotation(),
                    self.frame,
                    RotationMatrix(),
                    math.radians(lim.max_step_rotation_deg),
                ),
                "step rotation < 90 deg",
            ),
            (
                ik.AddAngleBetweenVectorsConstraint(
                    self.frame,
                    np.asarray(lim.down_axis, float),
                    world,
                    np.array([0.0, 0.0, -1.0]),
                    0.0,
                    math.radians(lim.max_tilt_deg),
                ),
                "downward tool",
            ),
        ]
        lower, upper = self.workspace.Lower(), self.workspace.Upper()
        for body in self._bodies:
            binding = ik.AddPositionConstraint(
                body.body_frame(), np.zeros(3), world, self.X_WB, lower, upper
            )
            described.append((binding, f"workspace ({body.name()})"))
        if apart:
            described.append(
                (ik.AddMinimumDistanceLowerBoundConstraint(lim.self_clearance), "self-contact")
            )
        for binding, description in described:
            binding.evaluator().set_description(description)
        ik.AddOrientationCost(
            world,
            X_WF_desired.rotation(),
            self.frame,
            RotationMatrix(),
            lim.orientation_cost_weight,
        )
        prog = ik.get_mutable_prog()
        n = len(self.q_indices)
        prog.AddQuadraticErrorCost(lim.joint_cost_weight * np.eye(n), q_previous, q)
        # SNOPT occasionally stalls from the previous q near a limit; retry from nearby
        # starts (seeded, so runs repeat) before reporting a failure.
        rng = np.random.default_rng(len(q_previous))
        starts = [q_previous] + [
            q_previous + rng.normal(0.0, 0.3, size=n) for _ in range(self.limits.retries)
        ]
        swing = 0.0
        for guess in starts:
            result = self._solver.Solve(prog, guess) if self._solver else Solve(prog, guess)
            if result.is_success() or (apart and _Feasible(prog, result)):
                q_new = self.NearestTurn(result.GetSolution(q), q_previous)
                swing = self.Swing(q_previous, q_new)
                if swing <= lim.max_swing:
                    return q_new, ""
        if swing > lim.max_swing:
            return None, (
                f"reaching the pose needs a reconfiguration (the tool would swing "
                f"{1000 * swing:.0f} mm off its path)"
            )
        names = result.GetInfeasibleConstraintNames(prog)
        return None, _Explain(names) if names else result.get_solution_result().name


def _Feasible(prog: MathematicalProgram, result: MathematicalProgramResult) -> bool:
    """Whether the result satisfies every constraint of prog (to 1e-6). The distance
    constraint between the arm's parts is not smooth where the closest pair changes: SNOPT
    then stops at a feasible point it cannot improve (its info 41) or at the iteration
    limit, and such a point is a solution that touches nothing."""
    x = result.GetSolution()
    return bool(np.all(np.isfinite(x))) and prog.CheckSatisfied(prog.GetAllConstraints(), x)


def _Explain(names: list[str]) -> str:
    kinds = list(dict.fromkeys(name.split("[")[0] for name in names))
    return "infeasible: " + ", ".join(kinds)
