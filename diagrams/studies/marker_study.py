"""The marker studies of `guidedarm marker-study`: each reproduces one accuracy table of
Annusewicz-Mistal et al. in simulation from its campaigns (diagrams/campaigns/marker_*.yaml,
CAMPAIGNS), run through the sweep engine (RunStudy), and writes the table and its plot
(DistanceTable, TiltTable, RepeatabilityTable, PressTable, OcclusionTable; the command's
docstring, diagrams/cli/command_marker_study.py, lists them)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from guidedarm.diagrams.campaigns.campaign import CampaignConfig
from guidedarm.diagrams.campaigns.campaign_file import LoadCampaign
from guidedarm.diagrams.campaigns.jobs import ExpandJobs, Job
from guidedarm.diagrams.campaigns.sweep import Sweep, SweepOptions
from guidedarm.diagrams.panel.panel_files import RecordedModelFile, RecordedPanelFile
from guidedarm.diagrams.run_context import RunContext
from guidedarm.systems.markers.image_degradation import DegradationConfig

CAMPAIGNS = {
    "distance": ("marker_distance_straight", "marker_distance_angled"),
    "tilt": ("marker_tilt",),
    "repeatability": ("marker_repeatability",),
    "press": ("marker_press",),
    "occlusion": ("marker_occlusion",),
}
STUDIES = tuple(CAMPAIGNS)
# The command-line flag of each DegradationConfig field.
DEGRADATION_FLAGS = {"noise_std": "--noise", "blur_sigma_px": "--blur", "lighting": "--lighting"}
Rows = list[dict[str, Any]]


def UnexpectedFailure(row: dict[str, Any]) -> bool:
    """A job that failed, except an `abort` policy run stopping at the covered markers
    (the result Table 6 asks for)."""
    aborted = row.get("operation.on_marker_loss") == "abort" and bool(row.get("lost_measurements"))
    return row["success"] is not True and not aborted


@dataclass(frozen=True)
class StudyCamera:
    """The camera of a study's jobs: the estimator's camera file and the real lens
    (k1 k2 p1 p2 k3), each None for the scenario's own."""

    camera_file: str | None = None
    lens: tuple[float, ...] | None = None


# Where each task of a study takes the real camera's lens.
LENS_KEYS = {
    "marker_view": "camera_errors.distortion",
    "panel_operation": "station.errors.cameras.camera.distortion",
}


def StudyCampaign(
    name: str,
    degradation: DegradationConfig,
    panel_file: str | None = None,
    camera: StudyCamera | None = None,
) -> tuple[CampaignConfig, str]:
    """The campaign `name` with the images of every job degraded as `degradation` (its seed
    left to each job's random_seed) and, given a panel_file, every job on that panel, given
    a camera, every job's estimator camera file and real lens as it says, and its folder
    under DIR (named after them)."""
    campaign = LoadCampaign(name)
    folder = name
    if panel_file is not None:
        campaign.set["panel_file"] = RecordedPanelFile(panel_file)
        folder += f"_{Path(panel_file).stem}"
    camera = camera or StudyCamera()
    if camera.camera_file is not None:
        campaign.set["estimator_camera_file"] = RecordedModelFile(
            "--camera-file", camera.camera_file, "panel/c920_camera.yaml"
        )
        folder += f"_{Path(camera.camera_file).stem}"
    if camera.lens is not None:
        campaign.set[LENS_KEYS[campaign.scenario]] = list(camera.lens)
        folder += "_lens" + "_".join(f"{k:g}" for k in camera.lens)
    if degradation != DegradationConfig():
        campaign.set.update(
            {f"degradation.{k}": getattr(degradation, k) for k in DEGRADATION_FLAGS}
        )
        folder += "_" + "_".join(
            f"{flag[2:]}{getattr(degradation, k):g}" for k, flag in DEGRADATION_FLAGS.items()
        )
    campaign.Validate()
    return campaign, folder


def DistanceTable(context: RunContext, straight: Rows, angled: Rows) -> dict:
    """Table 2: |p_CP| measured vs true, straight on and with a growing view angle."""
    rows = [
        [series, *_Values(r, "reference_deg", "reference_mm", "vision_mm")]
        + _Values(r, "abs_error_mm", "rel_error_pct")
        for series, runs in (("straight", straight), ("angled", angled))
        for r in runs
    ]
    context.write_csv(
        "distance",
        ["series", "angle_deg", "reference_mm", "vision_mm", "abs_error_mm", "rel_error_pct"],
        rows,
    )
    _Plot(context, "distance", rows, 2, 4, "reference distance (mm)", "absolute error (mm)")
    return {
        "max_error_straight_mm": _Max(r[4] for r in rows if r[0] == "straight"),
        "max_error_angled_mm": _Max(r[4] for r in rows if r[0] == "angled"),
        "seed_max_error_mm": 5.9,
    }


