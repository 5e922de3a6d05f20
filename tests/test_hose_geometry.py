"""Hose centerlines: reading and validation, the paper paths, random paths, geometry."""

import numpy as np
import pytest
from pydrake.multibody.plant import MultibodyPlant

from guidedarm.diagrams.tasks.path_following.setup import LoadHoseWorkspace
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.path_following.workspace import WorkspaceConfig
from guidedarm.systems.scene.hose_geometry import (
    ArcLength,
    CheckSelfClearance,
    HoseConfig,
    MinBendRadius,
    RandomPathConfig,
    RandomSmoothPath,
    ReadCenterline,
    RegisterHose,
    Resample,
    WriteCenterline,
)


@pytest.mark.parametrize(
    "name, min_radius",
    [
        ("paper_path_1", 0.15),
        ("paper_path_2", 0.10),
        ("paper_path_3", 0.10),
        ("paper_path_4", 0.14),
    ],
)
def test_paper_paths(name, min_radius):
    points = ReadCenterline(name)
    assert 0.3 < ArcLength(points)[-1] < 1.2
    assert MinBendRadius(points) >= min_radius
    assert points[:, 2].min() > 0.06


def test_path_4_raises_the_x_wall(tmp_path):
    assert LoadHoseWorkspace("paper_path_4").x == [-0.55, 0.85]
    assert LoadHoseWorkspace("paper_path_1") is None
    # A CSV file's NAME.yaml beside it counts as a named path's does.
    WriteCenterline(ReadCenterline("paper_path_1"), tmp_path / "mine.csv")
    (tmp_path / "mine.yaml").write_text("y: [-0.6, 0.7]\n")
    workspace = LoadHoseWorkspace(str(tmp_path / "mine.csv"))
    assert workspace.y == [-0.6, 0.7] and workspace.x == [-0.55, 0.55]
    (tmp_path / "mine.yaml").write_text("y: [0.7, -0.6]\n")
    with pytest.raises(ConfigurationError, match=r"y must be \[lower, upper\] with lower < upper"):
        LoadHoseWorkspace(str(tmp_path / "mine.csv"))
    (tmp_path / "mine.yaml").write_text("y: [-0.6, 0.7]\nx: [-0.5, 0.5]\ny: [-0.5, 0.5]\n")
    duplicate = r"mine\.yaml: key 'y' appears twice \(lines 1 and 3\)"
    with pytest.raises(ConfigurationError, match=duplicate):
        LoadHoseWorkspace(str(tmp_path / "mine.csv"))


@pytest.mark.parametrize(
    "text, message",
    [
        ("x,y,z\n0.3,0,0.1\n0.3,0.05,abc\n", ":3: not three numbers"),
        ("0.3,0,0.1\n0.3,0.05\n", "expected x,y,z"),
        ("0.3,0,0.1\n0.3,0.05,0.1\n", "too short"),
        ("0.3,0,0.1\n", "at least 2 points"),
        ("0.3,0,0.1\n0.3,0,0.1\n0.3,0.2,0.1\n", "repeated point"),
    ],
)
def test_bad_centerlines_name_the_cause(tmp_path, text, message):
    path = tmp_path / "hose.csv"
    path.write_text(text)
    with pytest.raises(ConfigurationError, match=message):
        ReadCenterline(str(path))


def test_header_is_optional(tmp_path):
    path = tmp_path / "hose.csv"
    path.write_text("0.3,0,0.1\n0.3,0.2,0.1\n")
    assert ReadCenterline(str(path)).shape == (2, 3)
    with pytest.raises(ConfigurationError, match="not found"):
        ReadCenterline(str(tmp_path / "missing.csv"))
    with pytest.raises(ConfigurationError, match="unknown hose path"):
        ReadCenterline("no_such_path")


def test_random_paths_are_smooth_and_inside_the_region():
    spec = RandomPathConfig()
    for seed in range(20):
        points = RandomSmoothPath(seed, spec)
        assert MinBendRadius(points) >= spec.min_bend_radius
        r = np.hypot(points[:, 0], points[:, 1])
        assert spec.radius_range[0] <= r.min() and r.max() <= spec.radius_range[1]
        assert spec.z_range[0] <= points[:, 2].min() and points[:, 2].max() <= spec.z_range[1]
        assert ArcLength(points)[-1] == pytest.approx(spec.length, abs=0.01)
    np.testing.assert_array_equal(RandomSmoothPath(7), RandomSmoothPath(7))


