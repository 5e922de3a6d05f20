"""`guidedarm describe`: every scenario key with its type, default or value, and a doc line."""

from __future__ import annotations

import dataclasses
import re

import pytest

from guidedarm.diagrams.cli.command_describe import DescribeScenario, FieldDocs
from guidedarm.diagrams.scenario_loading import list_named_scenarios
from guidedarm.diagrams.tasks.registry import AvailableTasks, LoadScenario


def _table(out: str) -> dict[str, list[str]]:
    """key -> [type, value, doc] of the leaf rows (columns are 2+ spaces apart)."""
    rows = [re.split(r"\s{2,}", line, maxsplit=3) for line in out.splitlines()[2:]]
    return {row[0]: row[1:] for row in rows if len(row) == 4}


def _undocumented(rows) -> list[str]:
    return [r.key for r in rows if not r.doc.strip()]


@pytest.mark.parametrize("task", sorted(AvailableTasks()))
def test_every_key_of_every_task_has_a_doc_line(task):
    schema = AvailableTasks()[task].scenario_type
    rows = DescribeScenario(schema())
    assert _undocumented(rows) == []
    keys = {r.key for r in rows}
    for f in dataclasses.fields(schema):  # the top level is complete ...
        assert f.name in keys
    # ... and so is every nested level: the station's Drake structs with their fields
    if "station" not in keys:
        return
    for nested in ("station.plant_config.time_step", "station.cameras.<name>.X_PB.base_frame"):
        assert nested in keys


@pytest.mark.parametrize("name", list_named_scenarios())
def test_every_key_of_every_named_scenario_has_a_doc_line(name):
    _, scenario, _ = LoadScenario(name, [])
    assert _undocumented(DescribeScenario(scenario)) == []


def test_field_docs_read_name_text_entries():
    @dataclasses.dataclass
    class Example:
        """An example: the first line is no entry.

        alpha, beta: two gains (1/s); gamma: a
            length (m).
        delta: `x` or `y`.

        A closing paragraph is no part of delta's line.
        """

        alpha: float = 0.0
        beta: float = 0.0
        gamma: float = 0.0
        delta: str = "x"
        epsilon: int = 0

    assert FieldDocs(Example) == {
        "alpha": "two gains (1/s)",
        "beta": "two gains (1/s)",
        "gamma": "a length (m).",
        "delta": "`x` or `y`.",
    }


def test_describe_a_task_prints_defaults(run_cli):
    code, out, _ = run_cli("describe", "waypoints")
    assert code == 0
    assert out.splitlines()[0].startswith("task waypoints")
    lines = _table(out)
    assert lines["planner.gain_p"][:2] == ["float", "20.0"]
    assert lines["station.arms.<name>.kp"][:2] == ["float", "1600.0"]
    assert "Lambda_P" in lines["planner.gain_p"][2]


def test_describe_a_scenario_prints_its_values_with_overrides(run_cli):
    code, out, _ = run_cli("describe", "panel_operation", "--set", "switch=3")
    assert code == 0
    rows = _table(out)
    assert rows["switch"][:2] == ["int", "3"]
    assert rows["station.cameras.camera.width"][:2] == ["int", "1920"]
    assert rows["station.cameras.camera.X_PB.base_frame"][1] == "rover_gripper::camera"
    code, out, _ = run_cli("describe", "panel_operation", "--defaults")
    assert code == 0 and "station.cameras.<name>.width" in out


def test_unknown_target_is_one_line(run_cli):
    code, _, err = run_cli("describe", "nosuch")
    assert code == 2
    assert len(err.strip().splitlines()) == 1
    assert "unknown task or scenario 'nosuch' (tasks: joint_tour" in err


@pytest.mark.parametrize("task", sorted(AvailableTasks()))
def test_every_metric_of_every_task_has_a_unit_and_a_meaning(task):
    docs = AvailableTasks()[task].MetricDocs()
    assert docs
    assert [name for name, (unit, meaning) in docs.items() if not unit or len(meaning) < 10] == []


def test_describe_metrics_defines_each_summary_key(run_cli):
    code, out, _ = run_cli("describe", "path_following_continuous", "--metrics")
    assert code == 0
    rows = {line.split()[0]: line.split(maxsplit=2)[1:] for line in out.splitlines()[2:]}
    assert rows["lost_steps"][0] == "count" and "did not detect the hose" in rows["lost_steps"][1]
    assert rows["tracking_error_mean_mm"][0] == "mm"
    assert {"success", "failure", "wall_time_s", "sim_time_s"} <= rows.keys()
    code, _, err = run_cli("describe", "path_following", "--metrics", "--set", "motion=continuous")
    assert code == 2 and "--set has no effect with --metrics" in err
