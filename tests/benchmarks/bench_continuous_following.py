"""Stop-and-go against continuous path following through the station: the four paper
paths and random_0..19 with the ranging estimator in `continuous` mode, the paper paths
also stop-and-go (joint_trajectory) and continuous with the grid estimator. Prints one
row per run (success, coverage, average speed, tracking mean / max, collisions, simulated
time, the run's wall time, and the summary's realtime_factor: simulated over wall-clock
time of the follower's loop on the station, setup and report excluded) and the
continuous set's totals against the goals (speed >= 80 mm/s, tracking mean <= 3 mm,
max <= 10 mm).

    .venv/bin/python tests/benchmarks/bench_continuous_following.py [--quick] [--more]
        [--paths P1,P2,...] [--load] [--set KEY=VALUE ...]

    .venv/bin/python tests/benchmarks/bench_continuous_following.py --breakdown PATH
        [--set KEY=VALUE ...]

    .venv/bin/python tests/benchmarks/bench_continuous_following.py --floor PATH
        [--set KEY=VALUE ...]

    .venv/bin/python tests/benchmarks/bench_continuous_following.py --rtf PATH [N]
        [--load] [--set KEY=VALUE ...]

    .venv/bin/python tests/benchmarks/bench_continuous_following.py --percall PATH [T]
        [--set KEY=VALUE ...]

--quick: paper paths only; --more: random_20..39 too; --paths: these hoses only (e.g.
paper_path_1,random_11); --load: one core kept busy by a process the benchmark starts
and stops itself (a pure-Python spin loop), so that "with one core busy" is the same load
wherever it runs (also with --rtf); --set: scenario overrides passed to every run (e.g.
--set station.plant_config.time_step=0.004 or --set station.hose.brackets=3). --breakdown: one
continuous ranging run on PATH in this process, printing the CPU time (process time,
which other processes' load disturbs less than wall time) per simulated second of the
simulation loop and of each per-tick Python system in it (the rest of the loop is the
plant and SceneGraph, the servo's C++ systems, loggers and the framework's event
dispatch), and of the replay's overlays, drawn after the loop. --floor: the same figure
for the station alone, with and without its ToF sensor, its arm held at PATH's start
pose and its arm driven along the joints a continuous run of PATH measured: the cost no
follower can go below. --rtf: N (default 5) continuous ranging runs
of PATH, alternating `guidedarm run` (which draws the Meshcat replay after the loop) and
the same run without Meshcat (as a campaign worker runs it: no replay), each in its own
process; prints each run's realtime_factor, the median of each kind and whether the
medians meet the goal (>= 10 on an idle machine, >= 5 with --load). --percall: the CPU
time of one call of each per-tick Python callback (the servo's update, the follower's
update on a tick without a reading and what a reading adds to it, the ToF sensor's
reading and its ray casting), the least of several repeats at the loop's context T
(default 3.004) simulated seconds into a continuous ranging run of PATH, times its rate:
CPU s per simulated s with warm caches and inputs already evaluated, so less than the
loop pays for the same calls (--breakdown). One run after another (about 10-30 s each in
continuous mode, minutes stop-and-go).
"""

import collections
import contextlib
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

GUIDEDARM = str(Path(sys.executable).with_name("guidedarm"))
# The real-time factor the continuous loop must reach (issue 31): on an idle machine, and
# with one core busy (--load).
RTF_GOAL, RTF_GOAL_LOADED = 10.0, 5.0
FIELDS = (
    "success",
    "coverage",
    "average_speed_mm_s",
    "tracking_error_mean_mm",
    "tracking_error_max_mm",
    "collisions",
    "sim_time_s",
)


def Overrides(argv: list[str]) -> list[str]:
    """The `--set KEY=VALUE` pairs of argv, as guidedarm arguments."""
    return [arg for k, a in enumerate(argv[:-1]) if a == "--set" for arg in ("--set", argv[k + 1])]


def RunOne(path: str, motion: str, estimator: str) -> dict:
    """The summary of one `guidedarm run` (its output folder removed), with its wall time."""
    with tempfile.TemporaryDirectory(prefix="bench_cont_") as out:
        start = time.perf_counter()
        run = subprocess.run(
            [
                GUIDEDARM,
                "run",
                "path_following",
                "--out",
                out,
                "--set",
                f"path={path}",
                "--set",
                f"motion={motion}",
                "--set",
                f"estimator={estimator}",
                *Overrides(sys.argv),
            ],
            capture_output=True,
            text=True,
            check=False,
        )
        if not (Path(out) / "summary.json").is_file():
            last = (run.stderr.strip().splitlines() or ["no output"])[-1]
            sys.exit(f"bench_continuous_following: {path} {motion} wrote no summary: {last}")
        summary = json.loads((Path(out) / "summary.json").read_text())
        summary["wall_s"] = round(time.perf_counter() - start, 1)
    summary["rtf"] = summary.get("realtime_factor")
    return summary


