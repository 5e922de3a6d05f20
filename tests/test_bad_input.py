"""Bad input of every command and every schema section: one line on stderr, exit 2, never a
traceback, a Drake "Failure at", a summary or a silent wrong result (the run contract in
docs/usage.md). Most cases run in-process through main(); a few through real subprocesses,
among them those that aborted natively before the validation layer."""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import os
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import cv2
import numpy as np
import pytest

from guidedarm.diagrams.panel.panel_files import DEFAULT_PANEL_FILE
from guidedarm.diagrams.run_context import MakeMeshcat, RunContext
from guidedarm.diagrams.scenario_loading import list_named_scenarios
from guidedarm.diagrams.task_run import RunTask
from guidedarm.diagrams.tasks.registry import LoadScenario, TaskDefinition
from guidedarm.systems.config_checks import CheckConfig, FieldError
from guidedarm.systems.errors import ConfigurationError, RunFailedError
from guidedarm.systems.scene.hose_geometry import ReadCenterline

GUIDEDARM = str(Path(sys.executable).parent / "guidedarm")
BAD_OUTPUT = ["Traceback", "Failure at"]

GOOD_CAMERA = "width: 64\nheight: 48\nfx: 50.0\nfy: 50.0\ncx: 31.5\ncy: 23.5\n"
GOOD_PANEL = DEFAULT_PANEL_FILE.read_text()
BINARY = bytes(range(128, 256)) * 4 + b"\x00\x89PNG\r\n\x1a\n"
NAN_FRAME_SCENARIO = """\
task: joint_tour
arm: ur10e
waypoints: [[-1.2, -1.3, -2.0, -1.2, 1.5708, 0.4]]
station:
  directives:
  - add_directives: {file: package://guidedarm/directives/ur10e.dmd.yaml}
  - add_frame:
      name: mark
      X_PF: {base_frame: world, translation: [.nan, 0, 0]}
  arms: {ur10e: {}}
"""


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> Path:
    """Malformed, binary and out-of-range input files, and a few good ones beside them."""
    root = tmp_path_factory.mktemp("bad_input")
    texts = {
        "afile": "a file, not a directory\n",
        "malformed.yaml": "task: [joint_tour\n",
        "list.yaml": "- 1\n- 2\n",
        "huge.csv": "1e308,0,0.1\n0.2,0,0.1\n0.3,0.1,0.1\n",
        "nan_frame.yaml": NAN_FRAME_SCENARIO,
        "nul.csv": "\x00" * 64,
        "camera.yaml": GOOD_CAMERA,
        "camera_nan_fx.yaml": GOOD_CAMERA.replace("fx: 50.0", "fx: .nan"),
        "camera_negative_fy.yaml": GOOD_CAMERA.replace("fy: 50.0", "fy: -1360.2"),
        "camera_inf_cy.yaml": GOOD_CAMERA.replace("cy: 23.5", "cy: .inf"),
        "camera_zero_width.yaml": GOOD_CAMERA.replace("width: 64", "width: 0"),
        "camera_cx_outside.yaml": GOOD_CAMERA.replace("cx: 31.5", "cx: 500.0"),
        "camera_distortion.yaml": GOOD_CAMERA + "distortion: [0, 0, 0]\n",
        "camera_wrong_type.yaml": GOOD_CAMERA.replace("fx: 50.0", "fx: wide"),
        "camera_unknown_key.yaml": GOOD_CAMERA + "skew: 0\n",
        "panel_negative_size.yaml": GOOD_PANEL.replace("size_m: 0.05", "size_m: -0.05", 1),
        "panel_nan_pose.yaml": GOOD_PANEL.replace("[0.12, 0.0, 0.0]", "[0.12, .nan, 0.0]"),
        "panel_dictionary.yaml": GOOD_PANEL.replace("DICT_ARUCO_ORIGINAL", "DICT_NOPE"),
        "panel_travel.yaml": GOOD_PANEL.replace(
            "  position: [0.03, -0.05, 0.012]",
            "  position: [0.03, -0.05, 0.012]\n  on_travel_m: 0.02",
        ),
        "not_an_image.png": "hello",
        "duplicate_key.yaml": NAN_FRAME_SCENARIO.replace(".nan", "0").replace(
            "arms: {ur10e: {}}", "arms: {ur10e: {kp: 400, kp: 900}}"
        )
        + "waypoints: []\n",
        "camera_duplicate_key.yaml": GOOD_CAMERA + "fx: 60.0\n",
        "panel_duplicate_key.yaml": "dictionary: DICT_4X4_50\n" + GOOD_PANEL,
        "campaign_duplicate_key.yaml": "scenario: duplicate_key.yaml\n",
    }
    for name, text in texts.items():
        (root / name).write_text(text)
    (root / "zyx_hose.csv").write_text("z,y,x\n0.1,0.0,0.3\n0.1,0.1,0.3\n")
    hairpin = [(x, -0.005, 0.1) for x in (0.3, 0.4, 0.5)] + [(x, 0.005, 0.1) for x in (0.5, 0.3)]
    (root / "folded_hose.csv").write_text("".join(f"{x},{y},{z}\n" for x, y, z in hairpin))
    (root / "binary_hose.csv").write_bytes(BINARY)
    (root / "binary.yaml").write_bytes(BINARY)
    (root / "camera_binary.yaml").write_bytes(BINARY)
    cv2.imwrite(str(root / "blank.png"), np.full((48, 64, 3), 200, np.uint8))
    (root / "a_directory.png").mkdir()
    return root


def Run(scenario: str, *settings: str, flags: tuple[str, ...] = ()) -> list[str]:
    """`run SCENARIO --out {out} [flags] --set s ...`."""
    sets = [a for s in settings for a in ("--set", s)]
    return ["run", scenario, "--out", "{out}", *flags, *sets]


def Estimate(camera: str, panel: str = str(DEFAULT_PANEL_FILE), image: str = "{f}/blank.png"):
    return ["estimate-marker-pose", image, "--camera", camera, "--panel", panel]


JT, WP, PF, PO = "ur10e_joint_tour", "ur10e_waypoints", "path_following", "panel_operation"
TOF_ERRORS = "station.errors.tof_tools.tof"

