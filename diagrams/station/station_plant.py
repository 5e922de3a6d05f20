"""The station's models in a MultibodyPlant: the one builder of every plant made from a
scenario (the simulated station's, the hardware station's, and the controller plants that
planners and IK solve on).

`MakeMultibodyPlant(scenario, model_instance_names)` follows the pattern of the
`manipulation` package's builder of the same name: the scenario's model directives, optionally
cut down to the named model instances. A weld whose parent is cut away becomes a weld to the
world at the parent's default pose, so a controller plant of one arm keeps the arm where the
station has it (e.g. the rover arm on its rover).
"""

from __future__ import annotations

import numpy as np
from pydrake.common.schema import Transform
from pydrake.geometry import SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import (
    FlattenModelDirectives,
    ModelDirective,
    ModelDirectives,
    ProcessModelDirectives,
)
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex

from guidedarm.diagrams.station.link_errors import AddCompliantBase, MoveJointFrames
from guidedarm.diagrams.station.model_paths import MakeParser
from guidedarm.diagrams.station.scenario import ArmConfig, StationScenario
from guidedarm.diagrams.station.station_errors import ArmErrors, ModelErrors
from guidedarm.systems.config_checks import (
    NON_NEGATIVE,
    CheckArgument,
    CheckConfig,
    CheckInstance,
    CheckNames,
)
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.plant_frames import GetScopedFrame
from guidedarm.systems.scene.hose_geometry import ReadCenterline, RegisterHose


def MakeMultibodyPlant(
    scenario: StationScenario,
    model_instance_names: list[str] | None = None,
    with_hose: bool = False,
    time_step: float = 0.0,
    scene_graph: SceneGraph | None = None,
    whole: MultibodyPlant | None = None,
) -> MultibodyPlant:
    """A finalized plant of the scenario's models (all, or only `model_instance_names`),
    the arms at their scenario initial positions. The hose is added only `with_hose`;
    controller plants leave it out (IK and planners must not know where it truly is).
    With `scene_graph` the plant is its geometry source (needed for any geometry query,
    and for the hose); the caller adds both to a diagram, or poses the plant's geometry
    with MultibodyPositionToGeometryPose. whole: the plant of all the scenario's models,
    when one is at hand (where a kept model is welded to a left-out one, its pose there is
    read from it; else it is built). Bad arguments raise ConfigurationError."""
    CheckInstance("scenario", scenario, StationScenario)
    CheckConfig(scenario, "scenario")
    if model_instance_names is not None:
        CheckNames("model_instance_names", model_instance_names)
    CheckArgument("time_step", time_step, NON_NEGATIVE)
    plant = MultibodyPlant(time_step)
    if scene_graph is not None:
        plant.RegisterAsSourceForSceneGraph(scene_graph)
    elif with_hose and scenario.hose is not None:
        raise ConfigurationError("a plant with the hose needs a SceneGraph (scene_graph=...)")
    CheckInstance("whole", whole, (MultibodyPlant, type(None)))
    AddStationModels(scenario, plant, model_instance_names, with_hose, whole=whole)
    plant.Finalize()
    SetInitialPositions(scenario, plant, model_instance_names)
    return plant


def AddStationModels(
    scenario: StationScenario,
    plant: MultibodyPlant,
    model_instance_names: list[str] | None = None,
    with_hose: bool = True,
    model_errors: dict[str, ModelErrors] | None = None,
    arm_errors: dict[str, ArmErrors] | None = None,
    whole: MultibodyPlant | None = None,
) -> None:
    """Adds the scenario's models (all, or the named instances) to an unfinalized plant;
    a welded model of `model_errors` (drawn, keyed by instance) where it truly is: its
    weld's X_PC followed by X_error; an arm of `arm_errors` with its link_errors
    (link_errors.MoveJointFrames). Errors are for the simulated station's plant only."""
    directives = scenario.directives
    if model_instance_names is not None:
        directives = _KeepInstances(scenario, model_instance_names, whole)
    if model_errors:
        directives = _MovedWelds(scenario, directives, model_errors)
    compliant = {a: e for a, e in (arm_errors or {}).items() if len(e.base_stiffness)}
    bases = []
    if compliant:
        directives, bases = _CutBaseWelds(directives, list(compliant))
    try:
        ProcessModelDirectives(ModelDirectives(directives=directives), MakeParser(plant))
    except Exception as e:
        raise _DirectivesError(e) from None
    for arm, parent, X_PC, child in bases:
        errors = compliant[arm]
        AddCompliantBase(
            plant,
            arm,
            GetScopedFrame(plant, parent, f"errors.arms.{arm}"),
            X_PC,
            GetScopedFrame(plant, child, f"errors.arms.{arm}"),
            list(errors.base_stiffness),
            list(errors.base_damping),
        )
    for arm, errors in (arm_errors or {}).items():
        if errors.link_errors:
            X_errors = [X.GetDeterministicValue() for X in errors.link_errors]
            GetArmInstance(plant, arm)  # a known instance, or one line naming the others
            MoveJointFrames(plant, arm, X_errors)
    if with_hose and scenario.hose is not None:
        RegisterHose(plant, HoseCenterlineInWorld(scenario), scenario.hose)


