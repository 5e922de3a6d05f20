"""Public LeafSystems and solvers refuse bad constructor arguments with one ConfigurationError
naming the argument, and still build from good ones."""

import dataclasses

import numpy as np
import pytest
from pydrake.geometry import SceneGraph
from pydrake.multibody.plant import MultibodyPlant

from guidedarm.diagrams.panel.panel_files import DEFAULT_PANEL_FILE, LoadPanelSpec
from guidedarm.diagrams.station.scenario import ArmConfig, StationScenario
from guidedarm.diagrams.station.scene_views import SceneDirectives
from guidedarm.diagrams.station.station_plant import AddStationModels, MakeMultibodyPlant
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.image_degradation import DegradationConfig, DegradeImage
from guidedarm.systems.markers.marker_pose_estimator import MarkerPoseEstimator
from guidedarm.systems.markers.marker_pose_estimator_math import CameraIntrinsics, MarkerPoseSolver
from guidedarm.systems.path_following.differential_ik_servo import DifferentialIkServo
from guidedarm.systems.path_following.joint_moves import MotionLimits
from guidedarm.systems.path_following.path_follower import FollowerConfig
from guidedarm.systems.path_following.tool_pose_ik import ToolPoseIk
from guidedarm.systems.path_following.tool_pose_ik_math import ToolPoseIkConfig, ToolPoseSolver
from guidedarm.systems.planning.acceleration_planner_kinematics import ArmKinematics
from guidedarm.systems.tof.tof_errors import ToFErrors
from guidedarm.systems.tof.tof_tool_sensor import ToFToolConfig, ToFToolSensor

HOME = [-1.5708, -1.5708, -2.356, -0.785, 1.5708, 0.785]
NAN = float("nan")
SCENARIO = StationScenario(
    directives=SceneDirectives("ur10e_tof_tool"), arms={"ur10e": ArmConfig(initial_position=HOME)}
)
ARM = MakeMultibodyPlant(SCENARIO, ["ur10e"])
ARM_INSTANCE = ARM.GetModelInstanceByName("ur10e")
TOOL0 = ARM.GetFrameByName("tool0", ARM_INSTANCE)
OTHER = MakeMultibodyPlant(SCENARIO, ["ur10e"])


def _Unfinalized() -> MultibodyPlant:
    plant = MultibodyPlant(0.0)
    AddStationModels(SCENARIO, plant, ["ur10e"])
    return plant


UNFINALIZED = _Unfinalized()


def Servo(**changes):
    arguments = dict(
        plant=ARM,
        frame=TOOL0,
        q_initial=np.array(HOME),
        period=0.008,
        max_speed=1.0,
        max_acceleration=5.0,
        gain=10.0,
        weights=np.ones(6),
        damping=0.01,
    )
    arguments.update(changes)
    return DifferentialIkServo(**arguments)


def Solver(**changes):
    arguments = dict(plant=ARM, instance=ARM_INSTANCE, frame=TOOL0, limits=ToolPoseIkConfig())
    arguments.update(changes)
    return ToolPoseSolver(**arguments)


def Intrinsics(**changes):
    return MarkerPoseSolver(
        dataclasses.replace(CameraIntrinsics(), **changes), LoadPanelSpec(DEFAULT_PANEL_FILE)
    )