# (id, arguments, a part of the one-line message); {f}: the files, {out}: a fresh directory.
BAD_INPUTS = [
    # --- the command line itself
    ("no-command", [], "required: command"),
    ("unknown-command", ["juggle"], "invalid choice: 'juggle'"),
    ("list-extra-argument", ["list", "extra"], "unrecognized arguments: extra"),
    ("run-no-scenario", ["run"], "required: scenario"),
    ("run-unknown-flag", ["run", JT, "--fast"], "unrecognized arguments: --fast"),
    # --- scenario files
    ("unknown-scenario", Run("juggling"), "unknown scenario 'juggling'"),
    ("missing-file", Run("{f}/missing.yaml"), "scenario file not found"),
    ("malformed-yaml", Run("{f}/malformed.yaml"), "malformed YAML"),
    ("binary-yaml", Run("{f}/binary.yaml"), "malformed YAML"),
    ("yaml-not-a-mapping", Run("{f}/list.yaml"), "the top level must be a mapping"),
    ("nan-in-directive-transform", Run("{f}/nan_frame.yaml"), "directives[1].add_frame.X_PF"),
    (
        "duplicate-key",
        Run("{f}/duplicate_key.yaml"),
        "duplicate_key.yaml: key 'waypoints' appears twice (lines 3 and 11)",
    ),
    (
        "duplicate-key-describe",
        ["describe", "{f}/duplicate_key.yaml"],
        "duplicate_key.yaml: key 'waypoints' appears twice (lines 3 and 11)",
    ),
    (
        "duplicate-key-despite-set",
        Run("{f}/duplicate_key.yaml", "waypoints=[[0,0,0,0,0,0]]"),
        "key 'waypoints' appears twice",
    ),
    (
        "duplicate-key-emulate",
        ["emulate", "nachi", "--scenario", "{f}/duplicate_key.yaml", "--port", "0"],
        "key 'waypoints' appears twice",
    ),
    (
        "duplicate-key-compare-planners",
        ["compare-planners", "--scenario", "{f}/duplicate_key.yaml"],
        "key 'waypoints' appears twice",
    ),
    (
        "duplicate-key-sweep-scenario",
        ["sweep", "{f}/campaign_duplicate_key.yaml", "--out", "{out}"],
        "key 'waypoints' appears twice",
    ),
    # --- --set syntax and types
    ("set-without-equals", Run(JT, "max_speed"), "--set expects key=value"),
    ("set-bad-yaml", Run(JT, "waypoints=[[1,"), "cannot parse value"),
    ("set-twice", Run(JT, "max_speed=1", "max_speed=2"), "--set max_speed given twice (1, 2)"),
    (
        "set-key-and-its-part",
        Run(JT, "station.arms.ur10e.kp=400", "station.arms={{ur10e: {{kd: 20}}}}"),
        "--set station.arms.ur10e.kp and --set station.arms both given",
    ),
    (
        "set-value-duplicate-key",
        Run(JT, "station.arms={{ur10e: {{kp: 1}}, ur10e: {{kp: 2}}}}"),
        "--set station.arms: key 'ur10e' appears twice",
    ),
    ("unknown-key", Run(JT, "speed=1"), "unknown key 'speed'"),
    ("wrong-type-string", Run(JT, "max_speed=fast"), "key 'max_speed': expected a number"),
    ("wrong-type-list", Run(JT, "max_speed=[1]"), "key 'max_speed': expected a number"),
    ("bad-exponent", Run(JT, "max_speed=1e-3x"), "expected a number, got '1e-3x'"),
    ("int-as-exponent", Run(PF, "random_seed=1e3"), "key 'random_seed': expected an integer"),
    ("int-as-float", Run(PF, "random_seed=1.5"), "key 'random_seed': expected an integer"),
    ("unknown-task", Run(JT, "task=juggling"), "unknown task 'juggling'"),
    # --- joint_tour
    ("joint-tour-nan-speed", Run(JT, "max_speed=.nan"), "key 'max_speed': must be a finite"),
    ("joint-tour-inf-speed", Run(JT, "max_speed=.inf"), "key 'max_speed': must be a finite"),
    ("joint-tour-zero-speed", Run(JT, "max_speed=0"), "key 'max_speed': must be in [0.05, 10]"),
    ("joint-tour-tiny-speed", Run(JT, "max_speed=1e-9"), "must be in [0.05, 10], got 1e-09"),
    ("joint-tour-nan-settle", Run(JT, "settle_time=.nan"), "key 'settle_time'"),
    ("joint-tour-negative-settle", Run(JT, "settle_time=-1"), "must be in [0, 60]"),
    ("joint-tour-no-waypoints", Run(JT, "waypoints=[]"), "at least one waypoint"),
    ("joint-tour-nan-waypoint", Run(JT, "waypoints=[[.nan,0,0,0,0,0]]"), "waypoints[0][0]"),
    ("joint-tour-out-of-limits", Run(JT, "waypoints=[[10,0,0,0,0,0]]"), "outside the joint"),
    ("joint-tour-short-waypoint", Run(JT, "waypoints=[[1,0,0]]"), "has 3 values"),
    ("joint-tour-unknown-arm", Run(JT, "arm=kuka"), "arm 'kuka' is not in station.arms"),
    # --- station.arms, .plant_config, .simulator_config, .visualization, .cameras
    ("arm-nan-kp", Run(JT, "station.arms.ur10e.kp=.nan"), "station.arms.ur10e.kp"),
    ("arm-negative-kp", Run(JT, "station.arms.ur10e.kp=-5"), "must be in [1, 1e+06]"),
    ("arm-zero-period", Run(JT, "station.arms.ur10e.control_period=0"), "control_period"),
    (
        "arm-nan-initial",
        Run(JT, "station.arms.ur10e.initial_position=[.nan,0,0,0,0,0]"),
        "initial_position[0]': must be a finite",
    ),
    (
        "arm-initial-out-of-limits",
        Run(JT, "station.arms.ur10e.initial_position=[9,0,0,0,0,0]"),
        "initial_position[0] = 9 rad is outside the joint limits",
    ),
    ("plant-negative-step", Run(JT, "station.plant_config.time_step=-1"), "time_step'"),
    ("plant-nan-step", Run(JT, "station.plant_config.time_step=.nan"), "time_step'"),
    ("plant-contact-model", Run(JT, "station.plant_config.contact_model=foo"), "contact_model"),
    ("plant-zero-stiction", Run(WP, "station.plant_config.stiction_tolerance=0"), "> 0"),
    ("simulator-scheme", Run(JT, "station.simulator_config.integration_scheme=x"), "scheme"),
    ("simulator-zero-step", Run(JT, "station.simulator_config.max_step_size=0"), "> 0"),
    ("simulator-nan-rate", Run(JT, "station.simulator_config.target_realtime_rate=.nan"), "rate"),
    ("visualization-period", Run(JT, "station.visualization.publish_period=-1"), "> 0"),
    ("visualization-lcm", Run(JT, "station.visualization.lcm_bus=x"), "Meshcat only"),
    ("camera-zero-width", Run(JT, "station.cameras.top.width=0"), "cameras.top.width"),
    ("camera-nan-focal", Run(PO, "station.cameras.camera.focal.x=.nan"), "focal.x"),
    ("camera-clipping", Run(JT, "station.cameras.top.clipping_near=-1"), "clipping_near"),
    ("camera-fps-ignored", Run(PO, "station.cameras.camera.fps=5"), "fps cannot be set"),
    ("camera-depth-range-ignored", Run(PO, "station.cameras.camera.z_far=2.0"), "z_far cannot"),
    ("camera-renamed", Run(PO, "station.cameras.camera.name=other"), "name cannot be set"),
    (
        "camera-background-ignored",
        Run(PO, "station.cameras.camera.background.rgba=[1.0,0.0,0.0,1.0]"),
        "background.rgba cannot be set",
    ),
    # --- station.hardware, .hose, .tof_tools
    ("driver-port-range", Run(PF, "station.hardware.arms.mz04d.port=70000"), "[0, 65535]"),
    ("driver-negative-port", Run(PF, "station.hardware.arms.mz04d.port=-1"), "port'"),
    ("driver-nan-watchdog", Run(PF, "station.hardware.arms.mz04d.watchdog=.nan"), "watchdog'"),
    (
        "driver-lockstep-move",
        Run(
            PF,
            "station.hardware.arms.mz04d=!NachiDriver {{command_mode: move, lockstep: true}}",
            flags=("--hardware",),
        ),
        "lockstep': applies to command_mode 'stream' only",
    ),
    ("tof-driver-baudrate", Run(PF, "station.hardware.tof_tools.tof.baudrate=0"), "baudrate'"),
    (
        "driver-key-replaced",
        Run(PF, "station.hardware.arms.mz04d={{driver: nachi_tcp}}"),
        "mz04d.driver': replaced by the entry's YAML tag: write `mz04d: !NachiDriver {...}`",
    ),
    (
        "transport-key-replaced",
        Run(PF, "station.hardware.tof_tools.tof.transport=ble"),
        "tof.transport': replaced by the entry's YAML tag: write `tof: !ToFBleDriver {...}`",
    ),
    (
        "driver-unknown-tag",
        Run(PF, "station.hardware.arms.mz04d=!KukaRsiDriver {{}}"),
        "unknown tag !KukaRsiDriver (known: !UrRtdeDriver, !NachiDriver)",
    ),
    (
        "driver-field-of-another-driver",
        Run(PF, "station.hardware.arms.mz04d.gain=1000"),
        "unknown key 'station.hardware.arms.mz04d.gain' (known keys: acceleration_limits, "
        "command_mode, host, lockstep, port, stale_after, watchdog)",
    ),
    (
        "tof-ble-baudrate",
        Run(PF, "station.hardware.tof_tools.tof=!ToFBleDriver {{address: x, baudrate: 9600}}"),
        "unknown key 'station.hardware.tof_tools.tof.baudrate'",
    ),
    (
        "driver-command-mode-choice",
        Run(PF, "station.hardware.arms.mz04d.command_mode=servo"),
        "command_mode': 'servo' is not one of 'stream', 'move'",
    ),
    ("camera-driver-watchdog", Run(PF, "station.hardware.cameras.c.watchdog=-2"), "watchdog'"),
    ("hose-zero-diameter", Run(PF, "station.hose.diameter=0"), "station.hose.diameter"),
    ("hose-centerline-ignored", Run(PF, "station.hose.centerline={f}/binary_hose.csv"), "'path'"),
    ("tof-cone-range", Run(PF, "station.tof_tools.tof.cone_angle_deg=180"), "(0, 180)"),
    ("tof-nan-range", Run(PF, "station.tof_tools.tof.max_range=.nan"), "max_range"),
    ("tof-negative-rings", Run(PF, "station.tof_tools.tof.rings=-1"), "rings'"),
    ("tof-many-rings", Run(PF, "station.tof_tools.tof.rings=1000"), "in [0, 20]"),
    ("hose-tiny-segment", Run(PF, "station.hose.segment_length=1e-6"), ">= 0.001"),
    ("tof-seed-ignored", Run(PF, "station.tof_tools.tof.seed=4"), "the scenario's 'random_seed'"),
    ("tof-negative-ranging", Run(PF, "station.tof_tools.tof.ranging_time=-0.01"), "ranging_time'"),
    ("tof-ranging-period", Run(PF, "station.tof_tools.tof.ranging_time=0.03"), "exceed period"),
    ("tof-zero-period", Run(PF, "station.tof_tools.tof.period=0"), "period': must be > 0"),
    (
        "tof-offset-moved",
        Run(PF, "station.tof_tools.tof.offset=[0.001]"),
        "moved to 'station.errors",
    ),
    ("tof-offset-count", Run(PF, f"{TOF_ERRORS}.offset=[0.001]"), "offset must hold 6"),
    ("tof-nan-offset", Run(PF, f"{TOF_ERRORS}.offset=[0,0,.nan,0,0,0]"), "offset[2]'"),
    ("tof-offset-range", Run(PF, f"{TOF_ERRORS}.offset=[0,0,0,0,0,1]"), "offset[5] = 1 m"),
    ("tof-negative-drift", Run(PF, f"{TOF_ERRORS}.drift_rate=-1"), "drift_rate must be >= 0"),
    ("tof-inf-drift-max", Run(PF, f"{TOF_ERRORS}.drift_max=.inf"), "drift_max'"),
    (
        "tof-drift-without-bound",
        Run(PF, f"{TOF_ERRORS}.drift_rate=0.01", f"{TOF_ERRORS}.drift_max=0"),
        "needs drift_max > 0",
    ),
    ("errors-unknown-tool", Run(PF, "station.errors.tof_tools.tofx.offset=[]"), "no such tof_tool"),
    ("errors-unknown-preset", Run(PF, "station.errors_preset=foo"), "unknown preset 'foo'"),
    ("tof-driver-latency", Run(PF, "station.hardware.tof_tools.tof.latency=-1"), "latency'"),
    # --- waypoints and planner
    ("waypoints-inf-time", Run(WP, "max_time=.inf"), "key 'max_time': must be a finite"),
    ("waypoints-no-waypoints", Run(WP, "waypoints=[]"), "at least one waypoint"),
    ("waypoints-limit-count", Run(WP, "max_joint_velocity=[1,2]"), "1 or 6 positive"),
    ("waypoints-negative-limit", Run(WP, "max_joint_velocity=[-1]"), "[0]': must be > 0"),
    ("waypoints-limits-choice", Run(WP, "limits=fast"), "limits must be one of"),
    ("waypoints-nan-tracking", Run(WP, "max_tracking_error=.nan"), "max_tracking_error"),
    ("planner-zero-gain", Run(WP, "planner.gain_p=0"), "planner.gain_p': must be > 0"),
    ("planner-nan-singular", Run(WP, "planner.min_singular_value=.nan"), "min_singular"),
    ("planner-threshold-range", Run(WP, "planner.velocity_threshold=0.5"), "(0, 0.5)"),
    (
        "paper-mode-ignores-robust-key",
        Run(WP, "planner.robust=false", "planner.max_jerk=10"),
        "'planner.max_jerk' has no effect with planner.robust=false",
    ),
    (
        "paper-mode-ignores-joint-blend",
        Run(WP, "planner.robust=false", "planner.joint_space_blend=[0.001,0.01]"),
        "'planner.joint_space_blend' has no effect",
    ),
    (
        "path-planner-paper-mode-ignores-robust-key",
        Run(PF, "motion=planner", "planner.robust=false", "planner.max_jerk=10"),
        "'planner.max_jerk' has no effect with planner.robust=false",
    ),
    (
        "panel-planner-robust-mode-ignores-paper-key",
        Run(PO, "planner.parameters.scaling_recovery_rate=2"),
        "'planner.parameters.scaling_recovery_rate' has no effect with "
        "planner.parameters.robust=true",
    ),
    (
        "robust-mode-ignores-paper-key",
        Run(WP, "planner.scaling_recovery_rate=2"),
        "'planner.scaling_recovery_rate' has no effect with planner.robust=true",
    ),
    (
        "no-limits-ignore-velocity",
        Run(WP, "limits=none", "max_joint_velocity=[2]"),
        "'max_joint_velocity' has no effect with limits=none",
    ),
    (
        "velocity-limit-ignores-acceleration",
        Run(WP, "limits=velocity", "max_joint_acceleration=[2]"),
        "'max_joint_acceleration' has no effect with limits=velocity",
    ),
    # --- path_following, follower, ik
    ("path-random-negative", Run(PF, "path=random_-1"), "random_<seed>"),
    ("path-unknown", Run(PF, "path=paper_path_9"), "unknown hose path"),
    ("path-csv-missing", Run(PF, "path_csv={f}/missing.csv"), "not found"),
    ("path-csv-binary", Run(PF, flags=("--path-csv", "{f}/binary_hose.csv")), "not a text CSV"),
    (
        "path-csv-header-order",
        Run(PF, flags=("--path-csv", "{f}/zyx_hose.csv")),
        "the header 'z,y,x' must be x,y,z",
    ),
    ("path-csv-nul", Run(PF, "path_csv={f}/nul.csv"), "must be x,y,z"),
    ("path-csv-directory", Run(PF, flags=("--path-csv", "{f}")), "is a directory, not a CSV"),
    (
        "path-csv-folded",
        Run(PF, flags=("--path-csv", "{f}/folded_hose.csv")),
        "the hose passes through itself",
    ),
    (
        "path-beside-path-csv",
        Run(PF, "path=paper_path_2", flags=("--path-csv", "{f}/binary_hose.csv")),
        "'path' has no effect with path_csv (--path-csv) set",
    ),
    (
        "random-path-beside-named-hose",
        Run(PF, "random_path.length=0.5"),
        "'random_path.length' has no effect with the hose 'paper_path_1'",
    ),
    ("path-nan-period", Run(PF, "period=.nan"), "key 'period'"),
    ("path-negative-seed", Run(PF, "random_seed=-1"), "key 'random_seed': must be >= 0"),
    ("path-negative-repeat", Run(PF, "repeat_random_seed=-3"), "key 'repeat_random_seed'"),
    ("path-nan-acceleration", Run(PF, "max_joint_acceleration=.nan"), "max_joint_accel"),
    ("path-nan-tool-speed", Run(PF, "tool_speed=.nan"), "tool_speed"),
    ("path-inf-time", Run(PF, "max_time=.inf"), "max_time"),
    ("path-coverage-range", Run(PF, "min_coverage=1.5"), "in [0, 1]"),
    ("path-executor", Run(PF, "executor=teleport"), "'executor': 'teleport' is not one of"),
    ("path-motion", Run(PF, "motion=teleport"), "'motion': 'teleport' is not one of"),
    ("path-estimator", Run(PF, "estimator=lidar"), "'estimator': 'lidar' is not one of"),
    ("continuous-speed", Run(PF, "continuous.speed=0"), "continuous.speed': must be > 0"),
    ("continuous-nan-gain", Run(PF, "continuous.servo_gain=.nan"), "continuous.servo_gain"),
    ("continuous-roll-weight", Run(PF, "continuous.roll_weight=2"), "continuous.roll_weight"),
    ("continuous-huge-damping", Run(PF, "continuous.servo_damping=1e300"), "in [0.001, 1]"),
    ("continuous-tiny-spread", Run(PF, "continuous.spread_limit=1e-300"), "spread_limit'"),
    ("continuous-huge-rotation", Run(PF, "continuous.rotation_weight=1e100"), "rotation_weight'"),
    ("continuous-min-points", Run(PF, "continuous.min_fit_points=1"), "min_fit_points"),
    ("continuous-turns", Run(PF, "continuous.search_turns_deg=[120]"), "search_turns_deg"),
    ("continuous-speeds", Run(PF, "continuous.min_speed=0.5"), "min_speed <= speed"),
    (
        "continuous-fixture-speed",
        Run(PF, "continuous.fixture_speed=0.001"),
        "min_speed <= fixture_speed",
    ),
    (
        "continuous-thickening-max",
        Run(PF, "continuous.thickening_max=0.001"),
        "thickening_min < thickening_max",
    ),
    (
        "continuous-speed-beyond-readings",
        Run(PF, "motion=continuous", "continuous.speed=0.15", "continuous.min_fit_points=20"),
        "continuous.speed (0.15 m/s) is faster than the hose fit can follow",
    ),
    (
        "continuous-speed-beyond-look-ahead",
        Run(PF, "motion=continuous", "continuous.speed=1e3"),
        "need speed <= sqrt(2 acceleration look_ahead)",
    ),
    (
        "continuous-fit-too-short",
        Run(PF, "motion=continuous", "continuous.fit_length=1e-9"),
        "at most 6.25e-09 m/s",
    ),
    ("continuous-gate-tiny", Run(PF, "continuous.gate=1e-7"), "'continuous.gate'"),
    ("continuous-search", Run(PF, "continuous.loss_distance=0.05"), "loss_distance <"),
    (
        "kinematic-hardware",
        Run(PF, "executor=kinematic", flags=("--hardware",)),
        "executor=kinematic cannot run with --hardware",
    ),
    (
        "kinematic-ignores-kp",
        Run(PF, "executor=kinematic", "station.arms.mz04d.kp=900"),
        "'station.arms.mz04d.kp' has no effect with executor=kinematic",
    ),
    (
        "kinematic-meshcat",
        Run(PF, "executor=kinematic", flags=("--meshcat",)),
        "executor=kinematic cannot be watched with --meshcat",
    ),
    (
        "kinematic-ignores-visualization",
        Run(PF, "executor=kinematic", "station.visualization.publish_period=0.1"),
        "'station.visualization.publish_period' has no effect with executor=kinematic",
    ),
    (
        "kinematic-ignores-plant",
        Run(PF, "executor=kinematic", "station.plant_config.time_step=0.001"),
        "'station.plant_config.time_step' has no effect with executor=kinematic",
    ),
    (
        "continuous-hardware-move",
        Run(
            PF,
            "motion=continuous",
            "station.hardware.arms.mz04d.command_mode=move",
            flags=("--hardware",),
        ),
        "command_mode must be 'stream', not 'move'",
    ),
    (
        "continuous-hardware-periods",
        Run(
            PF,
            "motion=continuous",
            flags=("--hardware",),
        ),
        "must equal station.arms.mz04d.control_period",
    ),
    (
        "continuous-servo-faster-than-arm",
        Run(PF, "motion=continuous", "continuous.servo_period=1e-4"),
        "shorter than station.arms.mz04d.control_period",
    ),
    (
        "continuous-arm-samples-between-commands",
        Run(PF, "motion=continuous", "station.arms.mz04d.control_period=0.004"),
        "control_period (0.004 s) must equal continuous.servo_period (0.008 s)",
    ),
    (
        "continuous-ignores-follower",
        Run(PF, "motion=continuous", "follower.long_step=0.03"),
        "'follower.long_step' has no effect with motion=continuous",
    ),
    (
        "continuous-ignores-period",
        Run(PF, "motion=continuous", "period=0.05"),
        "'period' has no effect",
    ),
    (
        "continuous-ignores-tool-speed",
        Run(PF, "motion=continuous", "tool_speed=0.02"),
        "'tool_speed' has no effect",
    ),
    (
        "continuous-ignores-ik-swing",
        Run(PF, "motion=continuous", "ik.max_swing=0.05"),
        "'ik.max_swing' has no effect with motion=continuous",
    ),
    (
        "continuous-ignores-ik-shortfall",
        Run(PF, "motion=continuous", "ik.shortfall_tolerance_deg=30"),
        "'ik.shortfall_tolerance_deg' has no effect with motion=continuous",
    ),
    (
        "continuous-ignores-ik-step",
        Run(PF, "motion=continuous", "ik.max_step_rotation_deg=45"),
        "'ik.max_step_rotation_deg' has no effect",
    ),
    (
        "joint-moves-ignore-continuous",
        Run(PF, "continuous.speed=0.07"),
        "'continuous.speed' has no effect with motion=joint_trajectory",
    ),
    (
        "joint-moves-ignore-planner",
        Run(PF, "planner.gain_p=10"),
        "'planner.gain_p' has no effect with motion=joint_trajectory",
    ),
    ("follower-steps", Run(PF, "follower.long_step=0.001"), "short_step <= long_step"),
    ("follower-reduction", Run(PF, "follower.rotation_reduction=1"), "[0, 1)"),
    ("follower-readings", Run(PF, "follower.readings=-2"), "follower.readings"),
    (
        "follower-estimator-replaced",
        Run(PF, "follower.estimator=ranging"),
        "key 'follower.estimator' was replaced by 'estimator'",
    ),
    ("ik-walls-gone", Run(PF, "ik.z_min=0.1"), "unknown key 'ik.z_min'"),
    ("ik-nan-tolerance", Run(PF, "ik.position_tolerance=.nan"), "ik.position_tolerance"),
    ("ik-down-axis", Run(PF, "ik.down_axis=[0,0,0]"), "nonzero 3-vector"),
    # --- panel_operation, start, operation, degradation, planner
    (
        "panel-hardware",
        Run(PO, flags=("--hardware",)),
        "panel_operation cannot run with --hardware",
    ),
    ("panel-zero-switch", Run(PO, "switch=0"), "key 'switch': must be > 0"),
    ("panel-switch-range", Run(PO, "switch=9"), "switch must be 1 .. 3"),
    ("panel-negative-time", Run(PO, "time_limit_s=-1"), "time_limit_s"),
    (
        "start-seed-replaced",
        Run(PO, "start.seed=1"),
        "key 'start.seed' was replaced by 'random_seed'",
    ),
    ("path-seed-replaced", Run(PF, "seed=1"), "key 'seed' was replaced by 'random_seed'"),
    (
        "view-seed-conflict",
        Run("marker_view", "degradation.seed=5"),
        "degradation.seed (5) conflicts with the scenario's 'random_seed' (1)",
    ),
    ("start-distance-order", Run(PO, "start.distance_m=[0.4,0.3]"), "distance_m must be"),
    ("start-tilt-range", Run(PO, "start.max_tilt_deg=90"), "[0, 90)"),
    ("operation-nan-distance", Run(PO, "operation.base_distance_m=.nan"), "base_distance_m"),
    (
        "operation-motion",
        Run(PO, "operation.motion=teleport"),
        "operation.motion': 'teleport' is not one of",
    ),
    ("degradation-noise", Run(PO, "degradation.noise_std=-1"), "degradation.noise_std"),
    ("panel-planner-inf", Run(PO, "planner.max_joint_velocity=[.inf]"), "max_joint_velocity[0]"),
    ("panel-file-missing", Run(PO, "panel_file=panel/nope.yaml"), "file not found"),
    # --- output directories and Meshcat flags
    ("out-is-a-file", ["run", JT, "--out", "{f}/afile"], "is a file, not a directory"),
    ("out-under-a-file", ["run", JT, "--out", "{f}/afile/run"], "is a file, not a directory"),
    ("out-unwritable", ["run", JT, "--out", "/sys/guidedarm_run"], "cannot write there"),
    ("meshcat-wait-alone", Run(JT, flags=("--meshcat-wait", "3")), "needs --meshcat"),
    ("meshcat-host-alone", Run(JT, flags=("--meshcat-host", "0.0.0.0")), "needs --meshcat"),
    (
        "meshcat-wait-negative",
        Run(JT, flags=("--meshcat", "--meshcat-wait", "-1")),
        "must be >= 0 s",
    ),
    ("meshcat-wait-nan", Run(JT, flags=("--meshcat", "--meshcat-wait", "nan")), ">= 0 s"),
    ("meshcat-wait-text", Run(JT, flags=("--meshcat", "--meshcat-wait", "x")), "invalid float"),
    (
        "meshcat-host-unbindable",
        Run(JT, flags=("--meshcat", "--meshcat-host", "192.0.2.1")),
        "Meshcat cannot listen on host '192.0.2.1': no address of this machine",
    ),
    (
        "meshcat-host-unresolvable",
        Run(JT, flags=("--meshcat", "--meshcat-host", "999.1.1.1")),
        "Meshcat cannot listen on host '999.1.1.1': it does not resolve",
    ),
    # --- estimate-marker-pose: camera and panel files, images
    ("camera-missing", Estimate("{f}/missing.yaml"), "file not found"),
    ("camera-binary", Estimate("{f}/camera_binary.yaml"), "malformed YAML"),
    ("camera-nan-fx", Estimate("{f}/camera_nan_fx.yaml"), "key 'fx': must be a finite"),
    (
        "camera-negative-fy",
        Estimate("{f}/camera_negative_fy.yaml"),
        "key 'fy': must be in [1, 1e+06]",
    ),
    ("camera-inf-cy", Estimate("{f}/camera_inf_cy.yaml"), "key 'cy'"),
    ("camera-zero-width", Estimate("{f}/camera_zero_width.yaml"), "key 'width'"),
    ("camera-cx-outside", Estimate("{f}/camera_cx_outside.yaml"), "outside the image"),
    ("camera-distortion", Estimate("{f}/camera_distortion.yaml"), "distortion needs 5"),
    ("camera-wrong-type", Estimate("{f}/camera_wrong_type.yaml"), "expected a number"),
    ("camera-unknown-key", Estimate("{f}/camera_unknown_key.yaml"), "unknown key 'skew'"),
    (
        "camera-duplicate-key",
        Estimate("{f}/camera_duplicate_key.yaml"),
        "camera_duplicate_key.yaml: key 'fx' appears twice (lines 3 and 7)",
    ),
    (
        "panel-duplicate-key",
        Estimate("{f}/camera.yaml", "{f}/panel_duplicate_key.yaml"),
        "panel_duplicate_key.yaml: key 'dictionary' appears twice (lines 1 and",
    ),
    (
        "panel-negative-size",
        Estimate("{f}/camera.yaml", "{f}/panel_negative_size.yaml"),
        "markers[0].size_m",
    ),
    (
        "panel-nan-pose",
        Estimate("{f}/camera.yaml", "{f}/panel_nan_pose.yaml"),
        "markers[1].X_PM.translation[1]",
    ),
    (
        "panel-dictionary",
        Estimate("{f}/camera.yaml", "{f}/panel_dictionary.yaml"),
        "unknown marker dictionary",
    ),
    (
        "panel-travel",
        Estimate("{f}/camera.yaml", "{f}/panel_travel.yaml"),
        "on_travel_m must not exceed travel_m",
    ),
    ("panel-binary", Estimate("{f}/camera.yaml", "{f}/binary.yaml"), "malformed YAML"),
    ("image-missing", Estimate("{f}/camera.yaml", image="{f}/missing.png"), "cannot read"),
    ("image-not-image", Estimate("{f}/camera.yaml", image="{f}/not_an_image.png"), "cannot"),
    ("image-directory", Estimate("{f}/camera.yaml", image="{f}/a_directory.png"), "cannot"),
    ("image-no-marker", Estimate("{f}/camera.yaml"), "no marker of the panel"),
    (
        "image-size",
        Estimate(str(Path(__file__).parents[1] / "models/panel/c920_camera.yaml")),
        "is 64 x 48 px",
    ),
    # --- marker-study, compare-planners, show, picture
    ("study-unknown", ["marker-study", "speed"], "invalid choice: 'speed'"),
    ("study-nan-noise", ["marker-study", "tilt", "--noise", "nan"], "--noise: must be a finite"),
    ("study-negative-blur", ["marker-study", "tilt", "--blur", "-1"], "--blur: must be >= 0"),
    ("study-zero-lighting", ["marker-study", "tilt", "--lighting", "0"], "--lighting"),
    ("study-short-lens", ["marker-study", "tilt", "--lens", "1,2"], "--lens: five finite numbers"),
    (
        "study-missing-camera-file",
        ["marker-study", "tilt", "--camera-file", "nope.yaml"],
        "--camera-file 'nope.yaml': file not found",
    ),
    ("study-text-noise", ["marker-study", "tilt", "--noise", "loud"], "invalid float"),
    ("study-out-file", ["marker-study", "tilt", "--out", "{f}/afile"], "is a file"),
    ("compare-wrong-task", ["compare-planners", "--scenario", JT], "needs a waypoints"),
    ("compare-unknown", ["compare-planners", "--scenario", "nope"], "unknown scenario"),
    ("compare-nan-gain", ["compare-planners", "--set", "planner.gain_v=.nan"], "gain_v"),
    ("compare-limits", ["compare-planners", "--set", "limits=none"], "velocity,acceleration"),
    ("compare-out-file", ["compare-planners", "--out", "{f}/afile/x"], "is a file"),
    (
        "compare-negative-seed",
        ["compare-planners", "--random", "1", "--arm", "ur10e", "--seed", "-1"],
        "--seed must be >= 0, got -1",
    ),
    (
        "compare-random-every-problem",
        ["compare-planners", "--random", "0", "--seed", "-1"],
        "--random N needs N >= 1, got 0; --random needs --arm ARM; --seed must be >= 0, got -1",
    ),
    (
        "compare-random-unknown-key",
        ["compare-planners", "--random", "1", "--arm", "ur10e", "--set", "bogus=1"],
        "unknown key 'bogus'",
    ),
    (
        "compare-random-scenario",
        ["compare-planners", "--random", "1", "--arm", "ur10e", "--scenario", "mz04d_waypoints"],
        "--scenario is not read with --random",
    ),
    ("compare-robust", ["compare-planners", "--set", "planner.robust=false"], "runs both modes"),
    ("compare-arm-alone", ["compare-planners", "--arm", "ur10e"], "--arm is read only with"),
    ("compare-seed-alone", ["compare-planners", "--seed", "3"], "--seed is read only with"),
    ("emulate-set-alone", ["emulate", "nachi", "--set", "arm=ur10e"], "--set needs --scenario"),
    ("emulate-tof-arm", ["emulate", "tof", "--arm", "ur10e"], "--arm applies to `emulate nachi`"),
    ("emulate-tof-host", ["emulate", "tof", "--host", "0.0.0.0"], "--host applies to"),
    ("emulate-tof-lockstep", ["emulate", "tof", "--lockstep"], "--lockstep applies to `emulate"),
    ("show-unknown-arm", ["show", "kuka"], "unknown arm or scene 'kuka'"),
    ("show-negative-timeout", ["show", "ur10e", "--timeout", "-1"], "--timeout must be"),
    ("show-nan-timeout", ["show", "ur10e", "--timeout", "nan"], "--timeout must be"),
    ("show-html-under-file", ["show", "ur10e", "--html", "{f}/afile/x.html"], "is a file"),
    ("show-html-directory", ["show", "ur10e", "--html", "{f}/a_directory.png"], "directory"),
    ("show-html-timeout", ["show", "ur10e", "--html", "{out}/x.html", "--timeout", "1"], "drop"),
    ("picture-zero-width", ["picture", "{out}/p.png", "--width", "0"], "--width must be"),
    ("picture-huge-height", ["picture", "{out}/p.png", "--height", "100000"], "--height"),
    ("picture-text-width", ["picture", "{out}/p.png", "--width", "wide"], "invalid int"),
    ("picture-not-image", ["picture", "{out}/p.txt"], "must end in an image type"),
    ("picture-under-file", ["picture", "{f}/afile/p.png"], "is a file"),
    ("picture-directory", ["picture", "{f}/a_directory.png"], "is a directory"),
    # --- numbers beyond what is physical (huge or tiny finite values)
    ("random-path-huge-length", Run(PF, "path=random_3", "random_path.length=1e308"), "[0.1, 10]"),
    ("csv-huge-coordinate", Run(PF, flags=("--path-csv", "{f}/huge.csv")), "beyond 5 m"),
    ("marker-view-supersampling", Run("marker_view", "supersampling=50"), "[1, 8], got 50"),
    ("marker-view-huge-width", Run("marker_view", "camera.width=100000"), "[1, 16384]"),
    (
        "marker-view-pixels",
        Run("marker_view", "camera.width=5000", "camera.height=5000"),
        "more than 64,000,000",
    ),
    ("arm-huge-kp", Run(JT, "station.arms.ur10e.kp=1e308"), "kp': must be in [1, 1e+06]"),
    ("arm-tiny-kp", Run(JT, "station.arms.ur10e.kp=1e-300"), "kp': must be in [1, 1e+06]"),
    ("planner-tiny-step", Run(WP, "planner.time_step=1e-9"), "time_step': must be in [0.0001"),
    ("plant-huge-step", Run(JT, "station.plant_config.time_step=1e9"), "must be in [0, 0.1]"),
    ("arm-huge-period", Run(JT, "station.arms.ur10e.control_period=1e9"), "[0.0001, 1]"),
    ("joint-tour-huge-waypoint", Run(JT, "waypoints=[[1e308,0,0,0,0,0]]"), "waypoints[0][0]"),
    # --- model directives and instances
    (
        "directives-missing-file",
        Run(
            JT, "station.directives=[{{add_directives: {{file: package://guidedarm/no.dmd.yaml}}}}]"
        ),
        "model directives: error: URI",
    ),
    (
        "directives-unknown-package",
        Run(JT, "station.directives=[{{add_directives: {{file: package://nopkg/x.yaml}}}}]"),
        "unknown package 'nopkg'",
    ),
    (
        "directives-plain-path",
        Run(JT, "station.directives=[{{add_directives: {{file: /etc/passwd}}}}]"),
        "model directives:",
    ),
    ("panel-model-unknown", Run(PO, "panel_model=nosuch"), "no model instance 'nosuch'"),
    # --- settings a run would not read
    ("marker-view-hardware", Run("marker_view", flags=("--hardware",)), "--hardware has no"),
    ("marker-view-realtime", Run("marker_view", flags=("--realtime", "2")), "--realtime has no"),
    ("marker-view-camera-pose", Run("marker_view", "camera.X_PB.translation=[1,0,0]"), "X_PB"),
    ("marker-view-camera-fps", Run("marker_view", "camera.fps=5"), "'camera.fps' has no effect"),
    ("marker-view-camera-depth", Run("marker_view", "camera.depth=true"), "'camera.depth'"),
    ("marker-view-camera-name", Run("marker_view", "camera.name=x"), "'camera.name'"),
    ("marker-view-camera-z-far", Run("marker_view", "camera.z_far=0.2"), "'camera.z_far'"),
    ("marker-view-camera-lcm", Run("marker_view", "camera.lcm_bus=x"), "'camera.lcm_bus'"),
    (
        "marker-view-camera-renderer",
        Run("marker_view", "camera.renderer_name=other"),
        "'camera.renderer_name'",
    ),
    (
        "marker-view-camera-background",
        Run("marker_view", "camera.background.rgba=[1.0,0.0,0.0,1.0]"),
        "'camera.background.rgba'",
    ),
    ("marker-view-degradation-ss", Run("marker_view", "degradation.supersampling=2"), "top-level"),
    (
        "path-csv-twice",
        Run(PF, "path_csv={f}/huge.csv", flags=("--path-csv", "{f}/huge.csv")),
        "--path-csv and --set path_csv both given",
    ),
    (
        "hardware-keys-without-hardware",
        Run(PF, "station.hardware.arms.mz04d=!NachiDriver {{port: 1}}"),
        "station.hardware.arms.mz04d has no effect without --hardware",
    ),
    (
        "panel-speed-with-planner",
        Run(PO, "operation.max_joint_speed=0.5"),
        "'operation.max_joint_speed' has no effect with operation.motion=planner",
    ),
    (
        "panel-joint-moves-ignore-planner",
        Run(PO, "operation.motion=joint_trajectory", "planner.max_joint_velocity=[0.4]"),
        "'planner.max_joint_velocity' has no effect with operation.motion=joint_trajectory",
    ),
    (
        "panel-joint-moves-ignore-planner-parameters",
        Run(PO, "operation.motion=joint_trajectory", "planner.parameters.gain_p=3"),
        "'planner.parameters.gain_p' has no effect with operation.motion=joint_trajectory",
    ),
    (
        "panel-ignores-hardware-section",
        Run(PO, "station.hardware.arms.rover_arm=!NachiDriver {{port: 1}}", flags=("--hardware",)),
        "'station.hardware.arms' has no effect on panel_operation",
    ),
    (
        "kinematic-ignores-cameras",
        Run(PF, "executor=kinematic", "station.cameras={{top: {{width: 64, height: 48}}}}"),
        "'station.cameras' has no effect with executor=kinematic",
    ),
    (
        "panel-start-collides",
        Run(PO, "start.position=[0,0,2.5,0,0,0]"),
        "the rover_arm start pose collides: rover::rover_base and rover_arm::rover_link4",
    ),
    (
        "panel-no-reachable-start",
        Run(PO, "start.distance_m=[3.0, 3.1]"),
        "no reachable start pose found for seed",
    ),
    (
        "panel-tilt-with-position",
        Run(PO, "start.position=[0,0,0,0,0,0]", "start.max_tilt_deg=10"),
        "'start.max_tilt_deg' has no effect with start.position",
    ),
    ("describe-defaults-set", ["describe", WP, "--defaults", "--set", "max_time=3"], "--defaults"),
    ("describe-task-set", ["describe", "waypoints", "--set", "nosuch=1"], "task 'waypoints'"),
]


