"""station.errors: drawn once per run from the random seed, one stream per source, written
into the resolved scenario and the summary; and the physics of each error source."""

import json

import numpy as np
import pytest
from pydrake.common.schema import Gaussian, GaussianVector, Transform, UniformVector
from pydrake.common.yaml import yaml_load_typed

from guidedarm.diagrams.cli.main import main
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station_errors import (
    ArmErrors,
    ModelErrors,
    StationErrors,
)
from guidedarm.diagrams.tasks.registry import GetTask, LoadScenario, NumericMetricNames
from guidedarm.systems.cell_errors.camera_errors import CameraErrors, MakeTrueCamera
from guidedarm.systems.cell_errors.distributions import DrawErrors
from guidedarm.systems.cell_errors.joint_encoder_math import EncoderPositions
from guidedarm.systems.cell_errors.lens_distortion_math import (
    DistortPixels,
    MakeLensRemap,
    Remap,
)
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.tof.tof_errors import ToFErrors


def _Errors(**sources) -> StationErrors:
    arms = {"a": ArmErrors(**sources.pop("arm", {}))}
    models = {"m": ModelErrors(**sources.pop("model", {}))}
    return StationErrors(arms=arms, models=models, **sources)


OFFSET = GaussianVector(mean=[0.0, 0.0], stddev=[0.01, 0.02])
PLACEMENT = Transform(translation=UniformVector[3](min=[0.0, 0.0, 0.0], max=[0.01, 0.01, 0.01]))


def test_each_source_draws_from_its_own_stream_of_the_random_seed():
    """The same seed draws the same cell; another seed another; removing one source (the
    arm's resolution) leaves the draws of the others unchanged."""
    errors = _Errors(
        arm={"joint_offset": OFFSET, "encoder_resolution": Gaussian(mean=1e-4, stddev=1e-5)},
        model={"X_error": PLACEMENT},
    )
    first, again = DrawErrors(errors, 7), DrawErrors(errors, 7)
    other = DrawErrors(errors, 8)
    assert first.arms["a"].joint_offset == again.arms["a"].joint_offset
    assert first.arms["a"].joint_offset != other.arms["a"].joint_offset
    assert len(first.arms["a"].joint_offset) == 2
    fewer = _Errors(arm={"joint_offset": OFFSET}, model={"X_error": PLACEMENT})
    fewer = DrawErrors(fewer, 7)
    assert fewer.arms["a"].joint_offset == first.arms["a"].joint_offset
    X = fewer.models["m"].X_error.GetDeterministicValue()
    assert X.IsExactlyEqualTo(first.models["m"].X_error.GetDeterministicValue())
    assert X.translation().min() > 0 and X.translation().max() < 0.01
    with pytest.raises(ConfigurationError, match=r"arms\.a\.joint_offset is a distribution"):
        DrawErrors(errors, None)


def test_a_preset_is_overridden_field_by_field_and_the_draw_is_written(tmp_path):
    """station.errors_preset loads models/errors/NAME.yaml; an entry of station.errors
    replaces the fields it sets and keeps the preset's others. A run writes the drawn values
    into scenario.yaml (which repeats them) and summary.json, not as metrics."""
    code = main(
        [
            "run", "ur10e_waypoints", "--out", str(tmp_path),
            "--set", "station.errors_preset=ur10e",
            "--set", "station.errors.arms.ur10e.encoder_resolution=0.001",
            "--set", "max_time=0.1", "--set", "random_seed=3",
        ]
    )  # fmt: skip
    assert code == 1  # max_time: the TCP does not reach the last waypoint
    summary = json.loads((tmp_path / "summary.json").read_text())
    drawn = summary["errors"]["arms"]["ur10e"]
    assert drawn["encoder_resolution"] == 0.001
    assert len(drawn["joint_offset"]) == 6 and all(abs(x) < 0.01 for x in drawn["joint_offset"])
    assert NumericMetricNames(summary) <= set(GetTask("waypoints").KnownMetrics())
    _, resolved, _ = LoadScenario(tmp_path / "scenario.yaml", [])
    assert resolved.station.errors_preset == ""
    assert resolved.station.errors.arms["ur10e"].joint_offset == drawn["joint_offset"]
    assert resolved.station.errors.arms["ur10e"].encoder_resolution == 0.001


