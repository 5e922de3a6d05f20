"""Benchmark of path following: one six-sensor ToF reading, one IK solve, and the
real-time factor of full runs (station and kinematic executors).

Run: .venv/bin/python tests/benchmarks/bench_path_following.py
"""

import time
from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np

from guidedarm.diagrams.cli.command_run import LoadScenario
from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.tasks.path_following_diagram import MakeKinematicStation
from guidedarm.diagrams.tasks.path_following_setup import MakeSetup


def ReadingCost(repeats: int = 50) -> tuple[float, float]:
    """(ms per reading with the tool over the hose, ms with nothing in range)."""
    _, scenario, _ = LoadScenario("path_following", [])
    setup = MakeSetup(scenario)
    station = MakeKinematicStation(setup.station)
    context = station.CreateDefaultContext()
    command = station.GetInputPort(f"{setup.arm}.position_commanded")
    sensor = station.GetSubsystemByName(f"{setup.tool_name}.sensor")
    sensor_context = sensor.GetMyContextFromRoot(context)
    costs = []
    for q in (setup.q_start, np.array([0.0, np.pi / 2, 0.0, 0.0, -np.pi / 2, 0.0])):
        command.FixValue(context, q)
        start = time.perf_counter()
        for _ in range(repeats):
            sensor.TrueRanges(sensor_context)
        costs.append(1000 * (time.perf_counter() - start) / repeats)
    return costs[0], costs[1]


def RunCost(executor: str, path: str) -> dict:
    _, scenario, _ = LoadScenario("path_following", [f"executor={executor}", f"path={path}"])
    task, _, _ = LoadScenario("path_following", [])
    with TemporaryDirectory() as tmp:
        start = time.perf_counter()
        summary = task.run(scenario, RunContext(out_dir=Path(tmp), quiet=True))
        wall = time.perf_counter() - start
    return {
        "wall_s": wall,
        "sim_s": summary["sim_time_s"],
        "steps": summary["steps"],
        "ik_median_ms": summary["ik_time_median_ms"],
        "ik_p99_ms": summary["ik_time_p99_ms"],
    }


if __name__ == "__main__":
    over, empty = ReadingCost()
    print(
        f"six-sensor ToF reading: {over:.2f} ms over the hose, {empty:.2f} ms with nothing in range"
    )
    for executor in ("station", "kinematic"):
        r = RunCost(executor, "paper_path_1")
        print(
            f"paper_path_1, {executor}: {r['steps']} steps, {r['sim_s']:.1f} s simulated in "
            f"{r['wall_s']:.1f} s wall (real-time factor {r['sim_s'] / r['wall_s']:.1f}); "
            f"IK median {r['ik_median_ms']:.1f} ms, p99 {r['ik_p99_ms']:.1f} ms"
        )
    print("IK goal: median <= 10 ms, p99 <= 100 ms per step (the paper: 250 ms mean in Matlab)")
