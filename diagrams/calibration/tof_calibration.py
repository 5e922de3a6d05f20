"""`guidedarm calibrate tof SCENARIO --out DIR`: each ToF sensor's range offset against a
flat white target at known distances, in simulation.

The procedure of ST's VL6180X application note (offset calibration: a white target
perpendicular to the sensor at a known distance, the mean of repeated ranges compared with
it), run at TARGET_DISTANCES_M for each group of parallel sensors: the target
(models/calibration/tof_target.sdf) is clamped to the tool (welded to its tool frame, as a
jig on the real tool), perpendicular to sensors 1-3 (which look along the tool's -z), then
to sensors 4-6 (along +y). Per sensor, the mean of reading - distance over the distances
is the offset (how much the sensor reads too long); the slope of reading - distance
against the distance shows crosstalk (reported, not corrected). DIR/tof_offsets.yaml holds
`offset`, the value the ToF tool's `calibration_file` takes.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.common.schema import Transform
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.parsing import AddModel, AddWeld, ModelDirective
from pydrake.systems.analysis import Simulator

from guidedarm.diagrams.run_preparation import WithErrorsDrawn
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.tof.tof_errors import ToFErrors

# Distances from the emitters to the target (m), inside the VL6180X's reliable 20-80 mm.
TARGET_DISTANCES_M = (0.03, 0.04, 0.05, 0.06, 0.07)
# 40 readings (0.8 s at 50 Hz) per distance: the mean's noise (2 mm std, 1 mm steps) and the
# temperature drift's walk during it stay near 0.3 mm each.
READINGS_PER_DISTANCE = 40
# The tool's geometry (models/tools/tof_tool.urdf): emitters h = 55 mm from the tool frame;
# sensors 1-3 look along tool -z, 4-6 along +y. The target's face (its +z) faces them.
_ARM_OFFSET_M = 0.055
SENSOR_GROUPS = ((0, 1, 2), (3, 4, 5))
_TARGET_SHIFT_M = 0.01


def TargetInTool(group: int, distance: float) -> RigidTransform:
    """X_TP: the target's face P perpendicular to the sensors of SENSOR_GROUPS[group], its
    plane `distance` m from their emitters, in the tool frame T. Its centre lies
    _TARGET_SHIFT_M off the group's middle sensor, away from the other arm of the L: the
    110 mm target then ends 10 mm short of that arm's sensor boards, which a target centred
    on the sensors would touch, and still covers the group's three cones."""
    if group == 0:
        return RigidTransform([0.0, _TARGET_SHIFT_M, _ARM_OFFSET_M - distance])
    return RigidTransform(
        RollPitchYaw(np.pi / 2, 0, 0), [0, distance - _ARM_OFFSET_M, -_TARGET_SHIFT_M]
    )


def ToFTool(scenario: Any) -> str:
    """The scenario's one ToF tool (refused without one, or with several)."""
    station = getattr(scenario, "station", None)
    tools = list(getattr(station, "tof_tools", {}))
    if len(tools) != 1:
        raise ConfigurationError(
            f"calibrate tof needs a scenario whose station has one ToF tool, it has {tools}"
        )
    return tools[0]


def MeasureAtDistances(scenario: Any, tool: str) -> np.ndarray:
    """The mean reading (m) of each sensor (6) at each of TARGET_DISTANCES_M (3 x 6)."""
    means = np.full((len(TARGET_DISTANCES_M), 6), np.nan)
    for g, sensors in enumerate(SENSOR_GROUPS):
        for i, distance in enumerate(TARGET_DISTANCES_M):
            # Each placement is measured at its own time: its own noise and drift stream.
            seed = 1000 * (getattr(scenario, "random_seed", 0) or 0) + 10 * g + i
            readings = _Readings(scenario, tool, TargetInTool(g, distance), seed)
            means[i, list(sensors)] = readings[list(sensors)]
    return means


