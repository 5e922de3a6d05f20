"""The panel operation's start joints, chosen in its prepare step: an explicit joint vector
checked against the cell, or a random camera pose in front of the panel solved by inverse
kinematics, so that a start the cell refuses is refused before the run is announced."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant

from guidedarm.diagrams.panel.panel_camera_rig import LookAt
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station_plant import AddStationModels
from guidedarm.diagrams.tasks.common.cell_collisions import CellCollisions, ModelNames
from guidedarm.diagrams.tasks.panel_operation.builder import MakeCameraArmKinematics
from guidedarm.diagrams.tasks.panel_operation.scenario import (
    PanelOperationScenario,
    StartConfig,
)
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.marker_pose_estimator_math import PanelSpec
from guidedarm.systems.panel.panel_operation_math import CameraArmKinematics

# Random camera poses tried for one seed before the start is refused.
START_DRAWS = 50


@dataclass(frozen=True)
class PanelCell:
    """What choosing a start needs: the controller's camera and tip kinematics, collision
    queries of the arm in the cell (touching the panel allowed), and X_WP, the panel
    plate's true pose in the world (where the station places it, its drawn errors
    included)."""

    kinematics: CameraArmKinematics
    collisions: CellCollisions
    X_WP: RigidTransform


def MakePanelCell(scenario: PanelOperationScenario, station: StationScenario) -> PanelCell:
    """The PanelCell of `scenario` on `station` (its station scenario with the panel model
    generated and its errors drawn)."""
    kinematics = MakeCameraArmKinematics(
        station, scenario.arm, scenario.camera, scenario.tip_frame, scenario.CameraMount()
    )
    collisions = CellCollisions(
        station, scenario.arm, ModelNames(kinematics.plant), [scenario.panel_model]
    )
    return PanelCell(kinematics, collisions, TruePanelPose(station, scenario.panel_model))


def TruePanelPose(station: StationScenario, panel_model: str) -> RigidTransform:
    """X_WP: the `plate` frame of `panel_model` in the world, where the simulated station
    places it (its welded models' drawn errors applied, as MakeStation does)."""
    errors = station.WithErrorsDrawn(None).errors
    plant = MultibodyPlant(0.0)
    AddStationModels(station, plant, model_errors=errors.models, arm_errors=errors.arms)
    plant.Finalize()
    instance = plant.GetModelInstanceByName(panel_model)
    return plant.GetFrameByName("plate", instance).CalcPoseInWorld(plant.CreateDefaultContext())


def PanelStartPose(
    scenario: PanelOperationScenario, panel: PanelSpec, cell: PanelCell
) -> np.ndarray:
    """The start joints (rad): scenario.start.position, refused (ConfigurationError) when it
    touches the cell or the arm itself; else SampleStartPose from the scenario's
    random_seed."""
    if scenario.start.position:
        q_start = np.asarray(scenario.start.position, float)
        cell.collisions.Refuse(q_start, f"the {scenario.arm} start pose")
        return q_start
    return SampleStartPose(scenario.start, panel, cell, scenario.random_seed)


def SampleStartPose(start: StartConfig, panel: PanelSpec, cell: PanelCell, seed: int) -> np.ndarray:
    """Start joints (rad) whose camera sees the panel from a random pose (`start`: distance,
    tilt from the panel normal, aim point near the markers' middle), by inverse kinematics
    from the arm's default position, clear of the cell and of the arm itself; a pose that
    has no IK solution or collides is drawn again, up to START_DRAWS times, then
    ConfigurationError."""
    rng = np.random.default_rng(seed)
    centres = [m.X_PM.GetDeterministicValue().translation() for m in panel.markers]
    middle = np.mean(centres, axis=0)
    plant = cell.kinematics.plant
    q_default = plant.GetPositions(plant.CreateDefaultContext())
    for _ in range(START_DRAWS):
        aim = middle + np.append(rng.uniform(-1, 1, 2) * start.aim_offset_m, 0.0)
        tilt = np.radians(rng.uniform(0.0, start.max_tilt_deg))
        azimuth = rng.uniform(0.0, 2 * np.pi)
        direction = [np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)]
        p_PC = aim + rng.uniform(*start.distance_m) * np.asarray(direction)
        X_WT = cell.X_WP @ LookAt(p_PC, aim) @ cell.kinematics.X_CT
        q = cell.kinematics.SolveTip(X_WT, q_default)
        if q is not None and not cell.collisions.Contacts(q):
            return q
    raise ConfigurationError(f"no reachable start pose found for seed {seed}")
