"""Your own marker panel from one file: the panel file drives the estimator and the
simulated scene (its model and marker textures generated at load), found as a path or a
name under models/, with its own switch names, in panel_operation, marker_view and
marker-study."""

from __future__ import annotations

import json

import cv2
import pytest

from guidedarm.diagrams.campaigns.jobs import ExpandJobs
from guidedarm.diagrams.panel.panel_assets import GeneratedPanelModel
from guidedarm.diagrams.panel.panel_files import DEFAULT_PANEL_FILE, ResolvePanelFile
from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.studies.marker_study import StudyCampaign
from guidedarm.diagrams.tasks.panel_operation import PanelOperationRun
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.image_degradation import DegradationConfig

# A user's panel: a smaller dictionary, 40 mm markers 100 mm apart, switches named
# differently from the shipped panel's s1..s3.
MY_PANEL = """\
dictionary: DICT_4X4_50
markers:
- id: 3
  size_m: 0.04
  X_PM: {translation: [0.0, 0.0, 0.0]}
- id: 11
  size_m: 0.04
  X_PM: {translation: [0.10, 0.0, 0.0]}
switches:
- {name: left, position: [0.02, -0.05, 0.012]}
- {name: middle, position: [0.05, -0.05, 0.012]}
- {name: right, position: [0.08, -0.05, 0.012]}
"""


@pytest.fixture
def my_panel(tmp_path, monkeypatch):
    """my_panel.yaml in the working directory (a tmp folder)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "my_panel.yaml").write_text(MY_PANEL)
    return tmp_path / "my_panel.yaml"


def test_a_panel_file_is_a_path_or_a_name_under_models(my_panel):
    assert ResolvePanelFile("my_panel.yaml") == my_panel
    assert ResolvePanelFile(str(my_panel)) == my_panel
    assert ResolvePanelFile("panel/panel.yaml") == DEFAULT_PANEL_FILE
    with pytest.raises(ConfigurationError, match=r"panel_file 'nope\.yaml': file not found"):
        ResolvePanelFile("nope.yaml")


def test_the_generated_model_carries_the_file_s_markers_and_switches(my_panel):
    sdf = GeneratedPanelModel(my_panel)
    assert GeneratedPanelModel("my_panel.yaml") == sdf  # one model per content, shared
    text = sdf.read_text()
    for name in ("left", "middle", "right"):
        assert f'<joint name="{name}" type="prismatic">' in text
    detector = cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50), cv2.aruco.DetectorParameters()
    )
    for marker_id in (3, 11):
        texture = cv2.imread(str(sdf.parent / f"marker_{marker_id}.png"), cv2.IMREAD_GRAYSCALE)
        framed = cv2.copyMakeBorder(texture, 60, 60, 60, 60, cv2.BORDER_CONSTANT, value=255)
        _, ids, _ = detector.detectMarkers(framed)
        assert ids is not None and ids.ravel().tolist() == [marker_id]
        obj = (sdf.parent / f"marker_{marker_id}.obj").read_text()
        assert "v 0.02 0.02 0" in obj  # a 40 mm square


@pytest.mark.slow
def test_panel_operation_presses_a_switch_of_your_own_panel(my_panel, run_cli, tmp_path):
    code, _, err = run_cli(
        "run",
        "panel_operation",
        "--set",
        "panel_file=my_panel.yaml",
        "--set",
        "switch=3",
        "--set",
        "supersampling=1",
        "--out",
        tmp_path / "run",
    )
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert code == 0, summary["failure"] or err
    assert summary["switch_pressed"] == 3
    assert max(summary["press_error_mm"].values()) < 0.5
    assert all(m["ids"] in ([3, 11], [3], [11]) for m in summary["measurements"])
    recorded = (tmp_path / "run" / "scenario.yaml").read_text()
    assert f"panel_file: {my_panel}" in recorded  # repeatable from any directory


def test_marker_view_estimates_the_pose_of_your_own_panel(my_panel, run_cli, tmp_path):
    code, _, err = run_cli(
        "run",
        "marker_view",
        "--set",
        "panel_file=my_panel.yaml",
        "--set",
        "distance_m=0.25",
        "--set",
        "supersampling=1",
        "--out",
        tmp_path / "view",
    )
    summary = json.loads((tmp_path / "view" / "summary.json").read_text())
    assert code == 0, err
    assert summary["ids"] == [3, 11]
    assert summary["abs_error_mm"] < 1.0 and summary["rotation_error_deg"] < 0.5


@pytest.mark.parametrize(
    "overrides, message",
    [
        (["switch=4"], "switch must be 1 .. 3, got 4 (the switches of my_panel.yaml)"),
        (["panel_model=nosuch"], "panel_model: no model instance 'nosuch'"),
    ],
)
def test_a_panel_the_scene_cannot_take_is_refused_in_one_line(my_panel, overrides, message):
    overrides = ["panel_file=my_panel.yaml", *overrides]
    with pytest.raises(ConfigurationError) as error:
        _, scenario, _ = LoadScenario("panel_operation", overrides)
        PanelOperationRun(scenario, RunContext(out_dir=my_panel.parent))
    assert message in str(error.value) and "\n" not in str(error.value)


def test_marker_study_takes_your_panel(my_panel):
    campaign, folder = StudyCampaign("marker_tilt", DegradationConfig(), "my_panel.yaml")
    assert folder == "marker_tilt_my_panel"
    jobs = ExpandJobs(campaign)
    assert jobs and all(f"panel_file: {my_panel}" in job.scenario_yaml for job in jobs)