@pytest.mark.parametrize("args, message", [pytest.param(a, m, id=i) for i, a, m in BAD_INPUTS])
def test_bad_input_is_refused_in_one_line(run_cli, files, tmp_path, args, message):
    out = tmp_path / "out"
    code, stdout, err = run_cli(*[a.format(f=files, out=out) for a in args])
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1, err
    assert message in lines[0]
    assert lines[0].startswith("guidedarm: error: ")
    # Refused before the run: never announced as running, nothing written to --out.
    assert "running" not in stdout
    assert not out.exists() or not any(out.iterdir()), list(out.iterdir())


def _ScalarKeys(config, prefix=""):
    """(dotted key, kind) of every float, int and list-of-float value in a typed config tree
    (dataclasses and Drake structs)."""
    if dataclasses.is_dataclass(config):
        names = [f.name for f in dataclasses.fields(config)]
    elif hasattr(type(config), "__fields__"):
        names = [f.name for f in type(config).__fields__]
    else:
        return
    for name in names:
        value, key = getattr(config, name), f"{prefix}{name}"
        if isinstance(value, bool) or value is None:
            continue
        if isinstance(value, float | int):
            yield key, type(value)
        elif isinstance(value, list) and value and isinstance(value[0], float | int):
            yield f"{key}[0]", float
        elif isinstance(value, dict):
            for item_name, item in value.items():
                yield from _ScalarKeys(item, f"{key}.{item_name}.")
        else:
            yield from _ScalarKeys(value, f"{key}.")