def Breakdown(path: str) -> None:
    """Prints the loop's and each per-tick system's CPU seconds per simulated second."""
    from guidedarm.diagrams.cli.main import main as guidedarm_main
    from guidedarm.diagrams.tasks.path_following import execution as path_following_execution
    from guidedarm.systems.path_following import continuous_follower, differential_ik_servo
    from guidedarm.systems.tof import tof_tool_sensor

    cpu: dict[str, float] = collections.defaultdict(float)

    def Timed(owner: object, name: str, label: str) -> None:
        f = getattr(owner, name)

        def g(*args, **kwargs):
            start = time.process_time()
            try:
                return f(*args, **kwargs)
            finally:
                cpu[label] += time.process_time() - start

        setattr(owner, name, g)

    from guidedarm.systems.visualization import (
        detected_path_overlay,
        frame_trail_overlay,
        tof_tool_overlay,
    )

    servo = differential_ik_servo.DifferentialIkServo
    overlay = "Meshcat overlays (the replay, after the loop)"
    follower = continuous_follower.ContinuousFollower
    timed = (
        (servo, "_Update", "DifferentialIkServo"),
        (servo, "_BodyAtWall", "  wall check"),
        (differential_ik_servo, "ServoPeriod", "  ServoPeriod (its kernel)"),
        (follower, "_Update", "ContinuousFollower"),
        (follower, "_Read", "  readings"),
        (continuous_follower, "Advance", "  Advance"),
        (tof_tool_sensor.ToFToolSensor, "_Measure", "ToF sensor"),
        (tof_tool_overlay.ToFToolOverlay, "_PublishPose", overlay),
        (tof_tool_overlay.ToFToolOverlay, "_PublishReading", overlay),
        (detected_path_overlay.DetectedPathOverlay, "_Publish", overlay),
        (frame_trail_overlay.FrameTrailOverlay, "_Publish", overlay),
    )
    for owner, name, label in timed:
        Timed(owner, name, label)

    class TimedSimulator(path_following_execution.Simulator):
        def AdvanceTo(self, t: float):
            start = time.process_time()
            try:
                return super().AdvanceTo(t)
            finally:
                cpu["simulation loop"] += time.process_time() - start

    path_following_execution.Simulator = TimedSimulator
    with tempfile.TemporaryDirectory(prefix="bench_cont_") as out:
        args = ["run", "path_following", "--out", out, "--set", f"path={path}"]
        args += ["--set", "motion=continuous", "--set", "estimator=ranging"]
        sys.argv = ["guidedarm", *args, *Overrides(sys.argv)]
        with contextlib.suppress(SystemExit):  # the CLI exits with the run's status
            guidedarm_main()
        s = json.loads((Path(out) / "summary.json").read_text())
    sim = s["sim_time_s"]
    print(f"{path}: {sim} s simulated, realtime_factor {s['realtime_factor']} (wall)")
    print(
        f"speed {s['average_speed_mm_s']} mm/s, tracking {s['tracking_error_mean_mm']} / "
        f"{s['tracking_error_max_mm']} mm; CPU s per simulated s:"
    )
    for label in dict.fromkeys(["simulation loop", *(label for _, _, label in timed)]):
        print(f"  {label:40s} {cpu[label] / sim:.3f}")


def Floor(path: str, seconds: float = 4.0) -> None:
    """Prints the CPU time per simulated second of the station alone, with its ToF tool
    sensor and without it (plant, SceneGraph and servo only): its arm held at the start
    pose of PATH for `seconds`, and its arm driven along the joints a continuous ranging
    run of PATH measured (commanded by their linear interpolation): what no follower can
    go below, at rest and moving."""
    import copy

    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantVectorSource, TrajectorySource
    from pydrake.trajectories import PiecewisePolynomial

    from guidedarm.diagrams.run_context import RunContext
    from guidedarm.diagrams.station.station import MakeStation
    from guidedarm.diagrams.tasks.path_following.execution import Execute
    from guidedarm.diagrams.tasks.path_following.setup import MakeSetup
    from guidedarm.diagrams.tasks.registry import LoadScenario

    settings = [f"path={path}", "motion=continuous", "estimator=ranging"]
    setup = MakeSetup(LoadScenario("path_following", [*settings, *Overrides(sys.argv)[1::2]])[1])
    with tempfile.TemporaryDirectory(prefix="bench_cont_") as out:
        run = Execute(setup, "station", RunContext(out_dir=Path(out), quiet=True))
    joints = PiecewisePolynomial.FirstOrderHold(run.sample_times, run.q_samples.T)
    end = run.sample_times[-1]
    motions = (  # (what the arm does, its command's source, simulated s)
        (
            f"held at the start ({seconds:g} s)",
            lambda: ConstantVectorSource(setup.q_start),
            seconds,
        ),
        (f"along the run's joints ({end:.1f} s)", lambda: TrajectorySource(joints), end),
    )
    for motion, make_source, duration in motions:
        for label, tof_tools in (("station", setup.station.tof_tools), ("without ToF", {})):
            scenario = copy.deepcopy(setup.station)
            scenario.tof_tools = tof_tools
            builder = DiagramBuilder()
            station = builder.AddSystem(MakeStation(scenario))
            command = builder.AddSystem(make_source())
            builder.Connect(
                command.get_output_port(),
                station.GetInputPort(f"{setup.arm}.position_commanded"),
            )
            simulator = Simulator(builder.Build())
            simulator.Initialize()
            start = time.process_time()
            simulator.AdvanceTo(duration)
            cpu = (time.process_time() - start) / duration
            print(f"{label:12s} {motion:34s} {cpu:.3f} CPU s per simulated s")


