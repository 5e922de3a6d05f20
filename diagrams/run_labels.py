"""How a run names itself on its figures and report: title (arm, scenario, variant) and
the headline figures that go under each plot."""

from __future__ import annotations

from typing import Any

# Scenario fields that tell the variants of a scenario apart, in the order shown.
VARIANT_FIELDS = ("limits", "path", "path_csv", "estimator", "motion", "executor", "switch")

# The summary metrics printed under each figure, by figure name: (key, label, unit).
HEADLINES: dict[str, list[tuple[str, str, str]]] = {
    "tcp_path": [("T_s", "T", "s"), ("final_error_m", "e(T)", "m")],
    "joint_positions": [
        ("tracking_error_max_rad", "max joint tracking error", "rad"),
        ("tcp_tracking_error_max_m", "max TCP tracking error", "m"),
    ],
    "joint_velocities": [("qd_max", "max", "rad/s"), ("qd_min", "min", "rad/s")],
    "joint_accelerations": [("qdd_max", "max", "rad/s^2"), ("qdd_min", "min", "rad/s^2")],
    "scaling_coefficient": [("c_min", "min c", "")],
    "joints": [
        ("tracking_error_max_rad", "max tracking error", "rad"),
        ("final_error_rad", "final error", "rad"),
    ],
    "detected_path": [
        ("detected_path_error_mean_mm", "detected-path error mean", "mm"),
        ("detected_path_error_max_mm", "max", "mm"),
        ("tracking_error_mean_mm", "tracking error mean", "mm"),
        ("tracking_error_max_mm", "max", "mm"),
        ("coverage", "coverage", ""),
    ],
    "repeatability": [
        ("repeatability_mean_mm", "repeatability mean", "mm"),
        ("repeatability_max_mm", "max", "mm"),
    ],
    "tip_distance": [
        ("base_position_error_mm", "base point error", "mm"),
        ("press_error_mm", "press error", "mm"),
    ],
}


def RunTitle(name: str, scenario: Any, overrides: list[str]) -> str:
    """e.g. "ur10e_waypoints · ur10e · limits=none": the scenario, its arm and what sets
    this variant apart (the variant fields of the scenario, then the --set overrides)."""
    parts = [name]
    arm = getattr(scenario, "arm", "")
    if arm:
        parts.append(str(arm))
    variant = []
    for key in VARIANT_FIELDS:
        value = getattr(scenario, key, None)
        if value not in (None, ""):
            variant.append(f"{key}={value}")
    shown = {v.split("=", 1)[0] for v in variant}
    variant += [o for o in overrides if o.split("=", 1)[0] not in shown]
    if variant:
        parts.append(", ".join(variant))
    return " · ".join(parts)


def HeadlineText(figure_name: str, metrics: dict[str, Any]) -> str:
    """The headline figures of `figure_name` found in `metrics`, on one line."""
    items = []
    for key, label, unit in HEADLINES.get(figure_name, []):
        value = metrics.get(key)
        if value is None:
            continue
        items.append(f"{label} {_Format(value)}{' ' + unit if unit else ''}")
    return ";  ".join(items)


def _Format(value: Any) -> str:
    if isinstance(value, dict):
        return "(" + ", ".join(f"{k} {_Format(v)}" for k, v in value.items()) + ")"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)
