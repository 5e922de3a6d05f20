"""`guidedarm marker-study distance|tilt|repeatability|press|occlusion [--out DIR]`.

Each study reproduces one table of seed 003 in simulation and writes DIR/<study>.csv and
DIR/<study>.png:
  distance       Table 2: camera distance from the left marker, 200-430 mm, straight on and
                 with the view angle growing to 24 deg (the seed's second series);
  tilt           Table 3: rotation about the panel's y axis, 0-26 deg at 300 mm;
  repeatability  Table 4: the base position (170 mm) reached from 16 random starts;
  press          Table 5: the tip position while pressing, 10 runs from random starts;
  occlusion      Table 6: markers covered after the base position, both policies.
The first two use the free camera rig (exact ground truth, as the seed's IRB 1600); the
others run the whole panel_operation task. --noise, --blur and --lighting degrade the
images (ImageDegradation).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from guidedarm.diagrams.cli.command_run import LoadScenario
from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.tasks.panel_camera_rig import LookAt, PanelCameraRig
from guidedarm.diagrams.tasks.panel_files import DEFAULT_PANEL_FILE, LoadPanelSpec
from guidedarm.diagrams.tasks.panel_operation import PanelOperationRun
from guidedarm.systems.config_checks import FieldError
from guidedarm.systems.errors import ConfigurationError, GuidedArmError
from guidedarm.systems.markers.image_degradation import DegradationConfig
from guidedarm.systems.markers.marker_pose_estimator_math import MarkerPoseSolver

STUDIES = ("distance", "tilt", "repeatability", "press", "occlusion")
# The command-line flag of each DegradationConfig field.
DEGRADATION_FLAGS = {"noise_std": "--noise", "blur_sigma_px": "--blur", "lighting": "--lighting"}


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "marker-study", help="reproduce seed 003's accuracy tables in simulation"
    )
    parser.add_argument("study", choices=STUDIES)
    parser.add_argument("--out", type=Path, help="output directory (default runs/marker_study)")
    parser.add_argument("--noise", type=float, default=0.0, help="noise std (grey levels)")
    parser.add_argument("--blur", type=float, default=0.0, help="blur sigma (px)")
    parser.add_argument("--lighting", type=float, default=1.0, help="brightness scale")
    parser.set_defaults(func=study_command)


def study_command(args: argparse.Namespace) -> int:
    degradation = DegradationConfig(
        lighting=args.lighting, blur_sigma_px=args.blur, noise_std=args.noise, seed=1
    )
    try:
        degradation.Validate()
    except FieldError as e:
        raise ConfigurationError(f"{DEGRADATION_FLAGS.get(e.key, e.key)}: {e.why}") from None
    context = RunContext(out_dir=args.out or Path("runs") / "marker_study")
    study = {
        "distance": DistanceStudy,
        "tilt": TiltStudy,
        "repeatability": RepeatabilityStudy,
        "press": PressStudy,
        "occlusion": OcclusionStudy,
    }[args.study]
    summary = study(context, degradation)
    for key, value in summary.items():
        print(f"  {key}: {value}")
    print("wrote:")
    for path in context.written:
        print(f"  {path}")
    return 0


def _RigAndSolver():
    _, scenario, _ = LoadScenario("panel_operation", [])
    rig = PanelCameraRig(scenario.station.cameras[scenario.camera], scenario.supersampling)
    return rig, MarkerPoseSolver(rig.intrinsics, LoadPanelSpec(DEFAULT_PANEL_FILE))


def _Estimate(solver, rig, X_PC, degradation, stream):
    estimate = solver.estimate(rig.Render(X_PC, degradation, stream))
    if not estimate.valid:
        raise GuidedArmError(f"no valid pose at camera position {X_PC.translation()} (m)")
    return estimate


def DistanceStudy(context: RunContext, degradation: DegradationConfig) -> dict:
    """Table 2: |p_CP| measured vs true, straight on and with a growing view angle."""
    rig, solver = _RigAndSolver()
    rows = []
    distances = np.linspace(0.200, 0.430, 13)
    for series, angles in (("straight", np.zeros(13)), ("angled", np.linspace(0, 24, 13))):
        for i, (d, angle) in enumerate(zip(distances, angles, strict=True)):
            a = np.radians(angle)
            X_PC = LookAt(d * np.array([np.sin(a), 0.0, np.cos(a)]), [0, 0, 0])
            estimate = _Estimate(solver, rig, X_PC, degradation, i)
            measured = np.linalg.norm(estimate.X_CP.translation())
            error = abs(measured - d)
            rows.append([series, angle, 1e3 * d, 1e3 * measured, 1e3 * error, 100 * error / d])
    context.write_csv(
        "distance",
        ["series", "angle_deg", "reference_mm", "vision_mm", "abs_error_mm", "rel_error_pct"],
        rows,
    )
    _Plot(context, "distance", rows, 2, 4, "reference distance (mm)", "absolute error (mm)")
    straight = [r[4] for r in rows if r[0] == "straight"]
    return {
        "max_error_straight_mm": round(max(straight), 3),
        "max_error_angled_mm": round(max(r[4] for r in rows if r[0] == "angled"), 3),
        "seed_max_error_mm": 5.9,
    }


def TiltStudy(context: RunContext, degradation: DegradationConfig) -> dict:
    """Table 3: the view angle about the panel's y axis, measured vs true, at 300 mm."""
    rig, solver = _RigAndSolver()
    rows = []
    for i, angle in enumerate(range(0, 27, 2)):
        a = np.radians(angle)
        X_PC = LookAt(0.3 * np.array([np.sin(a), 0.0, np.cos(a)]), [0, 0, 0])
        estimate = _Estimate(solver, rig, X_PC, degradation, i)
        z_P = estimate.X_CP.inverse().rotation().matrix()[:, 2]
        measured = np.degrees(np.arctan2(-z_P[0], -z_P[2]))
        R_error = estimate.X_CP.rotation().inverse() @ X_PC.inverse().rotation()
        full = np.degrees(R_error.ToAngleAxis().angle())
        rows.append([angle, measured, abs(measured - angle), full])
    context.write_csv(
        "tilt", ["reference_deg", "vision_deg", "abs_error_deg", "rotation_error_deg"], rows
    )
    _Plot(context, "tilt", rows, 0, 2, "reference angle (deg)", "absolute error (deg)")
    return {
        "max_error_deg": round(max(r[2] for r in rows), 3),
        "max_rotation_error_deg": round(max(r[3] for r in rows), 3),
        "seed_max_error_deg": 3.71,
    }


