"""The replay drawn after the loop (diagrams/tasks/path_following/replay.py) is the replay
the loop draws when a live page watches it: the same objects and the same animation."""

from pathlib import Path

import numpy as np
import pytest
from replay_commands import Replay

from guidedarm.diagrams.run_context import MakeMeshcat, RunContext
from guidedarm.diagrams.task_run import RunTask
from guidedarm.diagrams.tasks.registry import LoadScenario


def _Replay(out: Path, settings: list[str], live: bool) -> Replay:
    task, scenario, _ = LoadScenario("path_following", settings)
    context = RunContext(out_dir=out, quiet=True)
    # A live page that nobody opens: the loop draws as it runs.
    context.meshcat, context.live = MakeMeshcat(), live
    metrics = RunTask(task, scenario, context)
    assert metrics["steps"] >= 5, metrics
    return Replay(out / "replay.html")


@pytest.mark.parametrize("motion", ["continuous", "joint_trajectory"])
def test_replay_after_the_loop_is_the_loops_drawing(tmp_path, motion):
    settings = ["path=paper_path_4", f"motion={motion}", "estimator=ranging", "max_time=2.5"]
    after = _Replay(tmp_path / "after", settings, live=False)
    during = _Replay(tmp_path / "during", settings, live=True)
    assert sorted(after.objects) == sorted(during.objects)
    assert sorted(after.tracks) == sorted(during.tracks)
    assert any(path.startswith("/overlays/tof") for path, _ in after.tracks)
    hose = {
        k: v for k, v in during.properties.items() if k[0].startswith("/drake/illustration/hose")
    }
    assert hose and {k: after.properties.get(k) for k in hose} == hose  # seen through
    for key, track in during.tracks.items():
        times = [k["time"] for k in track["keys"]]
        assert [k["time"] for k in after.tracks[key]["keys"]] == times, key
        for k_after, k_during in zip(after.tracks[key]["keys"], track["keys"], strict=True):
            np.testing.assert_array_equal(
                np.asarray(k_after["value"], float), np.asarray(k_during["value"], float), key
            )


def test_replay_is_drawn_for_a_cell_whose_tool_has_errors(tmp_path):
    # The drawing leaves the ToF tool out of its scene; the tool's errors go with it.
    offsets = "[0.003, 0.003, 0.003, 0.003, 0.003, 0.003]"
    errors = f"station.errors.tof_tools.tof.offset={offsets}"
    settings = ["path=paper_path_4", "motion=continuous", "max_time=2.5", errors]
    replay = _Replay(tmp_path, settings, live=False)
    assert any(path.startswith("/overlays/tof") for path, _ in replay.tracks)