# A run without Meshcat, as diagrams/campaigns/worker.py makes it; prints realtime_factor.
_HEADLESS_RUN = """
import sys, tempfile
from pathlib import Path
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.task_run import RunTask
task, scenario, _ = LoadScenario("path_following", sys.argv[1:])
with tempfile.TemporaryDirectory(prefix="bench_cont_") as out:
    print(RunTask(task, scenario, RunContext(out_dir=Path(out), quiet=True))["realtime_factor"])
"""


def RealtimeFactors(path: str, runs: int) -> None:
    """Prints the realtime_factor of `runs` continuous ranging runs of `path`, alternating
    runs with the replay recorded and runs without Meshcat, and each kind's median."""
    factors: dict[str, list[float]] = {"with the replay": [], "without Meshcat": []}
    settings = [
        f"path={path}",
        "motion=continuous",
        "estimator=ranging",
        *Overrides(sys.argv)[1::2],
    ]
    for k in range(runs):
        if k % 2 == 0:
            kind, rtf = "with the replay", RunOne(path, "continuous", "ranging")["rtf"]
        else:
            command = [sys.executable, "-c", _HEADLESS_RUN, *settings]
            result = subprocess.run(command, capture_output=True, text=True, check=True)
            kind, rtf = "without Meshcat", float(result.stdout.split()[-1])
        factors[kind].append(rtf)
        print(f"run {k + 1}: {kind}: realtime_factor {rtf}", flush=True)
    goal = RTF_GOAL_LOADED if "--load" in sys.argv else RTF_GOAL
    for kind, values in factors.items():
        if values:
            median = statistics.median(values)
            verdict = "meets" if median >= goal else "misses"
            print(
                f"{kind}: median {median:.2f} (min {min(values)}, max {max(values)}); "
                f"{verdict} the goal >= {goal:g}"
            )


def PerCall(path: str, at: float) -> None:
    """Prints the CPU time per call of each per-tick Python callback at the loop's context
    `at` simulated seconds into a continuous ranging run of PATH, and per simulated second
    at its rate."""
    import timeit

    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder

    from guidedarm.diagrams.station.station import MakeStation
    from guidedarm.diagrams.tasks.path_following.builder import AddPathFollowing
    from guidedarm.diagrams.tasks.path_following.setup import MakeSetup
    from guidedarm.diagrams.tasks.registry import LoadScenario

    settings = [f"path={path}", "motion=continuous", "estimator=ranging"]
    setup = MakeSetup(LoadScenario("path_following", [*settings, *Overrides(sys.argv)[1::2]])[1])
    builder = DiagramBuilder()
    station = builder.AddNamedSystem("station", MakeStation(setup.station))
    follower, servo = AddPathFollowing(builder, station, setup)
    sensor = station.GetSubsystemByName(f"{setup.tool_name}.sensor")
    simulator = Simulator(builder.Build())
    simulator.Initialize()
    simulator.AdvanceTo(at)
    root = simulator.get_context()
    servo_context = servo.GetMyContextFromRoot(root)
    follower_context = follower.GetMyContextFromRoot(root)
    sensor_context = sensor.GetMyContextFromRoot(root)
    # The updates write into scratch copies: the loop's context stays as it was.
    servo_state = servo.AllocateDiscreteVariables()
    sensor_state = sensor.AllocateDiscreteVariables()
    scratch = follower.CreateDefaultContext()
    scratch.SetTimeStateAndParametersFrom(follower_context)
    run = follower.Loop(follower_context)

    def Reading() -> None:
        # A reading the grid has not seen: its memo of the latest reading would answer.
        setup.grid._detect_memo[0] = setup.grid._start_memo[0] = None
        follower._Read(follower_context, run, run.stamp + 1e-3)

    servo_rate = 1 / setup.continuous.servo_period
    tof_rate = 1 / setup.station.tof_tools[setup.tool_name].period
    calls = (
        (
            "DifferentialIkServo update",
            servo_rate,
            lambda: servo._Update(servo_context, servo_state),
        ),
        (
            "ContinuousFollower update",
            servo_rate,
            lambda: follower._Update(follower_context, scratch.get_mutable_state()),
        ),
        ("ContinuousFollower reading", tof_rate, Reading),
        ("ToF sensor reading", tof_rate, lambda: sensor._Measure(sensor_context, sensor_state)),
        ("  ray casting", tof_rate, lambda: sensor.TrueRanges(sensor_context)),
    )
    print(f"{path} at t = {at} s: CPU per call (least of 7 x 200), per simulated s at its rate")
    total = 0.0
    for label, rate, call in calls:
        seconds = min(timeit.repeat(call, number=200, repeat=7, timer=time.process_time)) / 200
        total += 0 if label.startswith(" ") else seconds * rate
        print(f"  {label:32s} {1e6 * seconds:7.1f} us x {rate:5.1f} Hz = {seconds * rate:.4f}")
    print(f"  {'all of them':32s} {total:.4f} CPU s per simulated s")


