"""Calibration photos in simulation: the arm moves its camera through generated views of a
ChArUco board placed in the cell, and the station's camera renders each.

The board (models/calibration/charuco_board.sdf, board.yaml) stands BOARD_STANDOFF_M in
front of the scenario's panel (welded to `<panel_model>::plate`), facing the arm. Views come
from CalibrationViews (distance, tilt, roll, the board across the image), each reached by
inverse kinematics on the controller's own model of the arm; the station simulates the arm
settling at the commanded joints, and each view records what a real cell records: the image
(rendered at the scenario's supersampling, reduced by ImageDegradation) and the pose X_WF of
the camera's mount frame F from the measured joints and the controller's model.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from pydrake.common.schema import Transform
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.parsing import AddModel, AddWeld, ModelDirective
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from guidedarm.diagrams.calibration.board_assets import DEFAULT_BOARD_FILE
from guidedarm.diagrams.calibration.calibration_files import LoadBoardSpec
from guidedarm.diagrams.panel.panel_files import IntrinsicsFromCameraConfig
from guidedarm.diagrams.run_preparation import WithErrorsDrawn
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.diagrams.tasks.panel_operation import MakeCameraArmKinematics, PanelOperationScenario
from guidedarm.diagrams.tasks.panel_operation.run import SupersampledStation
from guidedarm.systems.calibration.calibration_views import CalibrationViews
from guidedarm.systems.cell_errors.camera_errors import CameraErrors
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.image_degradation import DegradationConfig, ImageDegradation
from guidedarm.systems.markers.marker_pose_estimator_math import CameraIntrinsics

BOARD_MODEL = "calibration_board"
# The board 40 mm in front of the panel plate (clear of the 12 mm switch caps), centred on
# the markers' middle, upright as printed (x_B along the panel's x, y_B down).
BOARD_STANDOFF_M = 0.04
# Simulated time for the arm to settle at each view (s).
SETTLE_TIME_S = 0.3


@dataclass
class SimulatedView:
    """One photo: its name, RGBA image, the measured joints and X_WF from them."""

    name: str
    image: np.ndarray
    q_measured: np.ndarray
    X_WF: RigidTransform


class SimulatedCalibrationCell:
    """The scenario's station with the board; Photos(count, seed) takes the views."""

    def __init__(self, scenario: PanelOperationScenario) -> None:
        if not isinstance(scenario, PanelOperationScenario):
            raise ConfigurationError(
                "calibration in simulation needs a panel_operation scenario (an arm carrying "
                f"a camera in front of a panel), got task '{getattr(scenario, 'task', '?')}'"
            )
        scenario = WithErrorsDrawn(scenario)
        self.scenario = scenario
        self.spec = LoadBoardSpec(DEFAULT_BOARD_FILE)
        camera = scenario.station.cameras[scenario.camera]
        k = scenario.supersampling
        self.nominal_intrinsics: CameraIntrinsics = IntrinsicsFromCameraConfig(camera)
        self.estimator_intrinsics = scenario.EstimatorIntrinsics() or self.nominal_intrinsics
        station_scenario = self._StationWithBoard(
            scenario, SupersampledStation(scenario.station, scenario.camera, camera, k)
        )
        self.kinematics = MakeCameraArmKinematics(
            station_scenario, scenario.arm, scenario.camera, scenario.tip_frame
        )
        builder = DiagramBuilder()
        self.station = builder.AddNamedSystem("station", MakeStation(station_scenario))
        degrade = builder.AddNamedSystem(
            "image_degradation", ImageDegradation(DegradationConfig(supersampling=k))
        )
        builder.Connect(
            self.station.GetOutputPort(f"{scenario.camera}.rgb_image"), degrade.get_input_port()
        )
        self._image_port = degrade.get_output_port()
        self.diagram = builder.Build()
        self.simulator = Simulator(self.diagram)
        self.plant = self.station.GetSubsystemByName("plant")
        plant_context = self.plant.CreateDefaultContext()
        self.X_WB = self.plant.GetFrameByName(
            "board", self.plant.GetModelInstanceByName(BOARD_MODEL)
        ).CalcPoseInWorld(plant_context)
        config = station_scenario.cameras[scenario.camera]
        self.X_FC_nominal = (
            config.X_PB.GetDeterministicValue() @ config.X_BC.GetDeterministicValue()
        )
        self.mount_frame = config.X_PB.base_frame
        # The truth of the simulated cell: the camera file's intrinsics and the nominal
        # mount, with the drawn station.errors of the camera.
        errors = scenario.station.errors.cameras.get(scenario.camera, CameraErrors())
        self.true_intrinsics = TrueIntrinsics(self.nominal_intrinsics, errors)
        self.true_X_FC = self.X_FC_nominal @ errors.X_mount_error.GetDeterministicValue()
        # What the measured joints lack: the drawn offsets less those the scenario's
        # calibration_file already adds.
        n = self.kinematics.plant.num_positions()
        arm_errors = scenario.station.errors.arms.get(scenario.arm)
        offset = np.zeros(n)
        if arm_errors is not None and arm_errors.joint_offset:
            offset = np.asarray(arm_errors.joint_offset, float)
        calibration = scenario.station.ArmCalibration(scenario.arm)
        self.true_joint_offset = offset - (0.0 if calibration is None else calibration)
        stiffness = arm_errors.joint_stiffness if arm_errors is not None else []
        self.true_joint_stiffness = np.asarray(stiffness or np.full(n, np.inf), float)
        self._torque_context = self.kinematics.plant.CreateDefaultContext()

    def X_WF(self, q: np.ndarray) -> RigidTransform:
        """The mount frame F's pose in W at joints q (rad) on the controller's model."""
        return self.kinematics.X_WC(q) @ self.X_FC_nominal.inverse()

    def HoldingTorque(self, q: np.ndarray) -> np.ndarray:
        """The gravity torque (N m) each joint holds at q (rad), on the controller's model."""
        plant = self.kinematics.plant
        plant.SetPositions(self._torque_context, q)
        return -plant.CalcGravityGeneralizedForces(self._torque_context)

    def TrueMountInMeasuredFlange(self) -> RigidTransform:
        """The true X_FC in the frame F that the last joint's *measured* angle puts: the
        mount a kinematic calibration identifies (its last joint's offset is a turn of the
        mount, joint_bundle_adjustment.py); true_X_FC when that offset is 0."""
        q = self.kinematics.plant.GetPositions(self.kinematics.plant.CreateDefaultContext())
        last = np.zeros_like(q)
        last[-1] = self.true_joint_offset[-1]
        return self.X_WF(q).inverse() @ self.X_WF(q + last) @ self.true_X_FC

    def _StationWithBoard(self, scenario, station: StationScenario) -> StationScenario:
        width, height = self.spec.size_m()
        X_plate_B = RigidTransform(
            RollPitchYaw(np.pi, 0, 0), [0.06 - width / 2, height / 2 - 0.0125, BOARD_STANDOFF_M]
        )
        board = [
            ModelDirective(
                add_model=AddModel(
                    file="package://guidedarm/calibration/charuco_board.sdf", name=BOARD_MODEL
                )
            ),
            ModelDirective(
                add_weld=AddWeld(
                    parent=f"{scenario.panel_model}::plate",
                    child=f"{BOARD_MODEL}::board",
                    X_PC=Transform(X_plate_B),
                )
            ),
        ]
        return dataclasses.replace(station, directives=[*station.directives, *board])

    def Photos(self, count: int, seed: int) -> list[SimulatedView]:
        """`count` views of the board (the camera's believed pose X_BC from CalibrationViews,
        reached by IK; views the arm cannot reach are replaced by others)."""
        candidates = CalibrationViews(
            self.spec,
            self.estimator_intrinsics,
            6 * count,
            seed,
            distance_m=(0.28, 0.45),
            max_tilt_deg=30.0,
        )
        kin = self.kinematics
        q_guess = kin.plant.GetPositions(kin.plant.CreateDefaultContext())
        views = []
        for X_BC in candidates:
            q = kin.SolveTip(self.X_WB @ X_BC @ kin.X_CT, q_guess)
            if q is None:
                continue
            views.append(self._Take(f"view{len(views):02d}", q))
            if len(views) == count:
                return views
        raise ConfigurationError(
            f"the arm reaches only {len(views)} of the {count} views of the board wanted"
        )

    def _Take(self, name: str, q: np.ndarray) -> SimulatedView:
        context = self.simulator.get_mutable_context()
        arm = self.scenario.arm
        station_context = self.station.GetMyMutableContextFromRoot(context)
        instance = self.plant.GetModelInstanceByName(arm)
        plant_context = self.plant.GetMyMutableContextFromRoot(context)
        self.plant.SetPositions(plant_context, instance, q)
        self.plant.SetVelocities(plant_context, instance, np.zeros_like(q))
        interpolator = self.station.GetSubsystemByName(f"{arm}.command_interpolator")
        interpolator.set_initial_position(interpolator.GetMyMutableContextFromRoot(context), q)
        self.station.GetInputPort(f"{arm}.position_commanded").FixValue(station_context, q)
        self.simulator.AdvanceTo(context.get_time() + SETTLE_TIME_S)
        q_measured = self.station.GetOutputPort(f"{arm}.position_measured").Eval(station_context)
        image = np.array(
            self._image_port.Eval(self._image_port.get_system().GetMyContextFromRoot(context)).data
        )
        return SimulatedView(name, image, np.array(q_measured), self.X_WF(q_measured))


def TrueIntrinsics(nominal: CameraIntrinsics, errors: CameraErrors) -> CameraIntrinsics:
    """The intrinsics of the images the station renders: the camera file's plus the drawn
    focal and principal point errors, with the drawn lens distortion."""
    dfx, dfy = errors.focal_error_px or (0.0, 0.0)
    dcx, dcy = errors.principal_point_error_px or (0.0, 0.0)
    return dataclasses.replace(
        nominal,
        fx=nominal.fx + dfx,
        fy=nominal.fy + dfy,
        cx=nominal.cx + dcx,
        cy=nominal.cy + dcy,
        distortion=list(errors.distortion) or [0.0] * 5,
    )
