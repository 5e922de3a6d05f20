"""What `make demo` shows: each demo scenario's replay holds its overlays and a camera on
the action, runs/index.html gathers every run, and a browser draws both.

The demo scenarios (Makefile DEMO_SCENARIOS) run shortened (their time limits cut), so the
test stays short; a run cut short ends with exit code 1 and still writes its replay.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from browser import CHROMIUM, MISSING, Screenshot
from replay_commands import Replay

from guidedarm.diagrams.cli.main import main
from guidedarm.diagrams.demo_index import WriteDemoIndex
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.diagrams.tasks.waypoints import MakePlannerSetup
from guidedarm.systems.scene.hose_geometry import DistanceToCenterline, ReadCenterline

REPO = Path(__file__).resolve().parents[1]
# Time limits that cut each task short but past its first sensing or planning.
SHORTENED = {
    "waypoints": ["max_time=0.6"],
    "path_following": ["max_time=2.0"],
    "panel_operation": ["time_limit_s=0.8"],
    "joint_tour": [],
}
# Meshcat's default camera: 75 deg vertical field of view.
MESHCAT_FOV_DEG = 75.0
MAGENTA = np.array([255.0, 0.0, 255.0])  # overlay_geometry.PLAN_RGBA, in BGR too


def DemoScenarios() -> list[str]:
    makefile = (REPO / "Makefile").read_text()
    return re.search(r"^DEMO_SCENARIOS \?= (.+)$", makefile, re.M).group(1).split()


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> Path:
    """runs/<scenario>/ of every demo scenario (shortened), and runs/index.html."""
    runs = tmp_path_factory.mktemp("runs")
    for name in DemoScenarios():
        task, _, _ = LoadScenario(name, [])
        overrides = [a for o in SHORTENED[task.name] for a in ("--set", o)]
        assert main(["run", name, "--out", str(runs / name), *overrides]) in (0, 1)
    WriteDemoIndex(runs)
    return runs


def Camera(replay: Replay) -> tuple[np.ndarray, np.ndarray]:
    """(camera position, target) in Drake's world frame, from the page's camera commands."""
    position = replay.properties[("/Cameras/default/rotated/<object>", "position")]
    target = next(c["value"] for c in replay.commands if c["type"] == "set_target")
    # The page stores them in three.js's y-up frame: (x, z, -y) of the world's (x, y, z).
    to_world = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
    return to_world @ position, to_world @ target


@pytest.mark.slow
def test_every_demo_replay_holds_its_overlays(runs):
    for name in DemoScenarios():
        replay = Replay(runs / name / "replay.html")
        task, scenario, _ = LoadScenario(name, [])
        overlays = replay.Paths("/overlays/")
        assert overlays, f"{name}: no overlay"
        eye, target = Camera(replay)
        assert 0.2 < np.linalg.norm(eye - target) < 5.0, f"{name}: camera {eye} -> {target}"
        CHECKS[task.name](replay, scenario)


def CheckWaypoints(replay: Replay, scenario) -> None:
    setup = MakePlannerSetup(scenario)
    kinematics = setup.planning.kinematics
    X_WB = kinematics.base_frame.CalcPoseInWorld(kinematics.plant.CreateDefaultContext())
    epsilon = scenario.planner.neighbourhood_radius
    for k, waypoint in enumerate(scenario.waypoints[:-1]):
        path = f"/overlays/waypoints/{k + 1}/neighbourhood"
        assert replay.objects[path]["geometries"][0]["radius"] == pytest.approx(epsilon)
        assert np.allclose(replay.Translation(path), X_WB @ np.array(waypoint[:3]), atol=1e-9)
    trail = [p for p in replay.Paths("/overlays/tcp_commanded/trail/") if "tail" not in p]
    assert trail and all(replay.Keyframes(p, "visible")[0] == (0.0, False) for p in trail)


def CheckPathFollowing(replay: Replay, scenario) -> None:
    for k in range(1, 7):
        assert f"/overlays/tof/sensor_{k}/cone" in replay.objects
    assert len(replay.Paths("/overlays/tof/grid/")) == 27
    assert len(replay.Keyframes("/overlays/tof", "position")) > 30  # the tool moves
    points = replay.Paths("/overlays/detected_path/points/")
    assert points, "no detected hose point"
    detected = np.array([replay.Translation(p) for p in points])
    # The grid estimate is within the paper's 16 mm of the true centerline.
    assert DistanceToCenterline(detected, ReadCenterline(scenario.path)).max() < 0.016
    assert replay.Paths("/overlays/tool_centre/trail/")


def CheckPanel(replay: Replay, scenario) -> None:
    for part in ("camera/frustum", "true_panel/x", "estimated_panel/x", "target_switch"):
        assert f"/overlays/panel/{part}" in replay.objects, part
    shown = replay.Keyframes("/overlays/panel/estimated_panel", "visible")
    assert shown[0] == (0.0, False) and shown[-1][1] is True and shown[-1][0] > 0
    estimated = np.array(replay.Translation("/overlays/panel/estimated_panel"))
    true = np.array(replay.Translation("/overlays/panel/true_panel"))
    assert np.linalg.norm(estimated - true) < 0.005


def CheckJointTour(replay: Replay, scenario) -> None:
    assert replay.Paths("/overlays/flange_commanded/trail/")


CHECKS = {
    "waypoints": CheckWaypoints,
    "path_following": CheckPathFollowing,
    "panel_operation": CheckPanel,
    "joint_tour": CheckJointTour,
}


def test_index_links_every_run_and_its_files(runs):
    page = (runs / "index.html").read_text()
    for name in DemoScenarios():
        assert f'href="{name}/replay.html"' in page
        for png in (runs / name).glob("*.png"):
            assert f'src="{name}/{png.name}"' in page
            assert png.with_suffix(".svg").is_file()
    assert 'class="failed"' in page  # the shortened runs failed, and the page says so


def Project(p_W: np.ndarray, eye: np.ndarray, target: np.ndarray, size) -> np.ndarray:
    """Pixel (u, v) of world point p_W in Meshcat's perspective camera at `eye` looking at
    `target`, up along world z, on a page of `size` (width, height)."""
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    d = p_W - eye
    tan = np.tan(np.radians(MESHCAT_FOV_DEG / 2))
    x = (d @ right) / (d @ forward) / (tan * size[0] / size[1])
    y = (d @ up) / (d @ forward) / tan
    return np.array([(x + 1) / 2 * size[0], (1 - y) / 2 * size[1]])


@pytest.mark.skipif(CHROMIUM is None, reason=MISSING)
def test_replay_shows_the_waypoint_overlays_where_they_are(runs, tmp_path):
    name = next(n for n in DemoScenarios() if n.endswith("_waypoints"))
    replay = Replay(runs / name / "replay.html")
    size = (800, 600)
    image = Screenshot(runs / name / "replay.html", tmp_path / "replay", size)
    magenta = (image[:, :, 0] > 150) & (image[:, :, 2] > 150) & (image[:, :, 1] < 120)
    eye, target = Camera(replay)
    # The intermediate waypoints, inside their neighbourhood spheres (the final one sits
    # in the tool at the end of the replay, hidden by the robot).
    count = len([p for p in replay.Paths("/overlays/waypoints/") if p.endswith("/point")])
    centres = [replay.Translation(f"/overlays/waypoints/{k}/point") for k in range(1, count)]
    assert len(centres) >= 2
    for p_W in centres:
        u, v = Project(np.array(p_W), eye, target, size).round().astype(int)
        assert 0 <= u < size[0] and 0 <= v < size[1], f"waypoint {p_W} is off screen"
        window = magenta[max(v - 12, 0) : v + 13, max(u - 12, 0) : u + 13]
        assert window.mean() > 0.2, f"no overlay colour at pixel {(u, v)} of {p_W}"
    # Elsewhere the page is mostly not magenta: the colour marks the overlays only.
    assert magenta.mean() < 0.1


@pytest.mark.skipif(CHROMIUM is None, reason=MISSING)
def test_index_page_shows_the_plots(runs, tmp_path):
    size = (1200, 1600)
    image = Screenshot(runs / "index.html", tmp_path / "index", size, 3000)
    # The same page with its images missing: what differs is what the plots draw.
    blind = runs / "index_without_images.html"
    blind.write_text((runs / "index.html").read_text().replace('src="', 'src="missing/'))
    without = Screenshot(blind, tmp_path / "blind", size, 3000)
    plotted = np.linalg.norm(image - without, axis=2) > 60
    # A page whose images are missing shows none (0.0); the plots cover 5 % of it.
    assert plotted.mean() > 0.03, f"only {plotted.mean():.3f} of the page shows plots"
    # The "failed" verdicts of the shortened runs are drawn in red text.
    red = np.linalg.norm(image - [198.0, 40.0, 40.0], axis=2) < 60
    assert red.sum() > 50


@pytest.mark.parametrize(
    "content, message",
    [
        (b"\x7fELF\x02\x01\x01\x00\xff\xfe", "not UTF-8 text (byte 8)"),
        (b"[1, 2]", "not a JSON object of metrics"),
        (b"{", "not JSON"),
    ],
)
def test_unreadable_summary_is_refused_in_one_line(run_cli, tmp_path, content, message):
    (tmp_path / "r").mkdir()
    (tmp_path / "r" / "summary.json").write_bytes(content)
    code, out, err = run_cli("demo-index", tmp_path)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and message in err and "r/summary.json" in err
    assert not (tmp_path / "index.html").exists()
