"""Scenario files: typed loading, errors naming the key, `--set` overrides."""

from __future__ import annotations

import re

import pytest

from guidedarm.diagrams.scenario_loading import ScenarioError, parse_overrides
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.errors import ConfigurationError

GOOD = """\
task: joint_tour
arm: ur10e
waypoints: [[0, 0, 0, 0, 0, 0]]
station:
  directives:
  - add_directives: {file: package://guidedarm/directives/ur10e.dmd.yaml}
  arms:
    ur10e: {kp: 900}
  cameras:
    top:
      width: 64
      height: 48
      X_PB:
        translation: [0, 0, 2]
        rotation: !Rpy { deg: [180, 0, 0] }
"""


def write(tmp_path, text: str):
    path = tmp_path / "scenario.yaml"
    path.write_text(text)
    return str(path)


def test_good_scenario_loads_typed(tmp_path):
    task, scenario, name = LoadScenario(write(tmp_path, GOOD), [])
    assert task.name == "joint_tour" and name == "scenario"
    assert scenario.station.arms["ur10e"].kp == 900.0
    assert scenario.station.cameras["top"].width == 64
    X_PB = scenario.station.cameras["top"].X_PB.GetDeterministicValue()
    assert X_PB.translation()[2] == pytest.approx(2.0)
    assert X_PB.rotation().matrix()[2, 2] == pytest.approx(-1.0)


@pytest.mark.parametrize(
    "text, expected",
    [
        (GOOD + "colour: red\n", "unknown key 'colour'"),
        (GOOD.replace("kp: 900", "kp: 900, kq: 1"), "unknown key 'station.arms.ur10e.kq'"),
        (GOOD.replace("kp: 900", "kp: fast"), "key 'station.arms.ur10e.kp': expected a number"),
        (GOOD.replace("width: 64", "width: 6.4"), "station.cameras.top"),
        (GOOD.replace("waypoints: [[0, 0, 0, 0, 0, 0]]", "waypoints: 3"), "key 'waypoints'"),
        (GOOD.replace("[0, 0, 2]", "[0, 2]"), "station.cameras.top.X_PB"),
        (GOOD.replace("task: joint_tour", "task: juggling"), "unknown task 'juggling'"),
        (GOOD.replace("task: joint_tour\n", ""), "missing key 'task'"),
        ("task: [joint_tour\n", "malformed YAML"),
        (GOOD + "arm: ur10e\n", "key 'arm' appears twice (lines 2 and 16)"),
        (GOOD + "arm: ur10e\narm: ur10e\n", "key 'arm' appears 3 times (lines 2, 16 and 17)"),
        (GOOD.replace("kp: 900", "kp: 900, kp: 400"), "'station.arms.ur10e.kp' appears twice"),
        (
            GOOD.replace(
                "translation: [0, 0, 2]", "translation: [0, 0, 2]\n        base_frame: a"
            ).replace("rotation:", "base_frame: b\n        rotation:"),
            "key 'station.cameras.top.X_PB.base_frame' appears twice (lines 15 and 16)",
        ),
        (
            GOOD.replace(
                "  - add_directives: {file: package://guidedarm/directives/ur10e.dmd.yaml}",
                "  - add_directives: {file: a.yaml, file: b.yaml}",
            ),
            "key 'station.directives[0].add_directives.file' appears twice (line 6)",
        ),
    ],
)
def test_bad_scenario_names_the_cause(tmp_path, text, expected):
    with pytest.raises(ConfigurationError, match=re.escape(expected)):
        LoadScenario(write(tmp_path, text), [])


def test_overrides_reach_nested_keys_and_are_typed(tmp_path):
    _, scenario, _ = LoadScenario(
        write(tmp_path, GOOD), ["max_speed=0.25", "station.arms.ur10e.kp=400"]
    )
    assert scenario.max_speed == 0.25
    assert scenario.station.arms["ur10e"].kp == 400.0
    with pytest.raises(ScenarioError, match=r"unknown key 'station\.arms\.ur10e\.gain'"):
        LoadScenario(write(tmp_path, GOOD), ["station.arms.ur10e.gain=1"])
    with pytest.raises(ScenarioError, match="key 'max_speed': expected a number"):
        LoadScenario(write(tmp_path, GOOD), ["max_speed=fast"])


