"""The overlay systems draw what their input ports say, live and into the recording."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.geometry import Meshcat
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial
from replay_commands import Replay, Vertices

from guidedarm.diagrams.panel.panel_files import DEFAULT_CAMERA_FILE, LoadCameraIntrinsics
from guidedarm.diagrams.station.station_plant import MakeMultibodyPlant
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.plant_frames import GetScopedFrame
from guidedarm.systems.tof.tof_tool_sensor import MakeDetectionGrid
from guidedarm.systems.tof.tof_tool_sensor_math import ConeRays
from guidedarm.systems.visualization.frame_trail_overlay import OVERLAY_PERIOD, FrameTrailOverlay
from guidedarm.systems.visualization.overlay_geometry import (
    PLAN_RGBA,
    ArmFramePoses,
    FrustumSegments,
    GrowingPolyline,
    RecordedPose,
)
from guidedarm.systems.visualization.tof_tool_overlay import ToFToolOverlay


@pytest.fixture(scope="module")
def shared_meshcat():
    return Meshcat()


@pytest.fixture
def meshcat(shared_meshcat):
    """The module's Meshcat, without the overlays of earlier tests."""
    shared_meshcat.Delete("/overlays")
    return shared_meshcat


def Record(meshcat: Meshcat, builder: DiagramBuilder, t_final: float, page) -> Replay:
    """Simulates the diagram to t_final while recording; returns the replay page's scene."""
    simulator = Simulator(builder.Build())
    simulator.Initialize()
    meshcat.StartRecording(frames_per_second=30.0)
    simulator.AdvanceTo(t_final)
    meshcat.StopRecording()
    meshcat.PublishRecording()
    page.write_text(meshcat.StaticHtml())
    meshcat.DeleteRecording()
    return Replay(page)


def test_trail_follows_the_frame_and_grows_in_the_recording(meshcat, tmp_path):
    _, scenario, _ = LoadScenario("ur10e_joint_tour", [])
    plant = MakeMultibodyPlant(scenario.station)
    arm = plant.GetModelInstanceByName("ur10e")
    tool = GetScopedFrame(plant, "ur10e::tool0", "tool")
    q0 = plant.GetPositions(plant.CreateDefaultContext(), arm)
    motion = PiecewisePolynomial.FirstOrderHold([0.0, 1.0], np.column_stack([q0, q0 + 0.4]))
    builder = DiagramBuilder()
    source = builder.AddSystem(TrajectorySource(motion))
    poses = ArmFramePoses(plant, arm)
    trail = builder.AddSystem(FrameTrailOverlay(meshcat, "/overlays/trail", poses, tool, PLAN_RGBA))
    builder.Connect(source.get_output_port(), trail.get_input_port())
    replay = Record(meshcat, builder, 1.0, tmp_path / "trail.html")

    chunks = [p for p in replay.Paths("/overlays/trail/trail/") if "tail" not in p]
    tail = "/overlays/trail/trail/tail"
    drawn = np.vstack([Vertices(replay.objects[p]) for p in [*chunks, tail]])
    times = np.arange(0.0, 1.0 + 1e-9, OVERLAY_PERIOD)
    expected = np.array(
        [poses.Poses(motion.value(t).ravel(), [tool])[0].translation() for t in times]
    )
    # Every drawn vertex is the tool's position at a publish time (float32 on the page).
    nearest = np.min(np.linalg.norm(drawn[:, None] - expected[None], axis=2), axis=1)
    assert nearest.max() < 1e-5
    assert np.linalg.norm(drawn[-1] - expected[-1]) < 1e-5
    # Chunks appear one after another, each hidden at the start of the replay.
    appear = [replay.Keyframes(c, "visible") for c in chunks]
    assert all(k[0] == (0.0, False) and k[-1][1] is True for k in appear)
    shown_at = [k[-1][0] for k in appear]
    assert len(chunks) >= 3 and np.all(np.diff(shown_at) > 0.2)
    # The points after the last chunk (the tail) show from the last chunk's time on.
    tail_keys = replay.Keyframes("/overlays/trail/trail/tail", "visible")
    assert [v for _, v in tail_keys if v] == [True] and tail_keys[-1] == (shown_at[-1], True)