def _Set(config, key: str, value) -> None:
    *path, last = key.replace("[0]", "").split(".")
    for name in path:
        config = config[name] if isinstance(config, dict) else getattr(config, name)
    if key.endswith("[0]"):
        getattr(config, last)[0] = value
    else:
        setattr(config, last, value)


SCALARS = [
    (name, key, kind)
    for name in list_named_scenarios()
    for key, kind in _ScalarKeys(LoadScenario(name, [])[1])
]


def test_every_schema_section_has_numbers_to_check():
    sections = {key.split(".")[0] for _, key, _ in SCALARS}
    assert {"station", "planner", "follower", "ik", "operation", "start"} <= sections
    assert len(SCALARS) > 200


@pytest.mark.parametrize("name, key, kind", SCALARS, ids=[f"{n}:{k}" for n, k, _ in SCALARS])
def test_every_number_of_every_scenario_is_checked(name, key, kind):
    """NaN in any float and -1 in any int of a named scenario (its whole typed tree,
    Drake's structs included) is refused naming that key; max_swing's bound allows inf
    (checked on ik alone: with motion=continuous the scenario's rules refuse any
    ik.max_swing, which that motion does not read)."""
    scenario = copy.deepcopy(LoadScenario(name, [])[1])
    _Set(scenario, key, math.nan if kind is float else -1)
    with pytest.raises(FieldError) as error:
        CheckConfig(scenario)
    assert error.value.key == key
    if key == "ik.max_swing":
        _Set(scenario, key, math.inf)
        CheckConfig(scenario.ik)


