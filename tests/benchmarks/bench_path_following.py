"""Benchmark of path following: one six-sensor ToF reading (the analytic caster against
sphere tracing, in the same minute), one IK solve, and the real-time factor of full runs
(station and kinematic executors).

Run: .venv/bin/python tests/benchmarks/bench_path_following.py
"""

import time
from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np

from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.station.kinematic_station import MakeKinematicStation
from guidedarm.diagrams.tasks.path_following.setup import MakeSetup
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.tof.tof_tool_sensor_math import RayCaster


def ReadingCost(repeats: int = 300) -> dict[str, tuple[float, float]]:
    """Median CPU ms (process time) of one six-sensor reading (the ranges of the six cones
    from the tool body's pose) with the tool over the hose and with nothing in range: the
    sensor's analytic caster, and sphere tracing (the caster before it) interleaved with
    it, reading for reading, so that both see the same load of the shared machine."""
    _, scenario, _ = LoadScenario("path_following", [])
    setup = MakeSetup(scenario)
    station = MakeKinematicStation(setup.station)
    context = station.CreateDefaultContext()
    command = station.GetInputPort(f"{setup.arm}.position_commanded")
    query_port = station.GetOutputPort("sim.query_object")
    sensor = station.GetSubsystemByName(f"{setup.tool_name}.sensor")
    sensor_context = sensor.GetMyContextFromRoot(context)
    caster = sensor.Caster()
    tracer = RayCaster(caster.rays_S, caster.max_range, caster.ignored)
    costs: dict[str, list[float]] = {"analytic": [], "sphere tracing": []}
    for q in (setup.q_start, np.array([0.0, np.pi / 2, 0.0, 0.0, -np.pi / 2, 0.0])):
        command.FixValue(context, q)
        query = query_port.Eval(context)
        poses = sensor.SensorPosesInWorld(sensor_context)
        caster.MountedRanges(query)  # reads the anchored shapes once
        times: dict[str, list[float]] = {name: [] for name in costs}
        for _ in range(repeats):
            start = time.process_time()
            caster.MountedRanges(query)
            middle = time.process_time()
            [tracer.Range(query, X_WS) for X_WS in poses]
            times["analytic"].append(middle - start)
            times["sphere tracing"].append(time.process_time() - middle)
        for name, values in times.items():
            costs[name].append(1000 * float(np.median(values)))
    return {name: (values[0], values[1]) for name, values in costs.items()}


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
    for name, (over, empty) in ReadingCost().items():
        print(
            f"six-sensor ToF reading, {name}: median {over:.3f} ms over the hose, "
            f"{empty:.3f} ms with nothing in range"
        )
    for executor in ("station", "kinematic"):
        r = RunCost(executor, "paper_path_1")
        print(
            f"paper_path_1, {executor}: {r['steps']} steps, {r['sim_s']:.1f} s simulated in "
            f"{r['wall_s']:.1f} s wall (real-time factor {r['sim_s'] / r['wall_s']:.1f}); "
            f"IK median {r['ik_median_ms']:.1f} ms, p99 {r['ik_p99_ms']:.1f} ms"
        )
    print("IK goal: median <= 10 ms, p99 <= 100 ms per step (the paper: 250 ms mean in Matlab)")
