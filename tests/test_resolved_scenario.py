"""`guidedarm run DIR/scenario.yaml` repeats the run that wrote it: the resolved scenario
(overrides applied, defaults written out) gives the same steps and errors."""

import json

import pytest

from guidedarm.diagrams.tasks.registry import GetTask, NumericMetricNames

# Keys that describe how and when a run was made, not what it did.
PROVENANCE = {"scenario", "command", "wall_time_s"}
# Measured computing times differ from run to run.
TIMINGS = ("ik_time_", "realtime_factor")  # wall-clock figures differ between runs


def _Summary(out) -> dict:
    summary = json.loads((out / "summary.json").read_text())
    return {
        key: value
        for key, value in summary.items()
        if key not in PROVENANCE and not key.startswith(TIMINGS)
    }


@pytest.mark.parametrize(
    "name, overrides",
    [
        (
            "path_following",
            ["executor=kinematic", "estimator=ranging", "random_seed=3", "path=paper_path_4"],
        ),
        ("panel_operation", ["random_seed=4", "switch=3", "operation.motion=joint_trajectory"]),
    ],
)
@pytest.mark.slow
def test_resolved_scenario_repeats_the_run(tmp_path, run_cli, name, overrides):
    first, second = tmp_path / "first", tmp_path / "second"
    settings = [item for o in overrides for item in ("--set", o)]
    code, _, err = run_cli("run", name, "--out", first, *settings)
    assert code == 0, err
    resolved = first / "scenario.yaml"
    for override in overrides:
        key, _, value = override.partition("=")
        assert f"{key.split('.')[-1]}: {value}" in resolved.read_text()
    code, _, err = run_cli("run", resolved, "--out", second)
    assert code == 0, err
    again = _Summary(second)
    assert again == _Summary(first)
    # The summary carries the numbers its task declares: all of them, except the
    # path-following repeatability figures, which need repeat_random_seed.
    summary = json.loads((first / "summary.json").read_text())
    declared = set(GetTask(name).KnownMetrics())
    if name == "path_following":
        declared -= {"repeatability_mean_mm", "repeatability_max_mm"}
    assert NumericMetricNames(summary) == declared
    assert again.get("steps", again.get("switch_pressed")) is not None
