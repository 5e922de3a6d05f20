"""`guidedarm sweep`: campaign files, job expansion, and runs on the embedded Dask cluster."""

from __future__ import annotations

import csv
import dataclasses
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest
from distributed import Client

from guidedarm.diagrams.campaigns.campaign_file import ListNamedCampaigns, LoadCampaign
from guidedarm.diagrams.campaigns.engine import RunJobs
from guidedarm.diagrams.campaigns.jobs import ExpandJobs
from guidedarm.diagrams.campaigns.results import EmptyMetrics, ParseCell, ResultsTable
from guidedarm.diagrams.scenario_loading import read_raw_scenario
from guidedarm.diagrams.station.station_errors import PRESET_DIR
from guidedarm.diagrams.studies.marker_study import CAMPAIGNS
from guidedarm.diagrams.tasks.registry import AvailableTasks, NumericMetricNames

TOUR = "scenario: ur10e_joint_tour\nset: {settle_time: 0.2}\n"


def _Write(tmp_path: Path, text: str, name: str = "campaign.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def ReadRows(path: Path) -> list[dict]:
    with path.open() as f:
        return [{k: ParseCell(v) for k, v in row.items()} for row in csv.DictReader(f)]


@pytest.mark.parametrize(
    "text, message",
    [
        (TOUR + "gird: {max_speed: [1.0]}\n", "unknown key 'gird'"),
        (TOUR + "grid: {max_speed: []}\n", "grid key 'max_speed' has no values"),
        ("scenario: ur10e_joint_turn\ngrid: {max_speed: [1.0]}\n", "unknown scenario"),
        (TOUR + "grid: {max_sped: [1.0, 2.0]}\n", "unknown key 'max_sped'"),
        (TOUR + "grid: {station.arms.ur10e.gain: [1.0]}\n", "key 'station.arms.ur10e.gain'"),
        (TOUR + "grid: {max_speed: [fast]}\n", "key 'max_speed': expected a number"),
        (TOUR + "zip: {max_speed: [1.0, 2.0], settle_time: [0.1]}\n", "one length"),
        (TOUR + "grid: {settle_time: [0.1, 0.3]}\n", "'settle_time' is in both set and grid"),
        (TOUR + "grid: {max_speed: [1.0, 1.0]}\n", "resolve to the same scenario"),
        (TOUR + "random: {seed: 1, count: 2, draws: {max_speed: {normal: [0, 1]}}}\n", "uniform"),
        (TOUR + "repeat: {count: 3}\n", "repeat needs a scenario key"),
        (TOUR + "metrics: coverage\n", "metrics must be a list"),
        (TOUR + "grid: {max_speed: {linspace: [0.5, 0.6, -3]}}\n", "whole number from 1 to"),
        (TOUR + "grid: {max_speed: {linspace: [0.5, 0.6, 1.0e+8]}}\n", "got 1e+08"),
        (
            TOUR + "grid: {max_speed: {linspace: [0.5, 0.6, 1e12]}}\n",
            "'1e12' is not a finite number (YAML reads it as text: write 1.0e+12)",
        ),
        (TOUR + "grid: {max_speed: {range: [0, .inf, 1]}}\n", "inf is not a finite number"),
        (TOUR + "grid: {max_speed: [0.5, .nan]}\n", "max_speed[1] must be a finite number"),
        (
            TOUR + "grid: {max_speed: {range: [1, 0, 1]}}\n",
            "range length must be a whole number from 1 to 100000, got 0",
        ),
        (
            TOUR + "grid: {max_speed: {linspace: [1, 2, 1000]}, max_time: {range: [1, 1001, 1]}}\n",
            "1000000 jobs, more than the 100000",
        ),
        (
            TOUR + "random: {seed: -1, count: 2, draws: {max_speed: {uniform: [0.4, 0.5]}}}\n",
            "random.seed must be at least 0, got -1",
        ),
        (
            TOUR + "random: {seed: 1, count: 2, draws: {max_speed: {uniform: [.nan, 0.5]}}}\n",
            "max_speed.uniform[0] must be a finite number, got nan",
        ),
        (
            TOUR + "random: {seed: 1, count: 2, draws: {max_speed: {uniform: [0.6, 0.5]}}}\n",
            "need low <= high",
        ),
        (
            TOUR + "random: {seed: 1, count: 2, draws: {max_speed: {integers: [0.5, 3]}}}\n",
            "low and high must be whole numbers",
        ),
        (TOUR + "repeat: {key: random_seed, count: 2, start: -1}\n", "repeat.start (a seed)"),
        (
            TOUR + "metrics: [tracking_error_max_rad, coverage]\n",
            "metric 'coverage' is not a numeric metric of task 'joint_tour' (known: "
            "final_error_rad, sim_time_s, tracking_delay_s, tracking_error_max_rad, "
            "true_final_error_rad, "
            "wall_time_s)",
        ),
        (TOUR + "metrics: [task]\n", "metric 'task' is not a numeric metric"),  # text
        (TOUR + "metrics: [sim_time_s, sim_time_s]\n", "metric 'sim_time_s' is listed twice"),
        (TOUR + "grid: {draw: [1]}\n", "grid key 'draw' is the column that numbers"),
        (
            TOUR + "grid: {station.hardware.arms.ur10e.gain: [500.0, 600.0]}\n",
            "has no effect in a campaign (its jobs run in simulation",
        ),
        (
            TOUR + "grid: {max_speed: [1.0]}\nrepeat: {count: 2}\ngrid: {max_time: [3.0]}\n",
            "campaign.yaml: key 'grid' appears twice (lines 3 and 5)",
        ),
        (TOUR + "set: {max_time: 3.0}\n", "key 'set' appears twice (lines 2 and 3)"),
        (
            TOUR + "grid:\n  max_speed: [1.0]\n  max_time: [3.0]\n  max_speed: [2.0]\n",
            "key 'grid.max_speed' appears twice (lines 4 and 6)",
        ),
    ],
)
def test_bad_campaign_files_are_refused_in_one_line(tmp_path, run_cli, text, message):
    out = tmp_path / "out"
    code, _, err = run_cli("sweep", _Write(tmp_path, text), "--out", out)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("guidedarm: error: ")
    assert message in err
    assert not out.exists()  # refused before anything was written or started


@pytest.mark.parametrize(
    "flags, message",
    [
        (["--workers", "0"], "--workers must be at least 1, got 0"),
        (["--workers", "-1"], "--workers must be at least 1, got -1"),
        (["--workers", "1", "--scheduler", "tcp://x:1"], "not --scheduler"),
    ],
)
@pytest.mark.parametrize("command", ["sweep", "marker-study"])
def test_worker_flags_are_checked_alike(tmp_path, run_cli, command, flags, message):
    target = _Write(tmp_path, TOUR) if command == "sweep" else "press"
    out = tmp_path / "out"
    code, _, err = run_cli(command, target, "--out", out, *flags)
    assert code == 2
    assert err.count("\n") == 1 and message in err
    assert not out.exists()


def test_marker_study_checks_every_campaign_before_the_first_runs(tmp_path, run_cli, monkeypatch):
    # The distance study's second campaign names a metric marker_view does not report.
    bad = _Write(tmp_path, "scenario: marker_view\nmetrics: [vision_mm, coverage]\n")
    monkeypatch.setitem(CAMPAIGNS, "distance", ("marker_distance_straight", str(bad)))
    out = tmp_path / "out"
    code, _, err = run_cli("marker-study", "distance", "--out", out, "--workers", "1")
    assert code == 2 and err.count("\n") == 1
    assert f"{bad}: metric 'coverage' is not a numeric metric of task 'marker_view'" in err
    assert "(known: abs_angle_error_deg, abs_error_mm, ids.#, " in err
    assert not out.exists()  # the first campaign did not run


def test_every_task_declares_its_numeric_metrics():
    """Each task's metrics are compared with a real run's summary.json by a test of its
    own module: joint_tour test_run_command, waypoints test_waypoints_task, marker_view
    test_marker_pose, path_following and panel_operation test_resolved_scenario."""
    tasks = AvailableTasks()
    assert sorted(tasks) == [
        "joint_tour",
        "marker_view",
        "panel_operation",
        "path_following",
        "waypoints",
    ]
    for task in tasks.values():
        assert task.metrics and len(set(task.metrics)) == len(task.metrics)
        assert all(task.HasMetric(m.replace("#", "0")) for m in task.metrics)
    panel = tasks["panel_operation"]
    assert panel.HasMetric("measurements.0.distance_mm") and panel.HasMetric("press_tip_W_mm.2")
    assert not panel.HasMetric("press_error_mm")  # a mapping, not a number
    assert not panel.HasMetric("measurements.first.distance_mm")
    assert not panel.HasMetric("marker_loss")  # text
    assert NumericMetricNames({"a": [{"b": 1, "c": "x"}], "d": True, "e": 2.5}) == {"a.#.b", "e"}


def test_metrics_no_successful_job_has_are_named():
    rows = [
        {"success": True, "coverage": 0.9, "nosuch": None},
        {"success": False, "coverage": None, "nosuch": None},
    ]
    assert EmptyMetrics(rows, ["coverage", "nosuch"]) == ["nosuch"]
    assert EmptyMetrics(rows[1:], ["coverage", "nosuch"]) == []  # no success: no evidence
    assert EmptyMetrics(rows, None) == []


def test_expansion_crosses_the_axes_with_seeded_draws(tmp_path):
    text = (
        "scenario: ur10e_waypoints\n"
        "grid: {limits: [none, velocity]}\n"
        "zip: {max_time: [10.0, 12.0, 14.0], settle_time: [0.1, 0.2, 0.3]}\n"
        "random:\n  seed: 5\n  count: 4\n  draws:\n"
        "    waypoints:\n"
        "      uniform: [[[0.1, -0.6, 0.6, 3.1, 0, 2.3]], [[0.2, -0.5, 0.7, 3.1, 0, 2.3]]]\n"
        "    planner.gain_p: {choice: [10.0, 20.0]}\n"
        "repeat: {key: planner.gain_v, count: 2, start: 9}\n"
    )
    campaign = LoadCampaign(str(_Write(tmp_path, text)))
    jobs = ExpandJobs(campaign)
    assert len(jobs) == 2 * 3 * 4 * 2
    assert len({job.id for job in jobs}) == len(jobs)
    assert campaign.AxisNames() == [
        "limits",
        "max_time",
        "settle_time",
        "draw",
        "waypoints",
        "planner.gain_p",
        "planner.gain_v",
    ]
    # The same file gives the same jobs (the draws are seeded) ...
    assert [j.id for j in ExpandJobs(LoadCampaign(str(tmp_path / "campaign.yaml")))] == [
        j.id for j in jobs
    ]
    # ... and each job's resolved scenario holds its values.
    draws = {j.axes["draw"]: j.axes["waypoints"][0] for j in jobs}
    assert len(draws) == 4
    for waypoint in draws.values():
        assert 0.1 <= waypoint[0] <= 0.2 and -0.6 <= waypoint[1] <= -0.5
    job = jobs[-1]
    assert "limits: velocity\n" in job.scenario_yaml and "gain_v: 10.0" in job.scenario_yaml
    assert f"{job.axes['waypoints'][0][0]!r}" in job.scenario_yaml


def test_every_shipped_campaign_resolves_against_its_scenario():
    sizes = {name: len(LoadCampaign(name).AxisPoints()) for name in ListNamedCampaigns()}
    assert sizes == {
        "errors_markers": 250,
        "errors_moves": 50,
        "errors_panel": 50,
        "errors_repeatability": 50,
        "marker_distance_angled": 13,
        "marker_distance_straight": 13,
        "marker_occlusion": 4,
        "marker_press": 10,
        "marker_repeatability": 16,
        "marker_tilt": 14,
        "path_following_random_hoses": 40,
        "path_following_repeatability": 20,
        "path_following_presets": 96,
        "panel_planner_starts": 150,
        "planner_random_tasks": 60,
    }
    for name in sizes:
        # The first value of every axis: each key of the campaign is a key of its scenario
        # (expanding every job of the big campaigns takes tens of seconds).
        campaign = LoadCampaign(name)
        first = dataclasses.replace(
            campaign,
            grid={k: v[:1] for k, v in campaign.grid.items()},
            zip={k: v[:1] for k, v in campaign.zip.items()},
            random=campaign.random and dataclasses.replace(campaign.random, count=1),
            repeat=campaign.repeat and dataclasses.replace(campaign.repeat, count=1),
        )
        (job,) = ExpandJobs(first)
        assert f"task: {job.task}" in job.scenario_yaml


def test_the_marker_errors_campaign_draws_the_c920_preset():
    """marker_view has no station to name a preset: errors_markers spells out the c920
    preset's camera entry, which must stay what models/errors/c920.yaml says."""
    preset = read_raw_scenario(PRESET_DIR / "c920.yaml")["cameras"]["camera"]
    assert LoadCampaign("errors_markers").set["camera_errors"] == preset


@pytest.mark.slow
def test_sweep_records_rows_failures_and_resumes(tmp_path, run_cli):
    # The middle job passes every check at load but fails its run (final error bound).
    zipped = "zip: {max_speed: [2.5, 2.0, 1.5], max_final_error: [0.01, 1.0e-15, 0.01]}\n"
    campaign = _Write(tmp_path, TOUR + zipped)
    out = tmp_path / "out"
    code, _, err = run_cli("sweep", campaign, "--out", out, "--workers", "2", "--keep-runs")
    assert code == 0, err
    rows = ReadRows(out / "results.csv")
    assert [r["max_speed"] for r in rows] == [2.5, 2.0, 1.5]  # in the campaign's order
    fast, bad, slow = rows
    # A job whose run fails is that job's row, not the end of the campaign.
    assert bad["success"] is False and "max_final_error" in bad["failure"]
    for r in (fast, slow):
        assert r["success"] is True and r["failure"] is None and r["wall_time_s"] > 0.1
        assert r["tracking_error_max_rad"] < 0.02
        assert (out / "runs" / r["job_id"] / "summary.json").is_file()
    assert slow["sim_time_s"] > fast["sim_time_s"] + 0.5
    assert "ETA" in err and "[3/3]" in err
    report = (out / "report.html").read_text()
    assert report.count("<svg") >= 3 and "success 2 / 3" in report
    assert "max_speed: [2.5, 2.0, 1.5]" in (out / "campaign.yaml").read_text()
    before = (out / "results.csv").read_text()

    # Rerun into the same DIR: nothing to do.
    code, _, err = run_cli("sweep", campaign, "--out", out, "--workers", "1")
    assert code == 0 and "3 done already, 0 to run" in err
    assert (out / "results.csv").read_text() == before

    # Extend the grid: only the new job runs.
    zipped = (
        "zip: {max_speed: [2.5, 2.0, 1.5, 2.0], max_final_error: [0.01, 1.0e-15, 0.01, 0.02]}\n"
    )
    _Write(tmp_path, TOUR + zipped)
    code, _, err = run_cli("sweep", campaign, "--out", out, "--workers", "1")
    assert code == 0 and "3 done already, 1 to run" in err and "[1/1] max_speed=2.0" in err
    rows = ReadRows(out / "results.csv")
    assert [r["max_speed"] for r in rows] == [2.5, 2.0, 1.5, 2.0]
    assert [r["job_id"] for r in rows[:3]] == [fast["job_id"], bad["job_id"], slow["job_id"]]

    # Results of another campaign in DIR are not mixed in.
    other = _Write(tmp_path, TOUR + "grid: {max_speed: [0.9]}\n", "other.yaml")
    code, _, err = run_cli("sweep", other, "--out", out)
    assert code == 2 and "not in this campaign" in err


@pytest.mark.slow
def test_ctrl_c_leaves_a_consistent_table_and_the_rerun_finishes(tmp_path):
    campaign = _Write(tmp_path, TOUR + "grid: {max_speed: [2.0, 2.2, 2.4, 2.6, 2.8, 3.0]}\n")
    out = tmp_path / "out"
    command = [sys.executable, "-m", "guidedarm.diagrams.cli.main", "sweep", str(campaign)]
    command += ["--out", str(out), "--workers", "2"]
    process = subprocess.Popen(command, stderr=subprocess.PIPE, text=True, start_new_session=True)
    table = out / "results.csv"
    deadline = time.monotonic() + 60
    while not (table.exists() and len(ReadRows(table)) >= 2) and time.monotonic() < deadline:
        time.sleep(0.1)
    # While it runs, the cluster listens on the loopback interface only.
    tree = [psutil.Process(process.pid), *psutil.Process(process.pid).children(recursive=True)]
    listening = [
        c.laddr.ip
        for p in tree
        for c in p.net_connections(kind="inet")
        if c.status == psutil.CONN_LISTEN
    ]
    assert listening and set(listening) == {"127.0.0.1"}
    os.killpg(process.pid, signal.SIGINT)  # Ctrl-C in a terminal reaches the whole group
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130, err
    rows = ReadRows(table)
    assert table.read_text().endswith("\n")
    # Jobs that finished are rows; a job stopped on its worker may be an `engine:` row,
    # which the rerun runs again.
    done = [r for r in rows if r["success"] is True]
    assert 2 <= len(done) < 6 and len(rows) < 6
    assert all(r["failure"].startswith("engine: ") for r in rows if r not in done)

    command[-1] = "1"  # --workers 1
    code = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert code.returncode == 0, code.stderr
    assert f"{len(done)} done already, {6 - len(done)} to run" in code.stderr
    final = ReadRows(table)
    assert sorted(r["max_speed"] for r in final) == [2.0, 2.2, 2.4, 2.6, 2.8, 3.0]
    assert len({r["job_id"] for r in final}) == 6
    assert all(r["success"] is True for r in final)


def test_a_job_that_breaks_outside_its_task_is_a_lost_row_run_again(tmp_path):
    jobs = ExpandJobs(LoadCampaign(str(_Write(tmp_path, TOUR + "grid: {max_speed: [2.5]}\n"))))
    table = ResultsTable(tmp_path / "results.csv", ["max_speed"])
    not_a_folder = _Write(tmp_path, "", "file")  # the job cannot make its run folder here
    # As the engine's own cluster: the scheduler's HTTP endpoints on a free loopback port,
    # not 8787, which another test's cluster may hold.
    local = {
        "host": "127.0.0.1",
        "protocol": "tcp",
        "dashboard_address": None,
        "scheduler_kwargs": {"dashboard": False, "dashboard_address": "127.0.0.1:0"},
    }
    with Client(processes=False, n_workers=1, threads_per_worker=1, **local) as c:
        outcome = RunJobs(c, jobs, table, None, runs_dir=not_a_folder, progress=print)
    assert (outcome.ran, outcome.lost) == (1, 1)
    (row,) = ReadRows(tmp_path / "results.csv")
    assert row["success"] is False and row["failure"].startswith("engine: NotADirectoryError")
    assert ResultsTable(tmp_path / "results.csv", ["max_speed"]).DoneIds() == set()


@pytest.mark.slow
def test_a_campaign_whose_every_job_fails_exits_1_with_the_count(tmp_path, run_cli):
    text = TOUR.replace("settle_time: 0.2", "settle_time: 0.2, max_final_error: 1.0e-15")
    campaign = _Write(tmp_path, text + "metrics: [final_error_rad]\n")
    out = tmp_path / "out"
    code, stdout, err = run_cli("sweep", campaign, "--out", out, "--workers", "1")
    assert code == 1, err
    assert "failed: 1" in stdout and "guidedarm: all 1 job(s) failed, the first: " in err
    assert "Traceback" not in err
    (row,) = ReadRows(out / "results.csv")
    assert row["success"] is False and row["final_error_rad"] > 1e-15
    assert "success 0 / 1 (0.0 %)" in (out / "report.html").read_text()


@pytest.mark.slow
def test_sigterm_ends_the_campaign_with_its_report_and_no_worker_left(tmp_path):
    """SIGTERM to the command alone (as `kill` or a service manager sends it), three times:
    the first stops the jobs, the others do not cut the cluster's shutdown or the report."""
    campaign = _Write(tmp_path, TOUR + "grid: {max_speed: [2.0, 2.2, 2.4, 2.6, 2.8, 3.0]}\n")
    out = tmp_path / "out"
    command = [sys.executable, "-m", "guidedarm.diagrams.cli.main", "sweep", str(campaign)]
    command += ["--out", str(out), "--workers", "2"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    table = out / "results.csv"
    deadline = time.monotonic() + 90
    while not (table.exists() and ReadRows(table)) and time.monotonic() < deadline:
        time.sleep(0.1)
    children = psutil.Process(process.pid).children(recursive=True)
    assert len(children) >= 2  # the two workers (and multiprocessing's helpers)
    for _ in range(3):
        process.send_signal(signal.SIGTERM)
        time.sleep(0.2)
    stdout, err = process.communicate(timeout=60)
    assert process.returncode == 130, err
    assert "Traceback" not in err and "interrupted; run the same command again" in err
    assert "report.html" in stdout
    rows = ReadRows(table)
    assert 1 <= len(rows) < 6
    assert f"{len(rows)} of 6 jobs done" in (out / "report.html").read_text()
    _, alive = psutil.wait_procs(children, timeout=10)
    assert not alive, [p.cmdline() for p in alive]
