"""The simulated station: exported ports, position servo, cameras, configuration errors."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.common.schema import Transform
from pydrake.systems.analysis import Simulator
from pydrake.systems.sensors import CameraConfig

from guidedarm.diagrams.station.scenario import ArmConfig, StationScenario
from guidedarm.diagrams.station.scene_views import SceneDirectives
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.scene.hose_geometry import HoseConfig
from guidedarm.systems.tof.tof_tool_sensor import DEFAULT_TARGET_RADIUS, ToFToolConfig

HOME = {
    "ur10e": [-np.pi / 2, -np.pi / 2, -3 * np.pi / 4, -np.pi / 4, np.pi / 2, np.pi / 4],
    "mz04d": [0.0, np.pi / 2, 0.0, 0.0, -np.pi / 2, 0.0],
    "rover_arm": [0.0, -np.pi / 2, np.pi / 2, 0.0, 0.0, 0.0],
}


def station_for(arm: str, **arm_config) -> StationScenario:
    return StationScenario(
        directives=SceneDirectives(arm),
        arms={arm: ArmConfig(initial_position=HOME[arm], **arm_config)},
    )


def port_names(system, kind: str) -> dict[str, int]:
    count = getattr(system, f"num_{kind}_ports")()
    ports = [getattr(system, f"get_{kind}_port")(i) for i in range(count)]
    return {p.get_name(): p.size() for p in ports}


@pytest.mark.parametrize("arm", sorted(HOME))
def test_each_arm_exports_the_station_ports(arm):
    station = MakeStation(station_for(arm))
    assert port_names(station, "input") == {f"{arm}.position_commanded": 6}
    outputs = port_names(station, "output")
    for suffix, size in [("position_measured", 6), ("velocity_estimated", 6)]:
        assert outputs[f"{arm}.{suffix}"] == size
    assert outputs[f"{arm}.state_estimated"] == 12
    assert {"sim.query_object", "sim.body_poses", "sim.plant_state"} <= set(outputs)


@pytest.mark.parametrize("arm", sorted(HOME))
def test_servo_holds_the_commanded_pose_against_gravity(arm):
    station = MakeStation(station_for(arm))
    simulator = Simulator(station)
    context = simulator.get_mutable_context()
    station.GetInputPort(f"{arm}.position_commanded").FixValue(context, HOME[arm])
    simulator.AdvanceTo(1.0)
    q = station.GetOutputPort(f"{arm}.position_measured").Eval(context)
    v = station.GetOutputPort(f"{arm}.velocity_estimated").Eval(context)
    np.testing.assert_allclose(q, HOME[arm], atol=1e-6)
    assert np.max(np.abs(v)) < 1e-5


def test_servo_settles_on_a_step_command():
    target = np.array(HOME["ur10e"]) + [0.1, -0.1, 0.1, -0.1, 0.1, -0.1]
    station = MakeStation(station_for("ur10e"))
    simulator = Simulator(station)
    context = simulator.get_mutable_context()
    station.GetInputPort("ur10e.position_commanded").FixValue(context, target)
    simulator.AdvanceTo(0.5)
    q = station.GetOutputPort("ur10e.position_measured").Eval(context)
    np.testing.assert_allclose(q, target, atol=1e-4)


def test_servo_is_computed_torque_on_the_arm_of_the_whole_plant():
    """The station's servo (InverseDynamics on the controller plant of the arm,
    its gripper and ToF tool) applies tau = M_aa (kp e + kd e_dot) + c_a - tau_g,a of the
    station's own plant, in the arm's actuator order."""
    from guidedarm.diagrams.tasks.registry import LoadScenario

    task, scenario, _ = LoadScenario("path_following", [])
    config = task.Station(scenario)
    station = MakeStation(config)
    plant = station.GetSubsystemByName("plant")
    context = station.CreateDefaultContext()
    plant_context = plant.GetMyMutableContextFromRoot(context)
    arm = plant.GetModelInstanceByName("mz04d")
    rng = np.random.default_rng(0)
    q = plant.GetPositions(plant_context, arm) + rng.normal(0.0, 0.3, 6)
    v, q_d, v_d = rng.normal(0.0, 0.5, 6), q + rng.normal(0.0, 0.01, 6), rng.normal(0.0, 0.5, 6)
    plant.SetPositions(plant_context, arm, q)
    plant.SetVelocities(plant_context, arm, v)
    states = station.GetSubsystemByName("mz04d.servo_states")  # [x_d; x] of the servo
    states.get_input_port(0).FixValue(states.GetMyMutableContextFromRoot(context), np.r_[q_d, v_d])
    a = [
        plant.get_joint_actuator(i).joint().velocity_start()
        for i in plant.GetJointActuatorIndices(arm)
    ]
    kp = config.arms["mz04d"].kp
    M = plant.CalcMassMatrix(plant_context)[np.ix_(a, a)]
    expected = (
        M @ (kp * (q_d - q) + 2.0 * np.sqrt(kp) * (v_d - v))
        + plant.CalcBiasTerm(plant_context)[a]
        - plant.CalcGravityGeneralizedForces(plant_context)[a]
    )
    tau = plant.get_actuation_input_port(arm).Eval(plant_context)
    np.testing.assert_allclose(tau, expected, rtol=1e-9, atol=1e-9)  # N m
    assert np.max(np.abs(tau)) > 10.0  # a real correction, not a zero output


def test_camera_renders_the_arm_from_above():
    camera = CameraConfig(width=80, height=60, name="top")
    camera.X_PB = Transform()
    camera.X_PB.translation = [0.0, -0.3, 2.5]
    camera.X_PB.set_rotation_rpy_deg([180.0, 0.0, 0.0])
    scenario = station_for("ur10e")
    scenario.cameras = {"top": camera}
    station = MakeStation(scenario)
    image = station.GetOutputPort("top.rgb_image").Eval(station.CreateDefaultContext())
    rgb = image.data[:, :, :3].astype(float)
    background = rgb[0, 0]
    differs = np.linalg.norm(rgb - background, axis=2) > 30
    # The arm covers part of the view, not all of it and not none of it.
    assert 0.005 < differs.mean() < 0.6


def test_unknown_arm_and_bad_initial_position_are_configuration_errors():
    scenario = station_for("ur10e")
    scenario.arms = {"ur5": ArmConfig()}
    with pytest.raises(ConfigurationError, match="no model instance 'ur5'"):
        MakeStation(scenario)
    scenario.arms = {"ur10e": ArmConfig(initial_position=[0.0, 1.0])}
    with pytest.raises(ConfigurationError, match="initial_position has 2 values"):
        MakeStation(scenario)
    scenario.arms = {"ur10e": ArmConfig(kp=-1.0)}
    message = r"key 'scenario.arms.ur10e.kp': must be in \[1, 1e\+06\], got -1.0"
    with pytest.raises(ConfigurationError, match=message):
        MakeStation(scenario)


def test_bad_model_file_is_a_configuration_error():
    from pydrake.multibody.parsing import AddModel, ModelDirective

    directive = ModelDirective()
    directive.add_model = AddModel()
    directive.add_model.name = "ghost"
    directive.add_model.file = "package://guidedarm/nowhere/ghost.urdf"
    with pytest.raises(ConfigurationError, match="model directives"):
        MakeStation(StationScenario(directives=[directive]))


def test_arm_initial_position_is_checked_where_tasks_read_it():
    from pydrake.multibody.plant import MultibodyPlant

    from guidedarm.diagrams.station.station_plant import AddStationModels, ArmInitialPosition

    scenario = station_for("ur10e")
    plant = MultibodyPlant(0.0)
    AddStationModels(scenario, plant)
    plant.Finalize()
    np.testing.assert_allclose(
        ArmInitialPosition(plant, "ur10e", ArmConfig(initial_position=HOME["ur10e"])),
        HOME["ur10e"],
    )
    # Without a scenario value, the model's defaults (the directive's home pose) apply.
    np.testing.assert_allclose(ArmInitialPosition(plant, "ur10e", ArmConfig()), HOME["ur10e"])
    with pytest.raises(ConfigurationError, match="initial_position has 3 values"):
        ArmInitialPosition(plant, "ur10e", ArmConfig(initial_position=[0.0, 0.0, 0.0]))


def test_a_tof_tool_without_target_radius_assumes_the_station_hose():
    """target_radius 0: the hose's radius when the station has a hose, else the default."""
    scenario = StationScenario(tof_tools={"tof": ToFToolConfig()})
    assert scenario.ToFTool("tof").TargetRadius() == DEFAULT_TARGET_RADIUS
    scenario.hose = HoseConfig(diameter=0.032)
    assert scenario.ToFTool("tof").target_radius == pytest.approx(0.016)
    scenario.tof_tools["tof"].target_radius = 0.004
    assert scenario.ToFTool("tof").target_radius == 0.004