BAD = {
    "servo q_initial 5": (lambda: Servo(q_initial=np.array(HOME[:5])), "q_initial", "6 numbers"),
    "servo q_initial nan": (lambda: Servo(q_initial=[NAN] * 6), "q_initial[0]", "finite"),
    "servo period -1": (lambda: Servo(period=-1.0), "period", "> 0"),
    "servo max_speed nan": (lambda: Servo(max_speed=NAN), "max_speed", "finite"),
    "servo max_speed -1": (lambda: Servo(max_speed=-1.0), "max_speed", "> 0"),
    "servo max_acceleration 0": (lambda: Servo(max_acceleration=0.0), "max_acceleration", "> 0"),
    "servo gain nan": (lambda: Servo(gain=NAN), "gain", "finite"),
    "servo weights 3": (lambda: Servo(weights=np.ones(3)), "weights", "6 numbers"),
    "servo weights nan": (lambda: Servo(weights=np.full(6, NAN)), "weights[0]", "finite"),
    "servo weights -1": (lambda: Servo(weights=-np.ones(6)), "weights[0]", ">= 0"),
    "servo weights 0": (lambda: Servo(weights=np.zeros(6)), "weights", "at least one"),
    "servo damping 2": (lambda: Servo(damping=2.0), "damping", "in [0.001, 1]"),
    "servo feedforward 1.5": (lambda: Servo(feedforward=1.5), "feedforward", "in [0, 1]"),
    "servo unfinalized": (
        lambda: Servo(plant=UNFINALIZED, frame=UNFINALIZED.world_frame()),
        "plant",
        "finalized",
    ),
    "servo frame of another plant": (
        lambda: Servo(frame=OTHER.GetFrameByName("tool0")),
        "frame",
        "another plant",
    ),
    "solver p_FQ 2": (lambda: Solver(p_FQ=[0.1, 0.2]), "p_FQ", "3 numbers"),
    "solver frame of another plant": (
        lambda: Solver(frame=OTHER.GetFrameByName("tool0")),
        "frame",
        "another plant",
    ),
    "solver unfinalized": (lambda: Solver(plant=UNFINALIZED), "plant", "finalized"),
    "ik period 0": (lambda: ToolPoseIk(Solver(), 0.0), "period", "> 0"),
    "ik q_initial 5": (lambda: ToolPoseIk(Solver(), 0.02, np.zeros(5)), "q_initial", "6 numbers"),
    "ik solver None": (lambda: ToolPoseIk(None, 0.02), "solver", "ToolPoseSolver"),
    "kinematics unfinalized": (
        lambda: ArmKinematics(
            UNFINALIZED, ARM_INSTANCE, UNFINALIZED.world_frame(), UNFINALIZED.world_frame()
        ),
        "plant",
        "finalized",
    ),
    "kinematics min_singular_value 0": (
        lambda: ArmKinematics(ARM, ARM_INSTANCE, ARM.world_frame(), TOOL0, 0.0),
        "min_singular_value",
        "> 0",
    ),
    "tof plant without SceneGraph": (
        lambda: ToFToolSensor(MakeMultibodyPlant(SCENARIO), ToFToolConfig()),
        "plant",
        "SceneGraph",
    ),
    "tof unfinalized": (lambda: ToFToolSensor(UNFINALIZED, ToFToolConfig()), "plant", "finalized"),
    "tof seed 1.5": (lambda: ToFToolConfig(seed=1.5).Validate(), "seed", "integer"),
    "tof seed 'a'": (lambda: ToFToolConfig(seed="a").Validate(), "seed", "integer"),
    "tof rings 3.5": (lambda: ToFToolConfig(rings=3.5).Validate(), "rings", "integer"),
    "tof period '0.02'": (lambda: ToFToolConfig(period="0.02").Validate(), "period", "number"),
    "tof offset 'a'": (
        lambda: ToFErrors(offset=[0.0, "a", 0.0, 0.0, 0.0, 0.0]).Validate(),
        "offset[1]",
        "number",
    ),
    "follower readings 2.5": (
        lambda: FollowerConfig(readings=2.5).Validate(),
        "readings",
        "integer",
    ),
    "follower lost_limit '3'": (
        lambda: FollowerConfig(lost_limit="3").Validate(),
        "lost_limit",
        "integer",
    ),
    "follower max_steps True": (
        lambda: FollowerConfig(max_steps=True).Validate(),
        "max_steps",
        "integer",
    ),
    "motion tool_speed nan": (
        lambda: MotionLimits(tool_speed=NAN).Validate(),
        "tool_speed",
        "finite",
    ),
    "intrinsics fx -1": (lambda: Intrinsics(fx=-1.0), "fx", "must be in [1, 1e+06]"),
    "intrinsics width 0": (lambda: Intrinsics(width=0), "width", "must be in [1, 100000]"),
    "intrinsics cx nan": (lambda: Intrinsics(cx=NAN), "cx", "finite"),
    "estimator solver None": (lambda: MarkerPoseEstimator(None), "solver", "MarkerPoseSolver"),
}