def test_random_path_keys_are_read_with_a_random_path_only():
    """random_path set on the command line shapes a random_<seed> hose; a scenario file may
    keep its arm's region beside a named hose (ur10e_path_following)."""
    _, scenario, _ = LoadScenario("path_following", ["path=random_3", "random_path.length=0.5"])
    assert scenario.random_path.length == 0.5
    _, ur10e, _ = LoadScenario("ur10e_path_following", ["estimator=ranging"])
    assert ur10e.path == "ur10e_far_hose" and ur10e.random_path.radius_range == [0.55, 0.75]


def test_exponent_notation_is_accepted(tmp_path):
    _, scenario, _ = LoadScenario("ur10e_waypoints", ["max_tracking_error=1e-3", "max_time=1.5e1"])
    assert scenario.max_tracking_error == 0.001 and scenario.max_time == 15.0
    path = tmp_path / "tour.yaml"
    path.write_text(
        (Path(LoadScenario.__code__.co_filename).parents[1] / "scenarios/ur10e_joint_tour.yaml")
        .read_text()
        .replace("max_speed: 0.8", "max_speed: 8e-1\nsettle_time: 2.5E-1")
    )
    _, tour, _ = LoadScenario(str(path), [])
    assert tour.max_speed == 0.8 and tour.settle_time == 0.25