def test_tof_overlay_draws_ranges_validity_and_grid(meshcat, tmp_path):
    _, scenario, _ = LoadScenario("path_following", [])
    plant = MakeMultibodyPlant(scenario.station)
    arm = plant.GetModelInstanceByName("mz04d")
    tof = scenario.station.tof_tools["tof"]
    tool = GetScopedFrame(plant, tof.tool_frame, "tool")
    poses = ArmFramePoses(plant, arm)
    q = plant.GetPositions(plant.CreateDefaultContext(), arm)
    ranges = np.array([0.031, 0.042, 0.1, 0.055, 0.1, 0.066])
    valid = np.array([1.0, 1.0, 0.0, 1.0, 0.0, 1.0])
    detections = np.array([1.0, 0, 1, 1, 0, 1, 0, 0, 0])
    errors = np.array([0.0, 0, 1, 0, 0, 0, 0, 0, 0])
    builder = DiagramBuilder()
    rays = ConeRays(np.radians(tof.cone_angle_deg), tof.rings)
    overlay = builder.AddSystem(
        ToFToolOverlay(
            meshcat, "/overlays/tof", poses, tool, MakeDetectionGrid(plant, tof), rays, 0.1
        )
    )
    for name, value in [
        ("position", q),
        ("ranges", ranges),
        ("valid", valid),
        ("detections", detections),
        ("detection_errors", errors),
    ]:
        source = builder.AddSystem(ConstantVectorSource(value))
        builder.Connect(source.get_output_port(), overlay.GetInputPort(name))
    replay = Record(meshcat, builder, 0.2, tmp_path / "tof.html")

    (X_WT,) = poses.Poses(q, [tool])
    assert np.allclose(replay.Translation("/overlays/tof"), X_WT.translation(), atol=1e-9)
    for k in range(6):
        sensor = f"/overlays/tof/sensor_{k + 1}"
        assert replay.properties[(f"{sensor}/hit", "visible")] == bool(valid[k])
        if valid[k]:
            assert replay.properties[(f"{sensor}/hit", "scale")] == pytest.approx([ranges[k]] * 3)
            assert replay.Translation(f"{sensor}/hit_point") == pytest.approx([0, 0, ranges[k]])
        cone = Vertices(replay.objects[f"{sensor}/cone"])
        assert np.max(np.linalg.norm(cone, axis=1)) == pytest.approx(0.1, abs=1e-6)
    shown = {}
    for n in range(9):
        point = f"/overlays/tof/grid/p{n // 3 + 1}{n % 3 + 4}"
        states = [
            s
            for s in ("detected", "error", "none")
            if replay.properties[(f"{point}/{s}", "visible")]
        ]
        assert len(states) == 1
        shown[n] = states[0]
    assert [shown[n] for n in range(9)] == [
        "detected", "none", "error", "detected", "none", "detected", "none", "none", "none"
    ]  # fmt: skip


def test_frustum_edges_pass_through_the_image_corners():
    c = LoadCameraIntrinsics(DEFAULT_CAMERA_FILE)
    start, end = FrustumSegments(c.width, c.height, c.fx, c.fy, c.cx, c.cy, 0.2)
    far = end[:, :4].T
    assert np.allclose(far[:, 2], 0.2) and np.allclose(start[:, :4], 0.0)
    u = c.fx * far[:, 0] / far[:, 2] + c.cx
    v = c.fy * far[:, 1] / far[:, 2] + c.cy
    assert np.allclose(u, [-0.5, c.width - 0.5, c.width - 0.5, -0.5])
    assert np.allclose(v, [-0.5, -0.5, c.height - 0.5, c.height - 0.5])


def test_a_still_pose_is_recorded_at_both_ends_of_the_pause(meshcat, tmp_path):
    pose = RecordedPose(meshcat, "/overlays/pose")
    meshcat.StartRecording(frames_per_second=30.0)
    for t, x in [(0.0, 0.0), (0.5, 0.0), (1.0, 0.0), (1.5, 0.3)]:
        pose.Set(RigidTransform([x, 0.0, 0.0]), t)
    meshcat.StopRecording()
    meshcat.PublishRecording()
    (tmp_path / "pose.html").write_text(meshcat.StaticHtml())
    meshcat.DeleteRecording()
    keys = Replay(tmp_path / "pose.html").Keyframes("/overlays/pose", "position")
    # No glide from 0 to 0.3 during the pause: x = 0 is held until t = 1.0.
    assert [(t, v[0]) for t, v in keys] == [(0.0, 0.0), (1.0, 0.0), (1.5, 0.3)]


def test_polyline_without_chunks_shows_each_segment_at_its_time_and_no_tail(meshcat, tmp_path):
    """chunk_s = 0 (the detected path): each new point's segment is its own line, hidden
    before its time, shown from it; no tail path is drawn or recorded."""
    line = GrowingPolyline(meshcat, "/overlays/line", PLAN_RGBA, chunk_s=0.0)
    meshcat.StartRecording(frames_per_second=30.0)
    times = [0.1, 0.3, 0.6]
    for k, t in enumerate(times):
        line.Append(np.array([0.01 * k, 0.0, 0.0]), t)
    meshcat.StopRecording()
    meshcat.PublishRecording()
    page = tmp_path / "line.html"
    page.write_text(meshcat.StaticHtml())
    meshcat.DeleteRecording()
    replay = Replay(page)
    segments = replay.Paths("/overlays/line/")
    assert segments == ["/overlays/line/0000", "/overlays/line/0001"]
    for segment, t in zip(segments, times[1:], strict=True):
        keys = replay.Keyframes(segment, "visible")
        assert keys[0] == (0.0, False) and keys[-1][1] and keys[-1][0] == pytest.approx(t, abs=0.02)
    assert not any(path.startswith("/overlays/line/tail") for path, _ in replay.tracks)


def test_frame_poses_follow_every_new_q_even_in_the_same_array():
    """ArmFramePoses reuses its kinematics for a repeated q only: a new q, also written
    into the array it was last given, moves the frame as a fresh context does."""
    _, scenario, _ = LoadScenario("ur10e_joint_tour", [])
    plant = MakeMultibodyPlant(scenario.station)
    arm = plant.GetModelInstanceByName("ur10e")
    tool = GetScopedFrame(plant, "ur10e::tool0", "tool")
    poses = ArmFramePoses(plant, arm)
    q = plant.GetPositions(plant.CreateDefaultContext(), arm)
    (X_0,) = poses.Poses(q, [tool])
    q += 0.3
    (X_1,) = poses.Poses(q, [tool])
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, arm, q)
    assert X_1.IsExactlyEqualTo(tool.CalcPoseInWorld(context))
    assert np.linalg.norm(X_1.translation() - X_0.translation()) > 0.05
    (X_again,) = poses.Poses(q.copy(), [tool])
    assert X_again.IsExactlyEqualTo(X_1)