def test_hardware_runs_refuse_a_simulated_cell_s_errors(run_cli, tmp_path):
    code, _, err = run_cli(
        "run", "ur10e_waypoints", "--hardware", "--out", tmp_path,
        "--set", "station.errors.arms.ur10e.joint_offset=[0.01,0,0,0,0,0]",
    )  # fmt: skip
    assert code == 2 and "--hardware run drives the real one" in err


def test_encoders_read_the_motor_side_less_the_offset_in_whole_steps():
    q = np.array([0.1, -0.2])
    np.testing.assert_allclose(EncoderPositions(q, [0.01, 0.0], 0.0), [0.09, -0.2])
    np.testing.assert_allclose(EncoderPositions(q, [0.0, 0.0], 0.03), [0.09, -0.21])
    # 50 N m held by a 1e4 N m/rad transmission: the motor leads the link by 5 mrad
    np.testing.assert_allclose(
        EncoderPositions(q, [0.0, 0.0], 0.0, [50.0, 0.0], [1e4, 1e4]), [0.105, -0.2]
    )


def test_the_lens_remap_moves_a_dot_where_opencv_projects_it():
    """A bright pixel of the pinhole render appears in the remapped image where OpenCV's
    distortion model puts it (within 0.3 px), on a canvas wide enough for the barrel."""
    K = np.array([[200.0, 0.0, 159.5], [0.0, 200.0, 119.5], [0.0, 0.0, 1.0]])
    distortion = np.array([-0.3, 0.1, 0.001, -0.002, 0.0])
    remap = MakeLensRemap(K, distortion, 320, 240)
    assert remap.render_width > 320 and remap.render_height > 240
    for point in ([60.0, 40.0], [250.0, 200.0]):
        render = np.zeros((remap.render_height, remap.render_width), np.float32)
        u, v = np.add(point, remap.K_render[:2, 2] - K[:2, 2]).astype(int)
        render[v - 2 : v + 3, u - 2 : u + 3] = 1.0
        image = Remap(render, remap)
        ys, xs = np.nonzero(image)
        weights = image[ys, xs]
        seen = [np.average(xs, weights=weights), np.average(ys, weights=weights)]
        expected = DistortPixels(np.array([point]), K, distortion)[0]
        np.testing.assert_allclose(seen, expected, atol=0.3)


def test_camera_errors_make_the_true_camera():
    from pydrake.systems.sensors import CameraConfig

    nominal = CameraConfig(width=64, height=48, focal=CameraConfig.FocalLength(x=50.0, y=50.0))
    true = MakeTrueCamera(nominal, CameraErrors(focal_error_px=[1.0, 2.0]))
    intrinsics = true.config.MakeCameras()[0].core().intrinsics()
    assert (intrinsics.focal_x(), intrinsics.focal_y()) == (51.0, 52.0)
    assert true.remap is None
    assert MakeTrueCamera(nominal, CameraErrors()).config.width == 64


def test_a_focal_error_of_2_percent_shortens_the_estimated_distance_by_2_percent(tmp_path):
    """marker_view at 300 mm: the true lens 2 % longer than the camera file says makes the
    panel look 2 % nearer (1 - 1 / 1.02 = 1.96 %, within 0.15 %)."""
    distances = []
    for k, error in enumerate((0.0, 0.02 * 1360.2)):
        out = tmp_path / str(k)
        focal = f"camera_errors.focal_error_px=[{error},{error}]"
        assert main(["run", "marker_view", "--out", str(out), "--set", focal]) == 0
        distances.append(json.loads((out / "summary.json").read_text())["vision_mm"])
    shortening = 1 - distances[1] / distances[0]
    assert shortening == pytest.approx(1 - 1 / 1.02, abs=0.0015)


