"""The table as the followers know it (known_surfaces): the range a cone reads off a plane,
checked against densely sampled cones and against the station's own ray casting at the
start of a hose lying on the table, and the readings it takes out (the table's, not the
hose's)."""

import math

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw

from guidedarm.diagrams.station.kinematic_station import MakeKinematicStation
from guidedarm.diagrams.tasks.path_following.setup import MakeSetup
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.tof.known_surfaces import KnownPlane, PlaneRange
from guidedarm.systems.tof.tof_tool_sensor_math import ConeRays

CONE = math.radians(25.0)
# A hose on the table with the tool rolled so that both arms stay above it.
TABLE_HOSE = [
    "path=random_1",
    "random_path.on_table=true",
    "random_path.radius_range=[0.22, 0.3]",
    "tool_roll_deg=-45",
    "station.hose.brackets=false",
]


def test_the_plane_range_is_the_nearest_return_of_a_densely_sampled_cone():
    rays = ConeRays(CONE, 20)  # 1261 rays
    plane = KnownPlane((0.0, 0.0, 1.0), 0.0)
    rng = np.random.default_rng(3)
    compared = 0
    for _ in range(200):
        X_WS = RigidTransform(RollPitchYaw(rng.uniform(-np.pi, np.pi, 3)), [0, 0, 0.05])
        u_W = rays @ X_WS.rotation().matrix().T
        down = -u_W[:, 2]
        with np.errstate(divide="ignore"):
            sampled = np.where(down > 0, 0.05 / down, np.inf).min()
        exact = PlaneRange(X_WS.translation(), u_W[0], CONE, plane)
        if not sampled <= 0.1:  # beyond the sensors' 100 mm (grazing or looking away)
            assert exact > 0.095
            continue
        compared += 1
        # The sampled cone misses the exact nearest direction by at most its ring spacing.
        assert exact <= sampled + 1e-12
        assert sampled - exact <= 0.002 * sampled
    assert compared > 40
    # Straight down: the height; an emitter under the plane sees nothing of it.
    assert PlaneRange([0, 0, 0.04], [0, 0, -1], CONE, plane) == pytest.approx(0.04)
    assert PlaneRange([0, 0, -0.01], [0, 0, 1], CONE, plane) == math.inf


@pytest.fixture(scope="module")
def table_start():
    """(setup, the noiseless ranges the station's cones read at the start pose, X_WT)."""
    _, scenario, _ = LoadScenario("path_following", TABLE_HOSE)
    setup = MakeSetup(scenario)
    station = MakeKinematicStation(setup.station)
    context = station.CreateDefaultContext()
    station.GetInputPort(f"{setup.arm}.position_commanded").FixValue(context, setup.q_start)
    query = station.GetOutputPort("sim.query_object").Eval(context)
    plant = setup.solver.plant
    plant_context = plant.CreateDefaultContext()
    plant.SetPositions(plant_context, setup.q_start)
    tool = plant.GetFrameByName("tof_tool")
    X_WT = tool.CalcPoseInWorld(plant_context)
    caster = station.GetSubsystemByName(f"{setup.tool_name}.sensor").Caster()
    ranges = caster.Ranges(query, [X_WT @ X_TS for X_TS in setup.grid.X_TS])
    return setup, ranges, X_WT


def test_on_the_table_four_cones_read_the_table_inside_the_span_and_are_taken_out(table_start):
    setup, ranges, X_WT = table_start
    known = setup.known_surfaces
    assert known is not None and known.tolerance == pytest.approx(3 * 0.002 + 0.001)
    expected = known.Ranges(X_WT)
    # Rolled -45 deg, the centre sensors 2 and 5 look at the hose (45 mm) and sensor 6's
    # cone catches its flank; the others' cones pass beside it and meet the table within
    # the 100 mm span, where the known plane says (the ray casting's to 1 mm).
    assert ranges[1] == pytest.approx(0.045, abs=0.003)
    assert ranges[4] == pytest.approx(0.045, abs=0.003)
    table, hose = [0, 2, 3], [1, 4, 5]
    assert np.all(ranges[table] < 0.1)
    np.testing.assert_allclose(ranges[table], expected[table], atol=0.001)
    # The hose is nearer than the table's return by 12.8-21 mm, the tolerance (7 mm) and
    # more: a reading of it is taken for the table only with 2.9 noise sigmas (2 mm) on it.
    assert np.all(expected[hose] - ranges[hose] > 1.8 * known.tolerance)
    valid = np.isfinite(ranges)
    assert valid.all()
    np.testing.assert_array_equal(
        known.HoseReadings(X_WT, ranges, valid), [False, True, False, False, True, True]
    )
    # A reading a few noise sigmas off is still the table; an invalid one stays invalid.
    noisy = ranges + np.where(np.arange(6) % 2, 0.005, -0.005)
    assert not known.HoseReadings(X_WT, noisy, valid)[table].any()
    assert not known.HoseReadings(X_WT, ranges, np.zeros(6, bool)).any()
