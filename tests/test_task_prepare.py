"""The prepare step of a run: `guidedarm run` calls the task's prepare once, before it
announces the run and before --out exists, and the run reuses what prepare made."""

from __future__ import annotations

import dataclasses

import numpy as np

import guidedarm.diagrams.tasks.joint_tour as joint_tour
from guidedarm.diagrams.tasks.joint_tour.run import PrepareJointTour, RunJointTour

# A one-waypoint tour 0.05 rad from the ur10e scenario's start: the shortest complete run.
NEAR_START = "waypoints=[[-1.5708, -1.5708, -2.306194, -0.785398, 1.5708, 0.785398]]"


def test_run_prepares_once_before_announcing_and_reuses_it(run_cli, tmp_path, monkeypatch):
    out = tmp_path / "out"
    made, given = [], []

    def prepare(scenario):
        assert not out.exists(), "prepare ran after --out was made"
        made.append(PrepareJointTour(scenario))
        return made[-1]

    def run(scenario, context, prepared):
        given.append(prepared)
        return RunJointTour(scenario, context, prepared)

    task = dataclasses.replace(joint_tour.TASK, prepare=prepare, run=run)
    monkeypatch.setattr(joint_tour, "TASK", task)
    code, stdout, err = run_cli("run", "ur10e_joint_tour", "--out", out, "--set", NEAR_START)
    assert code == 0, err
    assert "running" in stdout
    assert len(made) == 1 and len(given) == 1 and given[0] is made[0]
    tour = made[0].trajectory
    np.testing.assert_allclose(tour.value(tour.end_time())[2], -2.306194)