@pytest.mark.parametrize("make, key, why", BAD.values(), ids=BAD.keys())
def test_a_bad_argument_is_refused_naming_it(make, key, why):
    with pytest.raises(ConfigurationError) as error:
        make()
    message = str(error.value)
    assert f"key '{key}':" in message and why in message
    assert "\n" not in message


def test_the_path_follower_refuses_a_bad_period():
    from guidedarm.diagrams.tasks.path_following.setup import MakeSetup
    from guidedarm.diagrams.tasks.registry import LoadScenario
    from guidedarm.systems.path_following.path_follower import PathFollower

    _, scenario, _ = LoadScenario("path_following", [])
    s = MakeSetup(scenario)
    PathFollower(s.follower, s.estimator, s.mount, s.grid, s.q_start, s.limits, s.period)
    for period, why in ((0.0, "> 0"), (-0.02, "> 0"), (NAN, "a finite number")):
        with pytest.raises(ConfigurationError, match=f"key 'period': must be {why}, got"):
            PathFollower(s.follower, s.estimator, s.mount, s.grid, s.q_start, s.limits, period)
    limits = dataclasses.replace(s.limits, tool_speed=NAN)
    with pytest.raises(ConfigurationError, match="key 'tool_speed'"):
        PathFollower(s.follower, s.estimator, s.mount, s.grid, s.q_start, limits, s.period)
    with pytest.raises(ConfigurationError, match="key 'q_initial\\[0\\]'"):
        PathFollower(s.follower, s.estimator, s.mount, s.grid, [NAN] * 6, s.limits, s.period)


def test_the_good_defaults_still_build():
    servo = Servo()
    assert servo.num_input_ports() == 1
    ik = ToolPoseIk(Solver(p_FQ=[0.0, 0.0, 0.1]), 0.02, np.array(HOME))
    assert ik.GetOutputPort("q_goal").size() == 6
    ArmKinematics(ARM, ARM_INSTANCE, ARM.world_frame(), TOOL0)
    plant = MakeMultibodyPlant(SCENARIO, scene_graph=SceneGraph())
    ToFToolSensor(plant, ToFToolConfig(seed=3, period=1))  # an int is a float
    MarkerPoseEstimator(Intrinsics())
    for config in (ToFToolConfig(), FollowerConfig(), MotionLimits(), ToolPoseIkConfig()):
        config.Validate()


def test_an_empty_image_is_refused_naming_its_size():
    with pytest.raises(ConfigurationError, match="the image is 0 x 0 px"):
        DegradeImage(np.zeros((0, 0, 4), np.uint8), DegradationConfig())
    with pytest.raises(ConfigurationError, match=r"the image is 5 x 4 px.*supersampling = 2"):
        DegradeImage(np.zeros((4, 5, 4), np.uint8), DegradationConfig(supersampling=2))


def test_the_hardware_drivers_refuse_a_bad_period():
    from guidedarm.systems.hardware.tof_driver import ToFDriver
    from guidedarm.systems.hardware.tof_protocol import ToFLineCollector

    with pytest.raises(ConfigurationError, match="key 'period': must be > 0, got 0"):
        ToFDriver(ToFLineCollector(), period=0.0, watchdog=0.2)
    with pytest.raises(ConfigurationError, match="key 'latency': must be >= 0, got -1"):
        ToFDriver(ToFLineCollector(), period=0.02, watchdog=0.2, latency=-1.0)