def HoseCenterlineInWorld(scenario: StationScenario) -> np.ndarray:
    """The hose's centerline (N, 3) in world coordinates (m): the CSV's points, given in
    `hose.frame`, moved by that frame's pose X_WF in the station (the frame must be fixed
    to the world)."""
    hose = scenario.hose
    if hose is None or not hose.centerline:
        raise ConfigurationError("hose.centerline: no centerline given")
    points = ReadCenterline(hose.centerline)
    if not hose.frame or hose.frame == "world":
        return points
    plant = MakeMultibodyPlant(scenario)
    return FixedFramePose(plant, hose.frame, "hose.frame").multiply(points.T).T


def FixedFramePose(plant: MultibodyPlant, scoped_name: str, key: str) -> RigidTransform:
    """X_WF of a frame of a station's plant (MakeMultibodyPlant) that is welded to the
    world (ConfigurationError naming `key` if it is missing or moves with a joint)."""
    frame = GetScopedFrame(plant, scoped_name, key)
    if frame.body().index() not in {b.index() for b in plant.GetBodiesWeldedTo(plant.world_body())}:
        raise ConfigurationError(f"{key}: frame '{scoped_name}' is not fixed to the world")
    return frame.CalcPoseInWorld(plant.CreateDefaultContext())


def SetInitialPositions(
    scenario: StationScenario,
    plant: MultibodyPlant,
    model_instance_names: list[str] | None = None,
) -> None:
    """Sets each arm's default joint positions (finalized plant) from the scenario."""
    for name, arm in scenario.arms.items():
        if model_instance_names is None or name in model_instance_names:
            instance = GetArmInstance(plant, name)
            plant.SetDefaultPositions(instance, ArmInitialPosition(plant, name, arm))
            ArmCalibrationOffset(scenario, name, plant.num_positions(instance))


def ArmCalibrationOffset(scenario: StationScenario, name: str, n: int) -> np.ndarray | None:
    """arms[name].calibration_file's joint offsets (rad), checked against the arm's n joints;
    None without a file."""
    offset = scenario.ArmCalibration(name)
    if offset is not None and offset.size != n:
        raise ConfigurationError(
            f"arms.{name}.calibration_file has {offset.size} joint offsets, the arm has {n} joints"
        )
    return offset


def ArmInitialPosition(plant: MultibodyPlant, name: str, arm: ArmConfig) -> np.ndarray:
    """The arm's initial joint positions (rad): the scenario's, checked against the model,
    or the model's defaults when the scenario gives none."""
    instance = GetArmInstance(plant, name)
    if len(arm.initial_position) == 0:
        return plant.GetDefaultPositions(instance)
    CheckJointPositions(plant, name, arm.initial_position, f"arms.{name}.initial_position")
    return np.asarray(arm.initial_position, float)


def CheckJointPositions(plant: MultibodyPlant, name: str, q: list[float], key: str) -> None:
    """Refuses (ConfigurationError naming `key`) joint positions of the arm `name` of a
    finalized plant that have the wrong count or lie outside the joint limits."""
    instance = GetArmInstance(plant, name)
    lower = plant.GetPositionsFromArray(instance, plant.GetPositionLowerLimits())
    upper = plant.GetPositionsFromArray(instance, plant.GetPositionUpperLimits())
    if len(q) != len(lower):
        raise ConfigurationError(f"{key} has {len(q)} values, the model has {len(lower)} joints")
    values = np.asarray(q, float)
    outside = np.flatnonzero(~((lower <= values) & (values <= upper)))
    if outside.size:
        j = int(outside[0])
        raise ConfigurationError(
            f"{key}[{j}] = {values[j]:g} rad is outside the joint limits "
            f"[{lower[j]:.4g}, {upper[j]:.4g}] of {name}"
        )


def ArmAndAttachments(plant: MultibodyPlant, arm: str) -> list[str]:
    """The model instances (names) of the arm `arm` of `plant` and of everything its joints
    move (gripper, tools): the models of its controller plant (MakeMultibodyPlant)."""
    instance = GetArmInstance(plant, arm)
    moved = plant.GetBodiesKinematicallyAffectedBy(plant.GetJointIndices(instance))
    names = {plant.GetModelInstanceName(plant.get_body(b).model_instance()) for b in moved}
    return sorted(names | {arm})


