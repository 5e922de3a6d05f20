"""ToF sensor timing: ranges read at their measurement instant and held, `measured_at`,
range offsets, crosstalk and a bounded drift (ToFErrors); the defaults keep a reading
unchanged."""

import numpy as np
import pytest
from pydrake.geometry import Capsule
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, CoulombFriction
from pydrake.multibody.tree import PrismaticJoint
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from guidedarm.diagrams.station.model_paths import MakeParser
from guidedarm.systems.tof.tof_errors import ToFErrors
from guidedarm.systems.tof.tof_tool_sensor import ToFToolConfig, ToFToolSensor
from guidedarm.systems.tof.tof_tool_sensor_math import DriftStep, Measure

SPEED = 0.2  # m/s, the tool across the hose along its y axis


def _SlidingTool(config: ToFToolConfig, errors: ToFErrors | None = None):
    """The ToF tool on a prismatic joint along its y axis (no gravity, no actuator: it
    slides at the velocity it starts with) and a 20 mm hose, a capsule along the tool's x
    axis through the tool frame's origin O (where the paper's hose lies) at joint position
    0. Returns the diagram, the plant and the sensor."""
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, 0.0)
    tool = MakeParser(plant).AddModels(url="package://guidedarm/tools/tof_tool.urdf")[0]
    body = plant.GetBodyByName("tof_tool", tool)
    plant.AddJoint(PrismaticJoint("slide", plant.world_frame(), body.body_frame(), [0.0, 1.0, 0.0]))
    X_WC = RigidTransform(RotationMatrix.MakeYRotation(np.pi / 2), [0.0, 0.0, 0.0])
    plant.RegisterCollisionGeometry(
        plant.world_body(), X_WC, Capsule(0.010, 0.3), "hose", CoulombFriction(0.5, 0.5)
    )
    plant.mutable_gravity_field().set_gravity_vector([0.0, 0.0, 0.0])
    plant.Finalize()
    sensor = builder.AddSystem(ToFToolSensor(plant, config, errors))
    builder.Connect(scene_graph.get_query_output_port(), sensor.get_input_port())
    return builder.Build(), plant, sensor


def _Start(diagram, plant, y0: float) -> Simulator:
    simulator = Simulator(diagram)
    plant_context = plant.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    plant.SetPositions(plant_context, [y0])
    plant.SetVelocities(plant_context, [SPEED])
    simulator.Initialize()
    return simulator


def _TrueRangesAt(diagram, plant, sensor, y: float) -> np.ndarray:
    context = diagram.CreateDefaultContext()
    plant.SetPositions(plant.GetMyMutableContextFromRoot(context), [y])
    return sensor.TrueRanges(sensor.GetMyContextFromRoot(context))


def test_a_moving_tool_reads_the_geometry_at_the_measurement_instant():
    """Across the hose at 0.2 m/s, with 20 ms period and 10 ms ranging: at 0, 2.5, 10 and
    12.5 ms into each period (not on a measurement instant: Drake 1.51 skips a periodic
    event whose time rounds just past an AdvanceTo boundary) the ranges equal the geometry
    where the tool was at `measured_at` = k 20 ms - 5 ms (the newest range available),
    within 1 um, and not the geometry at the output's time (more than 3 mm apart while a
    flank passes)."""
    config = ToFToolConfig(noise_std=0.0, quantization=0.0)
    diagram, plant, sensor = _SlidingTool(config)
    y0 = -0.030
    simulator = _Start(diagram, plant, y0)
    context = simulator.get_context()
    sensor_context = sensor.GetMyContextFromRoot(context)
    apart = []
    for t in (np.arange(0.0, 0.3, 0.02)[:, None] + [0.0, 0.0025, 0.01, 0.0125]).ravel():
        simulator.AdvanceTo(t)
        measured_at = sensor.GetOutputPort("measured_at").Eval(sensor_context)
        k = np.floor(t / 0.020 + 1e-9)
        expected_at = 0.0 if k == 0 else k * 0.020 - 0.005
        np.testing.assert_allclose(measured_at, expected_at, atol=1e-9)
        ranges = sensor.GetOutputPort("ranges").Eval(sensor_context)
        valid = sensor.GetOutputPort("valid").Eval(sensor_context) > 0.5
        then = _TrueRangesAt(diagram, plant, sensor, y0 + SPEED * expected_at)
        now = _TrueRangesAt(diagram, plant, sensor, y0 + SPEED * t)
        np.testing.assert_array_equal(valid, np.isfinite(then))
        np.testing.assert_allclose(ranges[valid], then[valid], atol=1e-6)
        both = valid & np.isfinite(now)
        apart.append(np.max(np.abs(ranges[both] - now[both]), initial=0.0))
    assert max(apart) > 0.003