def test_a_base_joint_offset_moves_the_true_tcp_by_its_arc(tmp_path):
    """UR10e, base joint 0.01 rad off: the planner still reaches its last waypoint within
    1 mm by what it measures (final_error_m), while the true TCP ends 0.01 x its distance
    from the base axis away (true_final_error_m; within the believed final error). The
    offset turns the whole move about the base axis: the true travel's length along the
    commanded move is right (true_move_error_m, within the believed final error)."""
    offset = "station.errors.arms.ur10e.joint_offset=[0.01,0,0,0,0,0]"
    assert main(["run", "ur10e_waypoints", "--out", str(tmp_path), "--set", offset]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    _, scenario, _ = LoadScenario("ur10e_waypoints", [])
    radius = np.hypot(*scenario.waypoints[-1][:2])
    assert summary["final_error_m"] < 0.001
    arc = 0.01 * radius
    assert abs(summary["true_final_error_m"] - arc) <= summary["final_error_m"] + 1e-4
    assert summary["true_move_error_m"] <= summary["final_error_m"] + 1e-4


def test_a_tof_offset_of_3_mm_moves_the_ranging_estimate_3_mm_along_each_sight():
    """Six sensors reading 3 mm long: the ranging estimator puts the hose 3 mm farther
    along both rows' lines of sight (within 0.1 mm: the cones' width), not across."""
    from test_tof_timing import _SlidingTool, _Start

    from guidedarm.systems.tof.tof_tool_sensor import MakeDetectionGrid, ToFToolConfig

    config = ToFToolConfig(noise_std=0.0, quantization=0.0)
    estimates = []
    for errors in (ToFErrors(), ToFErrors(offset=[0.003] * 6)):
        diagram, plant, sensor = _SlidingTool(config, errors)
        simulator = _Start(diagram, plant, 0.0)
        plant.SetVelocities(plant.GetMyMutableContextFromRoot(simulator.get_mutable_context()), [0])
        simulator.AdvanceTo(0.05)
        context = sensor.GetMyContextFromRoot(simulator.get_context())
        ranges = sensor.GetOutputPort("ranges").Eval(context)
        valid = sensor.GetOutputPort("valid").Eval(context) > 0.5
        S_T, _ = MakeDetectionGrid(plant, config).RangingEstimate(
            ranges, valid, np.array([1.0, 0, 0])
        )
        estimates.append(S_T)
    shift = estimates[1] - estimates[0]
    plant_context = plant.CreateDefaultContext()
    tool = plant.GetFrameByName("tof_tool")
    for i in (2, 5):  # the centre sensor of each row
        sight = plant.GetFrameByName(f"tof_sensor_{i}").CalcPose(plant_context, tool)
        assert shift @ sight.rotation().matrix()[:, 2] == pytest.approx(0.003, abs=1e-4)
    assert abs(shift[0]) < 1e-6


def test_error_entries_load_from_yaml_tags():
    station = yaml_load_typed(
        schema=StationScenario,
        data="""
        errors:
          cameras:
            camera:
              focal_error_px: !GaussianVector {mean: [0, 0], stddev: [5, 5]}
              X_mount_error:
                translation: !GaussianVector {mean: [0, 0, 0], stddev: [1e-3, 1e-3, 1e-3]}
        """,
    )
    drawn = station.WithErrorsDrawn(1).errors.cameras["camera"]
    assert len(drawn.focal_error_px) == 2
    assert drawn.X_mount_error.IsDeterministic()


def test_errors_budget_runs_every_source_alone_and_all_together(run_cli, tmp_path):
    """marker_view with the c920 preset, one draw each: a row per accuracy metric for
    `all` and for each of the preset's four camera sources, in the table and the CSV."""
    code, out, err = run_cli(
        "errors-budget", "marker_view", "--preset", "c920", "--runs", "1",
        "--out", tmp_path, "--set", "supersampling=1",
    )  # fmt: skip
    assert code == 0, err
    rows = (tmp_path / "errors_budget.csv").read_text().splitlines()
    sources = {row.split(",")[0] for row in rows[1:]}
    assert sources == {
        "all",
        "camera_errors.focal_error_px",
        "camera_errors.principal_point_error_px",
        "camera_errors.distortion",
        "camera_errors.X_mount_error",
    }
    assert (tmp_path / "errors_budget.png").stat().st_size > 0
    assert "abs_error_mm" in out


def test_link_errors_move_the_true_arm_s_joint_frames():
    """A 2 mm error of the UR10e's first joint frame (along its x) moves its tool by those
    2 mm at any joint angles; the arm keeps its joints, their order and its actuators."""
    from pydrake.math import RigidTransform
    from pydrake.multibody.plant import MultibodyPlant

    from guidedarm.diagrams.station.station_plant import AddStationModels

    _, scenario, _ = LoadScenario("ur10e_waypoints", [])
    link_errors = [Transform(RigidTransform([0.002, 0.0, 0.0]))] + [Transform()] * 5
    plants = []
    for arm_errors in ({}, {"ur10e": ArmErrors(link_errors=link_errors)}):
        plant = MultibodyPlant(0.0)
        AddStationModels(scenario.station, plant, arm_errors=arm_errors)
        plant.Finalize()
        plants.append(plant)
    q = np.array([0.3, -1.2, 1.0, -0.5, 0.7, 0.2])
    tools = []
    for plant in plants:
        context = plant.CreateDefaultContext()
        plant.SetPositions(context, plant.GetModelInstanceByName("ur10e"), q)
        tools.append(plant.GetFrameByName("tool0").CalcPoseInWorld(context).translation())
        assert plant.num_actuated_dofs(plant.GetModelInstanceByName("ur10e")) == 6
    nominal = plants[0]
    parent = nominal.GetFrameByName("shoulder_pan_joint_parent")
    R_WF = parent.CalcPoseInWorld(nominal.CreateDefaultContext()).rotation()
    np.testing.assert_allclose(tools[1] - tools[0], R_WF @ [0.002, 0.0, 0.0], atol=1e-12)


def test_a_compliant_base_tilts_until_its_springs_hold_the_arm(tmp_path):
    """The rover arm held at its start on a base with 5000 N m/rad tilt springs: after
    1 s each tilt's spring torque balances gravity's and the contact's on it (within 2 %),
    the tilt is not zero, and the arm keeps its six joints and ports."""
    from pydrake.systems.analysis import Simulator

    from guidedarm.diagrams.station.station import MakeStation

    sets = [
        "station.errors.arms.rover_arm.base_stiffness=[5000, 5000]",
        "station.errors.arms.rover_arm.base_damping=[300, 300]",
    ]
    _, scenario, _ = LoadScenario("rover_arm_waypoints", sets)
    station = MakeStation(scenario.station)
    simulator = Simulator(station)
    context = simulator.get_mutable_context()
    q0 = station.GetOutputPort("rover_arm.position_measured").Eval(context)
    station.GetInputPort("rover_arm.position_commanded").FixValue(context, q0)
    simulator.AdvanceTo(1.0)
    plant = station.GetSubsystemByName("plant")
    plant_context = plant.GetMyContextFromRoot(context)
    gravity = plant.CalcGravityGeneralizedForces(plant_context)
    compliance = plant.GetModelInstanceByName("rover_arm_base_compliance")
    contact = plant.get_generalized_contact_forces_output_port(compliance).Eval(plant_context)
    assert len(q0) == 6
    for i, axis in enumerate("xy"):
        joint = plant.GetJointByName(f"rover_arm_base_tilt_{axis}")
        angle = joint.get_angle(plant_context)
        tau = gravity[joint.velocity_start()] + contact[i]
        assert abs(5000 * angle - tau) <= 0.02 * abs(tau) + 1e-3
    assert (
        max(
            abs(plant.GetJointByName(f"rover_arm_base_tilt_{a}").get_angle(plant_context))
            for a in "xy"
        )
        > 1e-4
    )