def GetArmInstance(plant: MultibodyPlant, name: str) -> ModelInstanceIndex:
    """The model instance called `name`, or a ConfigurationError listing the known ones."""
    if not plant.HasModelInstanceNamed(name):
        known = [
            plant.GetModelInstanceName(ModelInstanceIndex(i))
            for i in range(plant.num_model_instances())
        ]
        raise ConfigurationError(f"arms.{name}: no model instance '{name}' (have {known})")
    return plant.GetModelInstanceByName(name)


def _KeepInstances(
    scenario: StationScenario, names: list[str], whole: MultibodyPlant | None
) -> list[ModelDirective]:
    """The flattened directives of the named instances; welds to a dropped parent become
    welds to the world at that parent's default pose in the whole station (`whole`, or a
    plant built for it)."""
    package_map = MakeParser(MultibodyPlant(0.0)).package_map()
    try:
        flat = FlattenModelDirectives(ModelDirectives(directives=scenario.directives), package_map)
    except Exception as e:
        raise _DirectivesError(e) from None
    known = {d.add_model.name for d in flat.directives if d.add_model}
    missing = sorted(set(names) - known)
    if missing:
        raise ConfigurationError(
            f"model directives: no model instance {missing} (have {sorted(known)})"
        )
    kept = []
    for directive in flat.directives:
        if directive.add_model:
            if directive.add_model.name in names:
                kept.append(directive)
        elif directive.add_weld:
            weld = directive.add_weld
            if _Instance(weld.child) not in names:
                continue
            if weld.parent != "world" and _Instance(weld.parent) not in names:
                whole = whole or MakeMultibodyPlant(scenario)
                X_WP = whole.GetFrameByName(
                    _Local(weld.parent), whole.GetModelInstanceByName(_Instance(weld.parent))
                ).CalcPoseInWorld(whole.CreateDefaultContext())
                X_PC = weld.X_PC.GetDeterministicValue() if weld.X_PC else RigidTransform()
                weld.parent = "world"
                weld.X_PC = Transform(X_WP @ X_PC)
            kept.append(directive)
        elif directive.add_frame and _Instance(directive.add_frame.X_PF.base_frame or "") in names:
            kept.append(directive)
    return kept


def _MovedWelds(
    scenario: StationScenario, directives: list[ModelDirective], errors: dict[str, ModelErrors]
) -> list[ModelDirective]:
    """The flattened directives with the weld of each model of `errors` (the weld whose
    child is in that instance) moved by its X_error; ConfigurationError for a model that
    no directive welds."""
    package_map = MakeParser(MultibodyPlant(0.0)).package_map()
    try:
        flat = FlattenModelDirectives(ModelDirectives(directives=directives), package_map)
    except Exception as e:
        raise _DirectivesError(e) from None
    moved = set()
    for directive in flat.directives:
        weld = directive.add_weld
        if weld and _Instance(weld.child) in errors and _Instance(weld.child) not in moved:
            X_PC = weld.X_PC.GetDeterministicValue() if weld.X_PC else RigidTransform()
            X_error = errors[_Instance(weld.child)].X_error.GetDeterministicValue()
            weld.X_PC = Transform(X_PC @ X_error)
            moved.add(_Instance(weld.child))
    missing = sorted(set(errors) - moved)
    if missing:
        raise ConfigurationError(
            f"errors.models.{missing[0]}: no weld of a model instance '{missing[0]}' in the "
            "directives (X_error moves a welded model)"
        )
    return flat.directives


def _CutBaseWelds(
    directives: list[ModelDirective], arms: list[str]
) -> tuple[list[ModelDirective], list[tuple[str, str, RigidTransform, str]]]:
    """The flattened directives without the weld that holds each arm of `arms` (the weld
    whose child is in the arm), and those welds as (arm, parent, X_PC, child)."""
    package_map = MakeParser(MultibodyPlant(0.0)).package_map()
    flat = FlattenModelDirectives(ModelDirectives(directives=directives), package_map)
    kept, cut = [], []
    for directive in flat.directives:
        weld = directive.add_weld
        if weld and _Instance(weld.child) in arms:
            X_PC = weld.X_PC.GetDeterministicValue() if weld.X_PC else RigidTransform()
            cut.append((_Instance(weld.child), weld.parent, X_PC, weld.child))
        else:
            kept.append(directive)
    missing = sorted(set(arms) - {arm for arm, *_ in cut})
    if missing:
        raise ConfigurationError(
            f"errors.arms.{missing[0]}.base_stiffness: no weld holds the arm's base"
        )
    return kept, cut


def _DirectivesError(e: Exception) -> ConfigurationError:
    """Drake's refusal of a directive (a missing or unparsable file, an unknown package)
    as one line."""
    message = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
    return ConfigurationError(f"model directives: {message}")


def _Instance(scoped_name: str) -> str:
    return scoped_name.rsplit("::", 1)[0] if "::" in scoped_name else ""


def _Local(scoped_name: str) -> str:
    return scoped_name.rsplit("::", 1)[-1]