@contextlib.contextmanager
def OneCoreBusy(busy: bool):
    """With busy, a process spinning one core for the duration of the block."""
    if not busy:
        yield
        return
    spinner = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        yield
    finally:
        spinner.kill()
        spinner.wait()


def main() -> None:
    with OneCoreBusy("--load" in sys.argv):
        Run()


def Run() -> None:
    if "--rtf" in sys.argv:
        at = sys.argv.index("--rtf")
        count = sys.argv[at + 2] if len(sys.argv) > at + 2 else "--"
        if count.startswith("--"):
            count = "5"
        if len(sys.argv) <= at + 1 or not count.isdigit() or int(count) < 1:
            print(
                "bench_continuous_following: --rtf needs a PATH and optionally N >= 1 runs",
                file=sys.stderr,
            )
            sys.exit(2)
        RealtimeFactors(sys.argv[at + 1], int(count))
        return
    if "--percall" in sys.argv:
        at = sys.argv.index("--percall")
        t = (
            sys.argv[at + 2]
            if len(sys.argv) > at + 2 and sys.argv[at + 2][0].isdigit()
            else "3.004"
        )
        PerCall(sys.argv[at + 1], float(t))
        return
    if "--breakdown" in sys.argv:
        Breakdown(sys.argv[sys.argv.index("--breakdown") + 1])
        return
    if "--floor" in sys.argv:
        Floor(sys.argv[sys.argv.index("--floor") + 1])
        return
    paths = [f"paper_path_{k}" for k in range(1, 5)]
    if "--quick" not in sys.argv:
        paths += [f"random_{k}" for k in range(40 if "--more" in sys.argv else 20)]
    if "--paths" in sys.argv:
        paths = sys.argv[sys.argv.index("--paths") + 1].split(",")
    paper = [p for p in paths if p.startswith("paper_path_")]
    runs = [(p, "continuous", "ranging") for p in paths]
    runs += [(p, "continuous", "grid") for p in paper]
    if "--paths" not in sys.argv:
        runs += [(p, "joint_trajectory", "ranging") for p in paper]
    print("| path | motion | estimator | " + " | ".join(FIELDS) + " | wall_s | rtf |")
    print("|" + "---|" * (len(FIELDS) + 5))
    results = []
    for path, motion, estimator in runs:
        s = RunOne(path, motion, estimator)
        results.append((path, motion, estimator, s))
        cells = [str(s.get(f)) for f in FIELDS] + [str(s["wall_s"]), str(s["rtf"])]
        print(f"| {path} | {motion} | {estimator} | " + " | ".join(cells) + " |", flush=True)
    main_set = [s for p, m, e, s in results if m == "continuous" and e == "ranging"]
    ok = [
        s
        for s in main_set
        if s["success"]
        and s["coverage"] >= 0.95
        and not s["collisions"]
        and s["average_speed_mm_s"] >= 80
        and s["tracking_error_mean_mm"] <= 3
        and s["tracking_error_max_mm"] <= 10
    ]
    print(
        f"continuous ranging: {len(ok)} / {len(main_set)} meet every goal; "
        f"slowest {min(s['average_speed_mm_s'] for s in main_set)} mm/s, worst mean "
        f"{max(s['tracking_error_mean_mm'] for s in main_set)} mm, worst max "
        f"{max(s['tracking_error_max_mm'] for s in main_set)} mm, real-time factor "
        f"{min(s['rtf'] for s in main_set)}-{max(s['rtf'] for s in main_set)}"
    )


if __name__ == "__main__":
    main()
