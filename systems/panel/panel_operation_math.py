"""Mathematics of the panel operation of Annusewicz-Mistal et al., "Autonomous Manipulator
of a Mobile Robot Based on a Vision System" (section 2.4): the sequence's parameters, the
camera arm's kinematics and tip IK, the target poses of the sequence's points, the planner's
frames and the minimum-jerk profile of the joint moves. Plain classes, testable without a
Diagram; PanelOperation (panel_operation.py) runs them.

Units: m, rad, s. Frames: W the controller plant's world, P panel, C camera, T gripper tip,
B the planner's base, N the planner's TCP.
"""

import typing
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame
from pydrake.solvers import Solve

from guidedarm.systems.config_checks import (
    CheckFields,
    CheckInstance,
    NonNegative,
    Positive,
    TextChoices,
)
from guidedarm.systems.markers.marker_pose_estimator_math import PanelSpec, SwitchSpec
from guidedarm.systems.plant_frames import CheckFrame, CheckPlant

# The camera looks straight at the panel: image x = panel x, image y = -panel y.
R_PC_STRAIGHT = RotationMatrix(np.diag([1.0, -1.0, -1.0]))
Motion = Literal["joint_trajectory", "planner"]
MOTIONS = typing.get_args(Motion)


@TextChoices
@dataclass
class PanelOperationConfig:
    """Parameters of the sequence (see PanelOperation in panel_operation.py).

    base_distance_m: camera distance from the panel plane at the base point (m).
    measure_standoff_m: tip distance in front of the switch at the last measurement (m).
    retake_distances_m: camera distances from the panel plane (m) of further views straight
        in front of the markers, taken in turn when the estimator refuses the base point's
        view (on_marker_loss `continue`); the press is never aimed with the start's estimate
        alone (the start is far away, in another arm configuration).
    approach_standoff_m: tip distance in front of the switch cap (m) from which the tip
        presses, and to which it returns, straight along the switch's axis; the sideways
        correction of the last measurement is made before, clear of the caps.
    retract_standoff_m: tip distance in front of the switch after the press (m).
    max_joint_speed: peak joint speed of the joint-trajectory moves (rad/s).
    settle_time_s: wait after a move before an image is analysed (s).
    stationary_speed: every joint slower than this counts as standing still (rad/s).
    press_hold_s: time the tip is held pressed (s).
    on_marker_loss: `abort` (stop and fail) or `continue` (keep the last valid estimate)
        when no marker is seen at a later measurement point.
    update_period_s: period of the sequencer's update (s).
    motion: `joint_trajectory` (IK + minimum-jerk joint segments) or `planner` (each move
        a task of the acceleration-level planner).
    """

    base_distance_m: float = Positive(0.17)
    measure_standoff_m: float = Positive(0.09)
    retake_distances_m: list[float] = Positive(factory=lambda: [0.25, 0.32])
    approach_standoff_m: float = Positive(0.015)
    retract_standoff_m: float = Positive(0.06)
    max_joint_speed: float = Positive(0.75)
    settle_time_s: float = NonNegative(0.3)
    stationary_speed: float = Positive(0.002)
    press_hold_s: float = NonNegative(0.3)
    on_marker_loss: Literal["abort", "continue"] = "continue"
    update_period_s: float = Positive(0.01)
    motion: Motion = "joint_trajectory"

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad parameter."""
        CheckFields(self)


class CameraArmKinematics:
    """Camera and tip poses of one arm of `plant` (all its positions are that arm's joints),
    and inverse kinematics for the tip. The camera frame C is `camera_frame` F moved by
    X_FC (m)."""

    def __init__(
        self,
        plant: MultibodyPlant,
        camera_frame: Frame,
        tip_frame: Frame,
        X_FC: RigidTransform | None = None,
    ) -> None:
        CheckPlant("plant", plant)
        CheckFrame("camera_frame", camera_frame, plant)
        CheckFrame("tip_frame", tip_frame, plant)
        CheckInstance("X_FC", X_FC, (RigidTransform, type(None)))
        self.plant = plant
        self.camera_frame = camera_frame
        self.tip_frame = tip_frame
        self._X_FC = X_FC if X_FC is not None else RigidTransform()
        self._context = plant.CreateDefaultContext()
        self.X_CT = self.X_WC(plant.GetPositions(self._context)).inverse() @ self.X_WT(
            plant.GetPositions(self._context)
        )

    def X_WC(self, q: np.ndarray) -> RigidTransform:
        self.plant.SetPositions(self._context, q)
        return self.camera_frame.CalcPoseInWorld(self._context) @ self._X_FC

    def X_WT(self, q: np.ndarray) -> RigidTransform:
        self.plant.SetPositions(self._context, q)
        return self.tip_frame.CalcPoseInWorld(self._context)

    def SolveTip(self, X_WT: RigidTransform, q_guess: np.ndarray) -> np.ndarray | None:
        """Joint positions putting the tip at X_WT (1e-6 m, 1e-5 rad), near q_guess.

        Facing a panel, a six-joint arm's wrist is often close to straight (a singularity:
        only the sum of the two wrist rolls is fixed), where SNOPT with the nearest-to-guess
        cost sometimes stalls; then the solve is repeated without the cost (from the guess,
        then from perturbed guesses) and the solution polished towards the guess.
        """
        q = self._SolveTipOnce(X_WT, q_guess, q_guess)
        if q is not None:
            return q
        rng = np.random.default_rng(0)
        for attempt in range(5):
            start = q_guess + (rng.normal(0, 0.2, q_guess.size) if attempt else 0.0)
            q = self._SolveTipOnce(X_WT, start, None)
            if q is not None:
                polished = self._SolveTipOnce(X_WT, q, q_guess)
                return q if polished is None else polished
        return None

    def _SolveTipOnce(self, X_WT: RigidTransform, start: np.ndarray, nearest: np.ndarray | None):
        ik = InverseKinematics(self.plant)
        p = X_WT.translation()
        world = self.plant.world_frame()
        ik.AddPositionConstraint(self.tip_frame, np.zeros(3), world, p - 1e-6, p + 1e-6)
        ik.AddOrientationConstraint(world, X_WT.rotation(), self.tip_frame, RotationMatrix(), 1e-5)
        prog = ik.get_mutable_prog()
        q = ik.q()
        if nearest is not None:
            prog.AddQuadraticErrorCost(np.eye(len(start)), nearest, q)
        prog.SetInitialGuess(q, start)
        result = Solve(prog)
        return result.GetSolution(q) if result.is_success() else None


class PanelTargets:
    """Tip poses X_PT of the sequence's points for `switch` of `panel`."""

    def __init__(
        self,
        panel: PanelSpec,
        switch: SwitchSpec,
        config: PanelOperationConfig,
        X_CT: RigidTransform,
    ) -> None:
        self._switch = np.asarray(switch.position, float)
        centres = [m.X_PM.GetDeterministicValue().translation() for m in panel.markers]
        self._middle = np.mean(centres, axis=0)
        self._config = config
        self._X_CT = X_CT

    def base(self, distance_m: float | None = None) -> RigidTransform:
        """The camera straight in front of the markers' middle, `distance_m` from the panel
        plane (default base_distance_m)."""
        distance_m = self._config.base_distance_m if distance_m is None else distance_m
        p_PC = self._middle + [0.0, 0.0, distance_m]
        return RigidTransform(R_PC_STRAIGHT, p_PC) @ self._X_CT

    def at_switch(self, standoff_m: float) -> RigidTransform:
        R_PT = R_PC_STRAIGHT @ self._X_CT.rotation()
        return RigidTransform(R_PT, self._switch + [0.0, 0.0, standoff_m])