def test_offset_crosstalk_and_a_bounded_drift_change_every_return():
    """Per-sensor offsets shift every return by their value; a crosstalk of 10 % shortens
    it by a tenth; a drift of 5 mm per sqrt(s) bounded at 2 mm moves the ranges by at most
    2 mm, and does move them."""
    offset = [0.001, -0.002, 0.0, 0.003, 0.0005, -0.001]
    base = ToFToolConfig(noise_std=0.0, quantization=0.0)
    cases = {
        "base": ToFErrors(),
        "shifted": ToFErrors(offset=offset),
        "crosstalk": ToFErrors(crosstalk=[0.1] * 6),
        "drifting": ToFErrors(drift_rate=0.005, drift_max=0.002),
    }
    readings = {}
    for name, errors in cases.items():
        diagram, plant, sensor = _SlidingTool(base, errors)
        simulator = _Start(diagram, plant, 0.0)
        plant.SetVelocities(plant.GetMyMutableContextFromRoot(simulator.get_mutable_context()), [0])
        rows = []
        for t in np.arange(0.0, 2.0, 0.02):
            simulator.AdvanceTo(t)
            rows.append(
                sensor.GetOutputPort("ranges").Eval(
                    sensor.GetMyContextFromRoot(simulator.get_context())
                )
            )
        readings[name] = np.array(rows)
    valid = readings["base"] < base.max_range
    assert valid[:, 1].all() and valid[:, 4].all()  # the centre sensors see the hose
    np.testing.assert_allclose(
        (readings["shifted"] - readings["base"])[valid],
        np.broadcast_to(offset, valid.shape)[valid],
        atol=1e-12,
    )
    np.testing.assert_allclose(
        readings["crosstalk"][valid], 0.9 * readings["base"][valid], rtol=1e-12
    )
    drift = (readings["drifting"] - readings["base"])[valid]
    assert np.max(np.abs(drift)) <= 0.002 + 1e-12
    assert np.max(np.abs(drift)) > 0.001


def test_drift_is_a_reflected_random_walk_within_its_bound():
    rng = np.random.default_rng(0)
    drift = np.zeros(6)
    path = []
    for _ in range(5000):
        drift = DriftStep(drift, rng, 0.01, 0.02, 0.009)
        path.append(drift)
    path = np.array(path)
    assert np.max(np.abs(path)) <= 0.009
    # Far from the bound the walk's steps have the asked spread: 0.01 m sqrt(0.02 s / 1 s).
    steps = np.diff(path, axis=0)[np.all(np.abs(path[:-1]) < 0.006, axis=1)]
    assert np.std(steps) == pytest.approx(0.01 * np.sqrt(0.02), rel=0.05)


def test_a_resting_tool_reads_as_before_the_timing_model():
    """Defaults, tool at rest over the hose: at every 10 ms tick the reading is the one the
    sensor gave before it had a timing model, the true ranges with the noise of
    default_rng((seed, floor(t / period)))."""
    config = ToFToolConfig(seed=3)
    diagram, plant, sensor = _SlidingTool(config)
    simulator = _Start(diagram, plant, 0.004)
    plant.SetVelocities(plant.GetMyMutableContextFromRoot(simulator.get_mutable_context()), [0])
    true = _TrueRangesAt(diagram, plant, sensor, 0.004)
    assert np.isfinite(true[[1, 4]]).all()
    for tick in range(30):
        t = 0.01 * tick
        simulator.AdvanceTo(t)
        context = sensor.GetMyContextFromRoot(simulator.get_context())
        rng = np.random.default_rng((3, int(np.floor(t / 0.02 + 1e-9))))
        ranges, valid = Measure(true, rng, 0.002, 0.001, 0.1)
        np.testing.assert_array_equal(sensor.GetOutputPort("ranges").Eval(context), ranges)
        np.testing.assert_array_equal(sensor.GetOutputPort("valid").Eval(context), valid)
