"""The live view: `--realtime RATE` paces a run, and the Meshcat page shows its progress."""

from __future__ import annotations

import json

import pytest
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator
from pydrake.systems.primitives import ConstantVectorSource

from guidedarm.diagrams.run_context import PROGRESS_SLIDER, RealtimeRate, RunContext


def test_realtime_rate_paces_the_run(tmp_path, run_cli):
    code, _, _ = run_cli("run", "ur10e_joint_tour", "--out", tmp_path, "--realtime", "4")
    assert code == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    # 4.2 s simulated at 4 x real time take at least 1.05 s of wall-clock time.
    assert summary["wall_time_s"] >= 0.95 * summary["sim_time_s"] / 4


@pytest.mark.parametrize("value", ["-1", "nan"])
def test_a_bad_realtime_rate_is_refused_in_one_line(tmp_path, run_cli, value):
    code, _, err = run_cli("run", "ur10e_joint_tour", "--out", tmp_path, "--realtime", value)
    assert code == 2
    assert err.strip().count("\n") == 0 and "--realtime" in err


def test_rate_defaults_to_real_time_with_meshcat_only():
    assert RealtimeRate(None, meshcat=True) == 1.0
    assert RealtimeRate(None, meshcat=False) == 0.0
    assert RealtimeRate(0.5, meshcat=True) == 0.5


def test_the_page_shows_the_simulated_time(tmp_path):
    meshcat = Meshcat()
    context = RunContext(out_dir=tmp_path, meshcat=meshcat, quiet=True, live=True)
    simulator = Simulator(ConstantVectorSource([0.0]))
    context.pace(simulator, t_final=2.0)
    simulator.AdvanceTo(1.5)
    context.progress("half way", force=True)
    assert meshcat.GetSliderValue(PROGRESS_SLIDER) == pytest.approx(1.5)
    context.pace(simulator, t_final=2.0)  # a second run of the same context
    assert meshcat.GetSliderValue(PROGRESS_SLIDER) == 0.0


def test_a_recording_meshcat_gets_no_progress(tmp_path):
    """Without a live page (the replay recorder of every run) nothing is shown."""
    meshcat = Meshcat()
    context = RunContext(out_dir=tmp_path, meshcat=meshcat, quiet=True)
    simulator = Simulator(ConstantVectorSource([0.0]))
    context.pace(simulator, t_final=2.0)
    simulator.AdvanceTo(1.5)
    context.progress("half way", force=True)
    assert PROGRESS_SLIDER not in meshcat.GetSliderNames()