def test_override_syntax_errors():
    assert parse_overrides(["limits=velocity,acceleration"]) == {"limits": "velocity,acceleration"}
    with pytest.raises(ScenarioError, match="key=value"):
        parse_overrides(["limits"])


@pytest.mark.parametrize(
    "items, message",
    [
        (["max_speed=1", "max_speed=1"], "--set max_speed given twice (1, 1): give it once"),
        (["a.b=1", "c=2", "a.b=3", "a.b=4"], "--set a.b given 3 times (1, 3, 4): give it once"),
        (["a.b.c=1", "a={b: {}}"], "--set a.b.c and --set a both given"),
        (["a={b: {}}", "a.b.c=1"], "--set a and --set a.b.c both given"),
        (["a={b: 1, b: 2}"], "--set a: key 'b' appears twice"),
        (["a=[{b: 1}, {c: [{d: 1, d: 1}]}]"], "--set a: key '[1].c[0].d' appears twice"),
    ],
)
def test_a_key_set_twice_is_refused(items, message):
    """--set KEY twice, or a key beside a part of it, would keep one value silently (the
    last, or the part merged into the whole in one order and lost in the other)."""
    with pytest.raises(ScenarioError) as refused:
        parse_overrides(items)
    assert str(refused.value) == message or str(refused.value).startswith(message)


def test_keys_of_one_prefix_that_do_not_overlap_are_accepted():
    assert parse_overrides(["a.b=1", "a.bc=2", "ab=3"]) == {"a.b": 1, "a.bc": 2, "ab": 3}


def test_unknown_named_scenario_lists_the_known_ones():
    with pytest.raises(ScenarioError, match=r"unknown scenario 'nope'.*ur10e_joint_tour"):
        LoadScenario("nope", [])


def test_cli_reports_bad_scenario_in_one_line(tmp_path, run_cli):
    code, _, err = run_cli("run", write(tmp_path, GOOD + "colour: red\n"), "--out", tmp_path)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "unknown key 'colour'" in lines[0]
    assert "Traceback" not in err


def test_a_rule_between_fields_names_the_set_that_broke_it():
    """A --set that breaks a rule between the fields of a section (continuous: loss_distance
    < look_ahead) is named beside the scenario file, not left for the user to guess."""
    from guidedarm.diagrams.scenario_loading import ScenarioError
    from guidedarm.diagrams.tasks.registry import LoadScenario

    with pytest.raises(ScenarioError) as refused:
        LoadScenario("path_following", ["motion=continuous", "continuous.look_ahead=0.008"])
    assert str(refused.value).endswith(
        "path_following.yaml with --set continuous.look_ahead: key 'continuous': continuous: "
        "need loss_distance < look_ahead"
    )


@pytest.mark.parametrize(
    "scenario, override, expected",
    [
        (
            "path_following",
            "motion=continuos",
            "--set key 'motion': 'continuos' is not one of 'joint_trajectory', 'planner', "
            "'continuous'",
        ),
        ("ur10e_waypoints", "limits=fast", "--set limits must be one of"),
        (
            "panel_operation",
            "operation.motion=teleport",
            "--set key 'operation.motion': 'teleport' is not one of",
        ),
    ],
)
def test_a_refused_set_value_names_the_flag_not_the_scenario_file(scenario, override, expected):
    with pytest.raises(ConfigurationError) as error:
        LoadScenario(scenario, [override])
    assert str(error.value).startswith(expected), str(error.value)
    assert ".yaml" not in str(error.value)


def test_a_path_csv_clears_the_path_it_replaces(tmp_path):
    from guidedarm.diagrams.run_labels import RunTitle

    hose = tmp_path / "my_hose.csv"
    hose.write_text("x,y,z\n0.24,-0.28,0.11\n0.24,-0.18,0.11\n0.24,-0.08,0.11\n")
    overrides = [f"path_csv={hose}"]
    _, scenario, name = LoadScenario("path_following", overrides)
    assert scenario.path == "" and scenario.path_csv == str(hose)
    title = RunTitle(name, scenario, overrides)
    assert "paper_path" not in title and "my_hose.csv" in title
