"""Benchmark of the seed-001 planner: cost of one 500 Hz step and real-time factors.

Run: .venv/bin/python tests/benchmarks/bench_planner.py
Goal (issue 3): the variant-3 task (both limits) at least 10x faster than real time.
"""

import time

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from guidedarm.diagrams.cli.command_run import LoadScenario
from guidedarm.diagrams.tasks.waypoints import MakePlannerSetup
from guidedarm.systems.planning.acceleration_planner import AccelerationPlanner
from guidedarm.systems.planning.acceleration_planner_math import RunPlanning


def main() -> None:
    _, scenario, _ = LoadScenario("ur10e_waypoints", [])
    setup = MakePlannerSetup(scenario)
    planning = setup.planning

    state = planning.InitialState(setup.q0)
    durations = []
    while not state.done:
        start = time.perf_counter()
        state = planning.Step(state)
        durations.append(time.perf_counter() - start)
    steps = np.array(durations) * 1e6
    print(f"planner step: median {np.median(steps):.1f} us, p95 {np.percentile(steps, 95):.1f} us")

    task_time = state.done_time
    start = time.perf_counter()
    RunPlanning(planning, setup.q0, max_time=scenario.max_time)
    wall = time.perf_counter() - start
    print(
        f"variant-3 task, law alone: {task_time:.2f} s in {wall:.3f} s -> {task_time / wall:.1f}x"
    )

    builder = DiagramBuilder()
    planner = builder.AddSystem(AccelerationPlanner(planning))
    source = builder.AddSystem(ConstantVectorSource(np.concatenate([setup.q0, np.zeros(6)])))
    builder.Connect(source.get_output_port(), planner.get_input_port())
    simulator = Simulator(builder.Build())
    simulator.Initialize()
    start = time.perf_counter()
    simulator.AdvanceTo(task_time)
    wall = time.perf_counter() - start
    print(
        f"variant-3 task, AccelerationPlanner in a Diagram at 500 Hz: {task_time:.2f} s in "
        f"{wall:.3f} s -> {task_time / wall:.1f}x real time (goal >= 10x)"
    )


if __name__ == "__main__":
    main()