def TiltTable(context: RunContext, runs: Rows) -> dict:
    """Table 3: the view angle about the panel's y axis, measured vs true, at 300 mm."""
    columns = ("reference_deg", "vision_deg", "abs_angle_error_deg", "rotation_error_deg")
    rows = [_Values(r, *columns) for r in runs]
    context.write_csv(
        "tilt", ["reference_deg", "vision_deg", "abs_error_deg", "rotation_error_deg"], rows
    )
    _Plot(context, "tilt", rows, 0, 2, "reference angle (deg)", "absolute error (deg)")
    return {
        "max_error_deg": _Max(r[2] for r in rows),
        "max_rotation_error_deg": _Max(r[3] for r in rows),
        "seed_max_error_deg": 3.71,
    }


def RepeatabilityTable(context: RunContext, runs: Rows) -> dict:
    """Table 4: the camera's true distance from the panel at the base point (target 170
    mm), from 16 random starts."""
    rows = []
    for r in runs:
        start, distance, error = _Values(
            r, "measurements.0.distance_mm", "base_camera_distance_mm", "base_position_error_mm"
        )
        rows.append([r["random_seed"], start, distance, abs(distance - 170.0), error])
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
        "max_distance_error_mm": _Max(r[3] for r in rows),
        "max_position_error_mm": _Max(r[4] for r in rows),
        "seed_max_distance_error_mm": 16.4,
    }


def PressTable(context: RunContext, runs: Rows) -> dict:
    """Table 5: tip position while pressing vs target (world frame), 10 random starts."""
    columns = ["press_tip_W_mm.0", "press_tip_W_mm.1", "press_tip_W_mm.2"]
    columns += ["press_error_mm.x", "press_error_mm.y", "press_error_mm.z"]
    rows = [[r["random_seed"], r["switch_pressed"], *_Values(r, *columns)] for r in runs]
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
        "max_error_mm": _Max(v for r in rows for v in r[5:]),
        "seed_max_error_mm": 12.1,
    }


def OcclusionTable(context: RunContext, runs: Rows) -> dict:
    """Table 6: markers covered after the base point, with each on_marker_loss policy."""
    rows = [
        [r["operation.on_marker_loss"], r["random_seed"], r["success"], r["switch_pressed"]]
        + _Values(r, "press_error_mm.x", "press_error_mm.y", "press_error_mm.z")
        + [r["failure"] or ""]
        for r in runs
    ]
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


def _Values(row: dict[str, Any], *columns: str) -> list[float]:
    """The numeric cells of a results row; NaN where the run gave none (it failed)."""
    return [math.nan if row.get(c) is None else float(row[c]) for c in columns]


def _Max(values) -> float | None:
    """The largest finite value, or None (null in the summary) when no run gave one."""
    finite = [v for v in values if math.isfinite(v)]
    return round(max(finite), 3) if finite else None


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
    axes.set_title(f"Annusewicz-Mistal et al. {name} study (simulation)")
    context.save_figure(figure, name)


TABLES = {
    "distance": DistanceTable,
    "tilt": TiltTable,
    "repeatability": RepeatabilityTable,
    "press": PressTable,
    "occlusion": OcclusionTable,
}


@dataclass
class StudyResult:
    """What RunStudy returns: the table's summary figures (TABLES), every campaign's
    results rows, and the jobs that failed unexpectedly (UnexpectedFailure)."""

    summary: dict[str, Any]
    rows: list[Rows]
    failed: Rows


def CheckedCampaigns(
    study: str, degradation: DegradationConfig, panel_file: str | None, camera: StudyCamera
) -> list[tuple[CampaignConfig, str, list[Job]]]:
    """Every campaign of `study` as StudyCampaign makes it, with its folder and its jobs
    (ExpandJobs): all of them checked before the first one runs."""
    studied = [StudyCampaign(name, degradation, panel_file, camera) for name in CAMPAIGNS[study]]
    return [(campaign, folder, ExpandJobs(campaign)) for campaign, folder in studied]


def RunStudy(
    study: str,
    checked: list[tuple[CampaignConfig, str, list[Job]]],
    context: RunContext,
    options: SweepOptions,
) -> StudyResult | None:
    """Runs the CheckedCampaigns of `study` into context.out_dir, then writes its table;
    None when a sweep was interrupted."""
    results = []
    for campaign, folder, jobs in checked:
        result = Sweep(campaign, context.out_dir / folder, options, jobs)
        if result.outcome.interrupted:
            return None
        context.written += result.written
        results.append(result.table.rows)
    summary = TABLES[study](context, *results)
    failed = [r for rows in results for r in rows if UnexpectedFailure(r)]
    if study != "occlusion":
        summary["failed_runs"] = [f"{r['job_id']}: {r['failure']}" for r in failed]
    return StudyResult(summary, results, failed)