def test_random_paths_follow_the_workspace():
    """The region is the annulus inside the workspace drawn in by the margin: an annulus
    out to 0.75 m stays inside walls at 0.6 m (margin 0.1: |x|, |y| <= 0.5), and a
    workspace with no room left is refused naming it."""
    spec = RandomPathConfig(radius_range=[0.35, 0.75], start_azimuth_centre_deg=-90.0)
    walls = WorkspaceConfig(x=[-0.6, 0.6], y=[-0.6, 0.6], z=[0.005, 0.15])
    for seed in range(10):
        points = RandomSmoothPath(seed, spec, walls)
        assert np.max(np.abs(points[:, :2])) <= 0.5 + 1e-9
        assert points[:, 2].max() <= 0.15 + 1e-9
        assert np.hypot(points[0, 0], points[0, 1]) >= 0.35 - 1e-9
        assert np.degrees(np.arctan2(points[0, 1], points[0, 0])) < -90 + 35
    with pytest.raises(ConfigurationError, match="no room inside the workspace"):
        RandomSmoothPath(0, spec, WorkspaceConfig(x=[-0.08, 0.08]))


def test_random_paths_on_the_table_lie_flat_at_their_radius():
    spec = RandomPathConfig(on_table=True, radius_range=[0.22, 0.3])
    for seed in range(5):
        points = RandomSmoothPath(seed, spec, None, 0.01)
        np.testing.assert_array_equal(points[:, 2], 0.01)
        r = np.hypot(points[:, 0], points[:, 1])
        assert r.min() >= 0.22 and r.max() <= 0.3
        assert MinBendRadius(points) >= spec.min_bend_radius
    # The paper's floor wall (5 mm) is above a 6 mm hose's centre: no room on the table.
    with pytest.raises(ConfigurationError, match=r"no room .* \(on_table: the hose's radius\)"):
        RandomSmoothPath(0, spec, None, 0.003)
    with pytest.raises(ConfigurationError, match="z_range and max_slope_deg have no effect"):
        RandomSmoothPath(0, RandomPathConfig(on_table=True, max_slope_deg=5.0), None, 0.01)


def test_hose_geometry_is_registered_with_roles():
    plant = MultibodyPlant(0.0)
    from pydrake.geometry import SceneGraph

    scene_graph = SceneGraph()
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    points = ReadCenterline("paper_path_1")
    ids = RegisterHose(plant, points, HoseConfig(segment_length=0.01))
    assert len(ids) == int(np.ceil(ArcLength(points)[-1] / 0.01))
    inspector = scene_graph.model_inspector()
    from pydrake.geometry import Role

    assert inspector.NumGeometriesWithRole(Role.kPerception) == len(ids) + 4
    assert inspector.NumGeometriesWithRole(Role.kProximity) == len(ids) + 4


def Hairpin(half_gap: float, leg: float = 0.2) -> np.ndarray:
    """Out along x, a half circle of radius half_gap, back along x (m)."""
    t = np.linspace(0.0, np.pi, 60)[1:-1]
    out = np.column_stack([np.linspace(0.0, leg, 40), np.full(40, -half_gap), np.zeros(40)])
    turn = np.column_stack([leg + half_gap * np.sin(t), -half_gap * np.cos(t), np.zeros(58)])
    return np.vstack([out, turn, out[::-1] * [1, -1, 1]])


@pytest.mark.parametrize(
    "half_gap, refused",
    # the tube (20 mm) through itself below a 10 mm bend radius; the legs 2 x half_gap apart
    [(0.004, True), (0.009, True), (0.0105, False), (0.03, False)],
)
def test_a_hose_through_itself_is_refused(half_gap, refused):
    points = Hairpin(half_gap)
    if not refused:
        CheckSelfClearance(points, 0.020, "hairpin")
        return
    with pytest.raises(ConfigurationError, match="passes through itself") as error:
        CheckSelfClearance(points, 0.020, "hairpin")
    gap_mm = float(str(error.value).split("within ")[1].split(" mm")[0])
    assert gap_mm == pytest.approx(2000 * half_gap, abs=0.6)


def test_a_crossing_hose_is_refused_and_a_bridge_over_it_is_not():
    for height, refused in ((0.0, True), (0.015, True), (0.025, False)):
        # along x through the origin, then round by right-angle corners and back along -y
        # through the point above the origin
        corners = [[-0.1, 0, 0], [0.1, 0, 0], [0.1, 0.15, height], [0, 0.15, height]]
        corners.append([0.0, -0.1, height])
        points = Resample(np.array(corners, float), 0.005)
        if refused:
            with pytest.raises(ConfigurationError, match="passes through itself"):
                CheckSelfClearance(points, 0.020, "crossing")
        else:
            CheckSelfClearance(points, 0.020, "crossing")