def _TaskRuns(context, degradation, overrides, seeds, switches=(2,)):
    results = []
    for switch in switches:
        _, scenario, _ = LoadScenario("panel_operation", [f"switch={switch}", *overrides])
        scenario.degradation = degradation
        run = PanelOperationRun(scenario, RunContext(context.out_dir, quiet=True))
        for seed in seeds:
            context.progress(f"switch {switch}, start {seed}", force=True)
            results.append((seed, run.Run(run.SampleStart(seed))))
    return results


def RepeatabilityStudy(context: RunContext, degradation: DegradationConfig) -> dict:
    """Table 4: the camera's true distance from the panel at the base point (target 170
    mm), from 16 random starts."""
    rows = []
    for seed, r in _TaskRuns(context, degradation, [], range(16)):
        start = r["measurements"][0].get("distance_mm", float("nan"))
        distance = r["base_camera_distance_mm"]
        rows.append([seed, start, distance, abs(distance - 170.0), r["base_position_error_mm"]])
    context.write_csv(
        "repeatability",
        [
            "start_seed",
            "start_distance_mm",
            "base_distance_mm",
            "abs_error_mm",
            "base_position_error_mm",
        ],
        rows,
    )
    _Plot(context, "repeatability", rows, 1, 4, "start distance (mm)", "base position error (mm)")
    return {
        "max_distance_error_mm": round(max(r[3] for r in rows), 3),
        "max_position_error_mm": round(max(r[4] for r in rows), 3),
        "seed_max_distance_error_mm": 16.4,
    }


def PressStudy(context: RunContext, degradation: DegradationConfig) -> dict:
    """Table 5: tip position while pressing vs target (world frame), 10 random starts."""
    rows = []
    for seed, r in _TaskRuns(context, degradation, [], range(10)):
        e = r["press_error_mm"] or {"x": np.nan, "y": np.nan, "z": np.nan}
        tip = r["press_tip_W_mm"] or [np.nan] * 3
        rows.append([seed, r["switch_pressed"], *tip, e["x"], e["y"], e["z"]])
    context.write_csv(
        "press",
        [
            "start_seed",
            "switch_pressed",
            "x_mm",
            "y_mm",
            "z_mm",
            "error_x_mm",
            "error_y_mm",
            "error_z_mm",
        ],
        rows,
    )
    _Plot(context, "press", rows, 0, 5, "start seed", "press error x (mm)")
    return {
        "all_pressed": all(r[1] == 2 for r in rows),
        "max_error_mm": round(float(np.nanmax([r[5:] for r in rows])), 3),
        "seed_max_error_mm": 12.1,
    }


def OcclusionStudy(context: RunContext, degradation: DegradationConfig) -> dict:
    """Table 6: markers covered after the base point, with each on_marker_loss policy."""
    rows = []
    for policy in ("abort", "continue"):
        overrides = ["cover_markers_after_base=true", f"operation.on_marker_loss={policy}"]
        for seed, r in _TaskRuns(context, degradation, overrides, range(2)):
            e = r["press_error_mm"] or {"x": np.nan, "y": np.nan, "z": np.nan}
            rows.append(
                [
                    policy,
                    seed,
                    r["success"],
                    r["switch_pressed"],
                    e["x"],
                    e["y"],
                    e["z"],
                    r["failure"] or "",
                ]
            )
    context.write_csv(
        "occlusion",
        [
            "policy",
            "start_seed",
            "success",
            "switch_pressed",
            "error_x_mm",
            "error_y_mm",
            "error_z_mm",
            "failure",
        ],
        rows,
    )
    _Plot(
        context,
        "occlusion",
        [r for r in rows if r[0] == "continue"],
        1,
        4,
        "start seed",
        "press error x (mm), continue policy",
    )
    return {
        "abort": [r[7] for r in rows if r[0] == "abort"],
        "continue_pressed": [r[3] for r in rows if r[0] == "continue"],
    }


def _Plot(context, name, rows, x_column, y_column, x_label, y_label) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(figsize=(6, 3.5))
    series = sorted({r[0] for r in rows}) if isinstance(rows[0][0], str) else [None]
    for s in series:
        chosen = [r for r in rows if s is None or r[0] == s]
        axes.plot(
            [r[x_column] for r in chosen], [r[y_column] for r in chosen], "o-", label=s or name
        )
    axes.set_xlabel(x_label)
    axes.set_ylabel(y_label)
    axes.grid(True, alpha=0.3)
    axes.legend()
    axes.set_title(f"seed 003 {name} study (simulation)")
    context.save_figure(figure, name)
