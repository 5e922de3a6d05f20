"""The public builders refuse misuse in one line before they add anything: an input of the
station already connected, a port the station lacks, a station outside the builder,
arguments and scenario fields of the wrong type (diagrams/builder_checks.py)."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, PassThrough

from guidedarm.diagrams.panel.panel_files import DEFAULT_PANEL_FILE, LoadPanelSpec
from guidedarm.diagrams.scenario_loading import list_named_scenarios
from guidedarm.diagrams.station.kinematic_station import MakeKinematicStation
from guidedarm.diagrams.station.scenario import ArmConfig, StationScenario
from guidedarm.diagrams.station.scene_views import SceneDirectives
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.diagrams.station.station_plant import MakeMultibodyPlant
from guidedarm.diagrams.tasks.panel_operation.builder import AddPanelOperation
from guidedarm.diagrams.tasks.path_following.builder import AddPathFollowing
from guidedarm.diagrams.tasks.path_following.setup import MakeSetup
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.config_checks import CheckConfig
from guidedarm.systems.errors import ConfigurationError

PANEL_ARGS = {"arm": "rover_arm", "camera": "camera", "tip_frame": "rover_gripper::gripper_tip"}


def _refused(call, message: str) -> None:
    with pytest.raises(ConfigurationError) as error:
        call()
    text = str(error.value)
    assert message in text, text
    assert "\n" not in text and "Failure at" not in text


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    _, scenario, _ = LoadScenario("path_following", [])
    return MakeSetup(scenario, tmp_path_factory.mktemp("builder_checks"))


@pytest.fixture(scope="module")
def panel_station():
    _, scenario, _ = LoadScenario("panel_operation", [])
    return scenario.station, MakeStation(scenario.station)


def test_path_following_wires_every_port_of_a_kinematic_station(setup):
    builder = DiagramBuilder()
    station = builder.AddNamedSystem("station", MakeKinematicStation(setup.station))
    AddPathFollowing(builder, station, setup)
    diagram = builder.Build()
    assert diagram.num_input_ports() == 0  # the arm's command is driven


def test_path_following_twice_is_refused_before_adding_a_system(setup):
    builder = DiagramBuilder()
    station = builder.AddNamedSystem("station", MakeKinematicStation(setup.station))
    AddPathFollowing(builder, station, setup)
    systems = len(builder.GetSystems())
    _refused(
        lambda: AddPathFollowing(builder, station, setup),
        "station 'station' input port 'mz04d.position_commanded' is already connected",
    )
    assert len(builder.GetSystems()) == systems
    builder.Build()  # the first loop is intact


def test_path_following_refuses_a_station_outside_the_builder_or_without_its_ports(setup):
    builder = DiagramBuilder()
    _refused(
        lambda: AddPathFollowing(builder, MakeKinematicStation(setup.station), setup),
        "station 'kinematic_station' is not a system of this builder",
    )
    inner = DiagramBuilder()
    command = inner.AddSystem(PassThrough(6))
    inner.ExportInput(command.get_input_port(), "mz04d.position_commanded")
    inner.ExportOutput(command.get_output_port(), "mz04d.position_measured")
    bare = inner.Build()
    bare.set_name("bare")
    builder.AddSystem(bare)
    _refused(
        lambda: AddPathFollowing(builder, bare, setup), "station 'bare' has no output port 'tof."
    )
    assert len(builder.GetSystems()) == 1


def test_panel_operation_refuses_a_command_input_already_wired(panel_station):
    scenario, station = panel_station
    builder = DiagramBuilder()
    builder.AddSystem(station)
    hold = builder.AddSystem(ConstantVectorSource(np.zeros(6)))
    builder.Connect(hold.get_output_port(), station.GetInputPort("rover_arm.position_commanded"))
    panel = LoadPanelSpec(DEFAULT_PANEL_FILE)
    _refused(
        lambda: AddPanelOperation(builder, station, scenario, panel, 2, **PANEL_ARGS),
        "input port 'rover_arm.position_commanded' is already connected",
    )
    assert len(builder.GetSystems()) == 2


@pytest.mark.parametrize(
    "panel, switch, message",
    [
        ("file", 2, "key 'panel': expected PanelSpec, got '"),
        ("spec", "2", "key 'switch': expected int, got '2'"),
        ("spec", True, "key 'switch': expected int, got True"),
    ],
)
def test_panel_operation_refuses_arguments_of_the_wrong_type(panel_station, panel, switch, message):
    scenario, _ = panel_station
    builder = DiagramBuilder()
    station = builder.AddSystem(MakeStation(scenario))
    panel = LoadPanelSpec(DEFAULT_PANEL_FILE) if panel == "spec" else str(DEFAULT_PANEL_FILE)
    _refused(
        lambda: AddPanelOperation(builder, station, scenario, panel, switch, **PANEL_ARGS), message
    )


def _ur10e(**fields) -> StationScenario:
    return StationScenario(directives=SceneDirectives("ur10e"), **fields)


@pytest.mark.parametrize(
    "scenario, message",
    [
        (_ur10e(arms=["ur10e"]), "key 'scenario.arms': expected a mapping, got ['ur10e']"),
        (_ur10e(arms={"ur10e": {}}), "key 'scenario.arms.ur10e': expected ArmConfig, got {}"),
        (
            _ur10e(arms={"ur10e": ArmConfig(kp="5")}),
            "key 'scenario.arms.ur10e.kp': expected a number, got '5'",
        ),
        (_ur10e(hose="hose.csv"), "key 'scenario.hose': expected HoseConfig, got 'hose.csv'"),
    ],
)
def test_station_builders_refuse_scenario_fields_of_the_wrong_type(scenario, message):
    _refused(lambda: MakeStation(scenario), message)
    _refused(lambda: MakeMultibodyPlant(scenario), message)
    _refused(lambda: MakeKinematicStation(scenario), message)


def test_every_shipped_scenario_and_numpy_values_have_their_declared_types():
    for name in list_named_scenarios():
        CheckConfig(LoadScenario(name, [])[1], name)
    arm = ArmConfig(initial_position=np.zeros(6), kp=np.float64(900.0), kd=40)
    plant = MakeMultibodyPlant(_ur10e(arms={"ur10e": arm}))
    assert plant.num_positions() == 6


def test_make_setup_refuses_a_dict():
    _refused(
        lambda: MakeSetup({"path": "paper_path_1"}),
        "key 'scenario': expected PathFollowingScenario, got {'path': 'paper_path_1'}",
    )


@pytest.mark.parametrize(
    "name, overrides, message",
    [
        ("ur10e_waypoints", None, "key 'overrides': expected a list of 'key=value' strings"),
        ("ur10e_waypoints", "max_time=3", "got 'max_time=3'"),
        ("ur10e_waypoints", [3], "key 'overrides[0]': expected a 'key=value' string, got 3"),
        (3, [], "key 'name_or_path': expected str or Path, got 3"),
    ],
)
def test_load_scenario_refuses_arguments_of_the_wrong_type(name, overrides, message):
    _refused(lambda: LoadScenario(name, overrides), message)


@pytest.mark.parametrize(
    "name, overrides, message",
    [
        ("ur10e_waypoints", ["limits=bogus"], "limits must be one of"),
        ("ur10e_waypoints", ["waypoints=[]"], "waypoints: at least one waypoint is needed"),
        (
            "ur10e_waypoints",
            ["limits=none", "max_joint_velocity=[2]"],
            "'max_joint_velocity' has no effect with limits=none",
        ),
        ("ur10e_joint_tour", ["arm=ur5"], "arm 'ur5' is not in station.arms"),
        ("panel_operation", ["camera=webcam"], "camera 'webcam' is not in station.cameras"),
        ("panel_operation", ["arm=ur5"], "arm 'ur5' is not in station.arms"),
        ("path_following", ["motion=teleport"], "key 'motion': 'teleport' is not one of"),
        ("path_following", ["tof=tof2"], "station must define arms.mz04d and tof_tools.tof2"),
    ],
)
def test_every_task_checks_its_scenario_at_load(name, overrides, message):
    """The rules between a task scenario's keys (its Validate()) hold when it is loaded,
    not first when its task runs."""
    _refused(lambda: LoadScenario(name, overrides), message)