def test_headerless_csv_with_a_byte_order_mark_keeps_its_first_point(tmp_path):
    rows = "0.30,0.00,0.10\n0.30,0.10,0.10\n0.30,0.20,0.10\n"
    for name, data in (("bom.csv", b"\xef\xbb\xbf" + rows.encode()), ("plain.csv", rows.encode())):
        (tmp_path / name).write_bytes(data)
        points = ReadCenterline(str(tmp_path / name))
        assert points.shape == (3, 3) and points[0].tolist() == [0.30, 0.0, 0.10]
    (tmp_path / "header.csv").write_bytes(b"\xef\xbb\xbfx,y,z\n" + rows.encode())
    assert ReadCenterline(str(tmp_path / "header.csv")).shape == (3, 3)
    (tmp_path / "spaced.csv").write_text(" X , Y , Z \n" + rows)
    assert ReadCenterline(str(tmp_path / "spaced.csv"))[0].tolist() == [0.30, 0.0, 0.10]


def _Task(run) -> TaskDefinition:
    return TaskDefinition("probe", object, run, "a task for the run contract")


def test_a_started_run_always_ends_with_metrics_and_a_failure(tmp_path):
    """What RunTask makes of a task that fails in each way (the run command writes it as
    summary.json and exits 1); a refusal before the run passes through (exit 2)."""
    context = RunContext(tmp_path)
    scenario = LoadScenario("ur10e_joint_tour", [])[1]

    def lost(scenario, context):
        raise RunFailedError("tof went quiet")

    def bug(scenario, context):
        raise ValueError("division by zero\nmore")

    def interrupted(scenario, context):
        raise KeyboardInterrupt

    def nan_metric(scenario, context):
        return {"error_mm": [1.0, math.nan], "failure": None}

    def refused(scenario, context):
        raise ConfigurationError("no such arm")

    def drake_check(scenario, context):
        from pydrake.multibody.plant import MultibodyPlant

        plant = MultibodyPlant(0.0)
        plant.Finalize()
        plant.SetPositions(plant.CreateDefaultContext(), [1.0])  # pydrake: SystemExit

    assert RunTask(_Task(lost), scenario, context)["failure"] == "tof went quiet"
    failure = RunTask(_Task(bug), scenario, context)["failure"]
    assert failure.startswith("internal error ValueError: division by zero (see traceback")
    assert "Traceback" in (tmp_path / "traceback.txt").read_text()
    assert RunTask(_Task(drake_check), scenario, context)["failure"] == (
        "internal error a Drake check failed in SetPositions() (multibody_plant.h:2896): "
        "condition 'q.size() == num_positions()' failed. (see traceback.txt)"
    )
    assert RunTask(_Task(interrupted), scenario, context)["failure"] == "interrupted"
    metrics = RunTask(_Task(nan_metric), scenario, context)
    assert metrics["error_mm"] == [1.0, None] and "error_mm.[1]" in metrics["failure"]
    assert metrics["success"] is False
    with pytest.raises(ConfigurationError):
        RunTask(_Task(refused), scenario, context)