def PressDepth(switch: SwitchSpec, depth_std_m: float) -> float:
    """How far past the cap's rest face the tip aims (m): the switch's full travel, so the
    tip may stop up to travel_m - on_travel_m short and still switch it on; deeper, to
    on_travel_m + 3 depth_std_m, when the estimate's reported depth standard deviation
    (m) leaves less than that margin (the cap then rests on its stop and the arm pushes)."""
    return max(switch.travel_m, switch.on_travel_m + 3.0 * depth_std_m)


@dataclass
class PlannerFrames:
    """For motion "planner": X_WB, the planner's base frame B in W, and X_TN, the planner's
    TCP frame N on the gripper tip T. N is T rotated so that the Z-Y-X Euler angles of the
    targets stay away from the representation's singularity at pitch +-90 deg."""

    X_WB: RigidTransform
    X_TN: RigidTransform

    def TaskRow(self, X_WT: RigidTransform) -> np.ndarray:
        """[x, y, z, roll, pitch, yaw] of N in B (m, rad) when the tip is at X_WT."""
        X_BN = self.X_WB.inverse() @ X_WT @ self.X_TN
        return np.concatenate([X_BN.translation(), RollPitchYaw(X_BN.rotation()).vector()])


def MinimumJerk(tau: float) -> float:
    """The minimum-jerk profile s(tau) on [0, 1] (0 and 1 outside); peak ds/dtau 1.875."""
    tau = min(max(tau, 0.0), 1.0)
    return tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)