def _Readings(scenario: Any, tool: str, X_TP: RigidTransform, seed: int) -> np.ndarray:
    """The mean of READINGS_PER_DISTANCE valid readings of each sensor with the target at
    X_TP in the tool frame, the sensors' noise seeded with `seed` (NaN where a sensor saw
    nothing)."""
    station_scenario = scenario.station
    tools = {**station_scenario.tof_tools}
    tools[tool] = dataclasses.replace(tools[tool], seed=seed)
    tool_frame = station_scenario.tof_tools[tool].tool_frame
    target = [
        ModelDirective(
            add_model=AddModel(
                file="package://guidedarm/calibration/tof_target.sdf", name="tof_target"
            )
        ),
        ModelDirective(
            add_weld=AddWeld(parent=tool_frame, child="tof_target::target", X_PC=Transform(X_TP))
        ),
    ]
    # No hose: the target is the only thing in front of the sensors.
    station_scenario = dataclasses.replace(
        station_scenario,
        directives=[*station_scenario.directives, *target],
        hose=None,
        tof_tools=tools,
    )
    station = MakeStation(station_scenario)
    simulator = Simulator(station)
    context = simulator.get_mutable_context()
    plant = station.GetSubsystemByName("plant")
    plant_context = plant.GetMyContextFromRoot(context)
    for arm in station_scenario.arms:
        q = plant.GetPositions(plant_context, plant.GetModelInstanceByName(arm))
        station.GetInputPort(f"{arm}.position_commanded").FixValue(context, q)
    period = station_scenario.tof_tools[tool].period
    ranges, valid = [], []
    for k in range(1, READINGS_PER_DISTANCE + 1):
        simulator.AdvanceTo(k * period)
        ranges.append(station.GetOutputPort(f"{tool}.ranges").Eval(context).copy())
        valid.append(station.GetOutputPort(f"{tool}.valid").Eval(context) > 0.5)
    ranges, valid = np.array(ranges), np.array(valid)
    count = valid.sum(axis=0)
    with np.errstate(invalid="ignore"):
        return np.where(count > 0, np.where(valid, ranges, 0).sum(axis=0) / count, np.nan)


def FitOffsets(means: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(offset, slope) of each sensor: the offset is the mean of reading - distance over
    TARGET_DISTANCES_M (ST's offset calibration, at several distances), the slope that of
    reading - distance against the distance (a linearity check: crosstalk makes it
    negative; an intercept extrapolated to 0 mm would be four times noisier); refused when a
    sensor saw nothing at some distance."""
    if np.any(~np.isfinite(means)):
        sensors = sorted({int(j) + 1 for j in np.argwhere(~np.isfinite(means))[:, 1]})
        raise ConfigurationError(f"sensors {sensors} saw no target at some distance")
    d = np.asarray(TARGET_DISTANCES_M)
    A = np.column_stack([np.ones_like(d), d])
    coefficients, *_ = np.linalg.lstsq(A, means - d[:, None], rcond=None)
    return np.mean(means - d[:, None], axis=0), coefficients[1]


def CalibrateToFInSimulation(scenario: Any, out_dir: Path) -> list[str]:
    """Runs the procedure on the scenario's station (errors drawn from its random_seed),
    writes out_dir/tof_offsets.yaml and tof_report.json; returns the lines comparing the
    offsets with the drawn truth."""
    tool = ToFTool(scenario)
    scenario = WithErrorsDrawn(scenario)
    means = MeasureAtDistances(scenario, tool)
    truth = scenario.station.errors.tof_tools.get(tool, ToFErrors()).Offsets()
    return WriteToFOffsets(out_dir, tool, means, truth)


def WriteToFOffsets(
    out_dir: Path, tool: str, means: np.ndarray, truth: np.ndarray | None = None
) -> list[str]:
    """Fits the offsets to the mean readings (m, TARGET_DISTANCES_M x 6; FitOffsets),
    writes out_dir/tof_offsets.yaml and tof_report.json; returns the lines of the table,
    beside the `truth` (m, six) in simulation."""
    offset, slope = FitOffsets(means)
    values = ", ".join(f"{v:.6f}" for v in offset)
    (out_dir / "tof_offsets.yaml").write_text(
        "# How much each of the six sensors reads too long (m), `guidedarm calibrate tof`:\n"
        f"# a white target at {', '.join(f'{d * 1e3:g}' for d in TARGET_DISTANCES_M)} mm, "
        f"{READINGS_PER_DISTANCE} readings each. The ToF tool's calibration_file takes it.\n"
        f"offset: [{values}]\n"
    )
    report = {
        "tool": tool,
        "distances_m": list(TARGET_DISTANCES_M),
        "mean_readings_m": means.round(6).tolist(),
        "offset_m": offset.round(6).tolist(),
        "slope": slope.round(5).tolist(),
    }
    if truth is not None:
        report["true_offset_m"] = truth.round(6).tolist()
    (out_dir / "tof_report.json").write_text(json.dumps(report, indent=1) + "\n")
    if truth is None:
        lines = [f"{'sensor':6s} {'calibrated':>11s}  (mm; slope)"]
        lines += [f"{i + 1:6d} {offset[i] * 1e3:11.3f}  ({slope[i]:+.4f})" for i in range(6)]
        return lines
    lines = [f"{'sensor':6s} {'calibrated':>11s} {'truth':>9s} {'residual':>9s}  (mm; slope)"]
    for i in range(6):
        lines.append(
            f"{i + 1:6d} {offset[i] * 1e3:11.3f} {truth[i] * 1e3:9.3f} "
            f"{(offset[i] - truth[i]) * 1e3:9.3f}  ({slope[i]:+.4f})"
        )
    return lines