def test_meshcat_listens_on_loopback_only_unless_asked():
    recorder = MakeMeshcat()
    assert recorder.web_url().startswith("http://127.0.0.1:")
    assert recorder.port() not in range(7000, 8000)  # an ephemeral port, announced nowhere
    live = MakeMeshcat(serve=True)
    assert live.web_url().startswith("http://localhost:7")
    with pytest.raises(ConfigurationError, match="cannot listen on host"):
        MakeMeshcat(serve=True, host="192.0.2.1")


def _Subprocess(*args: str, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([GUIDEDARM, *args], capture_output=True, text=True, timeout=300, **kwargs)


@pytest.mark.parametrize(
    "setting",
    ["max_speed=.nan", "station.plant_config.time_step=-1", "max_speed=1e-320"],
)
def test_formerly_native_aborts_are_one_line(tmp_path, setting):
    """These aborted the interpreter (SIGABRT, `free(): invalid pointer`, or Drake's
    `Failure at`) before the validation layer, so they run in a real process."""
    result = _Subprocess("run", JT, "--out", str(tmp_path), "--set", setting)
    assert result.returncode == 2, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    for text in BAD_OUTPUT:
        assert text not in result.stdout + result.stderr
    assert not (tmp_path / "summary.json").exists()


def test_estimate_marker_pose_refuses_a_mirrored_camera_in_a_process(files):
    result = _Subprocess(*Estimate(str(files / "camera_negative_fy.yaml")))
    assert result.returncode == 2 and result.stdout == ""
    assert result.stderr.strip().endswith("key 'fy': must be in [1, 1e+06], got -1360.2")


def test_list_into_a_closed_pipe_is_silent():
    result = subprocess.run(
        f"{GUIDEDARM} list | head -1", shell=True, capture_output=True, text=True, timeout=60
    )
    assert result.stdout == "scenarios:\n"
    assert result.stderr == ""


def test_meshcat_run_keeps_serving_without_a_terminal(tmp_path):
    """--meshcat with stdin closed: the page is served after the run until --meshcat-wait
    ends it (no EOFError), the summary is written and the exit code is the run's."""
    process = subprocess.Popen(
        [GUIDEDARM, "run", JT, "--out", str(tmp_path), "--meshcat", "--meshcat-wait", "30"],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    url = None
    for line in process.stdout:
        if line.startswith("Meshcat keeps serving at "):
            url = line.split()[4]
            break
    assert url is not None and url.startswith("http://localhost:7")
    with urllib.request.urlopen(url, timeout=10) as page:
        assert page.status == 200 and b"meshcat" in page.read().lower()
    process.send_signal(signal.SIGINT)  # Ctrl-C ends the serving, not the run's result
    out, err = process.communicate(timeout=60)
    assert process.returncode == 0, err
    assert json.loads((tmp_path / "summary.json").read_text())["failure"] is None
    for text in [*BAD_OUTPUT, "EOFError"]:
        assert text not in out + err


@pytest.mark.parametrize(
    "signum, failure",
    [(signal.SIGINT, "interrupted"), (signal.SIGTERM, "interrupted by SIGTERM")],
    ids=["ctrl-c", "sigterm"],
)
def test_a_signal_during_a_run_writes_an_interrupted_summary(tmp_path, signum, failure):
    """Ctrl-C, or SIGTERM from a supervisor or `timeout`, ends a run with its summary."""
    process = subprocess.Popen(
        [GUIDEDARM, "run", WP, "--out", str(tmp_path)],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    for line in process.stdout:
        if line.startswith("guidedarm: running"):
            break
    time.sleep(1.5)
    process.send_signal(signum)
    out, err = process.communicate(timeout=120)
    assert process.returncode == 1, err
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["failure"] == failure
    assert err.strip().splitlines()[-1] == f"guidedarm: run failed: {failure}"
    for text in BAD_OUTPUT:
        assert text not in out + err


@pytest.mark.parametrize(
    "signum, failure",
    [(signal.SIGINT, "interrupted"), (signal.SIGTERM, "interrupted by SIGTERM")],
    ids=["ctrl-c", "sigterm"],
)
def test_an_interrupted_path_following_keeps_its_partial_metrics(tmp_path, signum, failure):
    """A signal during the follower's loop ends it as a device fault does: the summary
    keeps the simulated time and the metrics of the steps made, and no second run. The
    station's loop (about 10 s for the whole hose) is cut at its first progress report
    past step 3, one second in; the kinematic one ends a fraction of a second after that
    report, and a signal that came after its end would find the run complete."""
    process = subprocess.Popen(
        [GUIDEDARM, "run", PF, "--out", str(tmp_path), "--set", "executor=station"],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    for line in process.stderr:
        if line.startswith("  ... step ") and int(line.split()[2].rstrip(",")) >= 3:
            break
    process.send_signal(signum)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 1, err
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["failure"] == failure
    assert summary["sim_time_s"] > 0 and summary["steps"] >= 3
    assert 0 < summary["coverage"] <= 1
    for text in BAD_OUTPUT:
        assert text not in err


def test_public_builders_refuse_bad_arguments_in_one_line():
    """The Python API: a negative time step (Drake's `Failure at` exit), one name instead of
    a list (read as its characters), a truthy string for a bool and an argument of the
    wrong type (an AttributeError deep inside) are refused by name."""
    from guidedarm.diagrams.station.station import MakeStation
    from guidedarm.diagrams.station.station_plant import MakeMultibodyPlant
    from guidedarm.diagrams.tasks.common.planner_builder import MakeAccelerationPlanner
    from guidedarm.systems.path_following.tool_pose_ik_math import (
        ToolPoseIkConfig,
        ToolPoseSolver,
    )
    from guidedarm.systems.planning.acceleration_planner_config import PlannerConfig

    station = LoadScenario(WP, [])[1].station
    plant = MakeMultibodyPlant(station, ["ur10e"])
    instance = plant.GetModelInstanceByName("ur10e")
    frames = ("ur10e::base", "ur10e::flange")
    for call, key in (
        (lambda: MakeStation("ur10e"), "scenario"),
        (lambda: MakeStation(station, kind="real"), "kind"),
        (lambda: MakeStation(station, meshcat=None, kind=True), "kind"),
        (lambda: MakeStation(station, meshcat="localhost"), "meshcat"),
        (lambda: MakeAccelerationPlanner(station, 0, *frames), "arm"),
        (lambda: MakeAccelerationPlanner(station, "ur10e", *frames, config={}), "config"),
        (lambda: MakeAccelerationPlanner(station, "ur10e", *frames, [[0.1, "a"]]), "waypoints"),
        (lambda: ToolPoseSolver(plant, "ur10e", None, ToolPoseIkConfig()), "instance"),
        (lambda: ToolPoseSolver(plant, instance, "flange", ToolPoseIkConfig()), "frame"),
        (lambda: MakeMultibodyPlant(station, ["ur10e"], time_step=-1.0), "time_step"),
        (lambda: MakeMultibodyPlant(station, ["ur10e"], time_step=math.nan), "time_step"),
        (lambda: MakeMultibodyPlant(station, "ur10e"), "model_instance_names"),
        (lambda: MakeMultibodyPlant(station, [0]), "model_instance_names[0]"),
        (lambda: PlannerConfig(robust="false").Validate(), "robust"),
    ):
        with pytest.raises(FieldError) as error:
            call()
        assert error.value.key == key and "\n" not in str(error.value)
    assert MakeMultibodyPlant(station, ["ur10e"], time_step=0.001).time_step() == 0.001


def test_a_drake_check_failing_outside_a_run_is_one_line(monkeypatch, capsys):
    """A command whose Drake call fails a check (pydrake's SystemExit "Failure at ...")
    exits 1 with one line naming the function and condition, without the build path."""
    from guidedarm.diagrams.cli import command_list
    from guidedarm.diagrams.cli.main import main

    def failing(args):
        raise SystemExit(
            "Failure at bazel-out/k8-opt/bin/external/drake+/drake/math/rigid_transform.cc:54 "
            "in GetDeterministicValue(): condition 'is_deterministic()' failed."
        )

    monkeypatch.setattr(command_list, "list_command", failing)
    assert main(["list"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "guidedarm: internal error: a Drake check failed in GetDeterministicValue() "
        "(rigid_transform.cc:54): condition 'is_deterministic()' failed."
    ]
    with pytest.raises(SystemExit):  # any other exit passes through
        monkeypatch.setattr(command_list, "list_command", lambda args: sys.exit(3))
        main(["list"])


def test_a_run_into_a_used_folder_leaves_no_verdict_of_the_previous_run(tmp_path):
    """A previous run's summary.json and traceback.txt in --out are removed when a run
    starts: a refused run leaves no old summary beside its scenario.yaml, and a new summary
    never stands beside an old traceback."""
    (tmp_path / "summary.json").write_text('{"success": true}')
    (tmp_path / "traceback.txt").write_text("Traceback of an earlier run")
    scenario = LoadScenario("ur10e_joint_tour", [])[1]

    def refused(scenario, context):
        raise ConfigurationError("the link is down")

    with pytest.raises(ConfigurationError):
        RunTask(_Task(refused), scenario, RunContext(tmp_path))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scenario.yaml"]


def test_run_task_refuses_a_flag_the_scenario_cannot_run_with_before_writing(tmp_path):
    """RunTask (a campaign job, a script) applies the task's CheckRun as `guidedarm run`
    does: the kinematic executor against hardware is refused with DIR left empty."""
    task, scenario, _ = LoadScenario(PF, ["executor=kinematic"])
    context = RunContext(out_dir=tmp_path / "out", hardware=True, quiet=True)
    with pytest.raises(ConfigurationError, match="executor=kinematic cannot run with --hardware"):
        RunTask(task, scenario, context)
    assert list((tmp_path / "out").iterdir()) == []
