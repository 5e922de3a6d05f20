"""Bounds and rules of Drake's structs used inside our schemas (MultibodyPlantConfig,
SimulatorConfig, CameraConfig, VisualizationConfig, Rgba), applied by
systems/config_checks.py's walk: their floats are finite and their ints >= 0 by the
general rules, DRAKE_BOUNDS adds each field's interval and DRAKE_CHECKS the rules between
fields.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pydrake.geometry import Rgba
from pydrake.multibody.plant import MultibodyPlantConfig
from pydrake.systems.analysis import GetIntegrationSchemes, SimulatorConfig
from pydrake.systems.sensors import CameraConfig
from pydrake.visualization import VisualizationConfig

from guidedarm.systems.config_bounds import (
    NON_NEGATIVE,
    POSITIVE,
    UNIT_INTERVAL,
    Bound,
    FieldError,
)

# The most pixels a camera renders (width x height, after supersampling): 64 MP, above
# the 1920 x 1080 x 3^2 = 18.7 MP of the shipped panel camera; beyond, VTK's buffers fail.
MAX_RENDER_PIXELS = 64_000_000


def _CheckCamera(config: CameraConfig) -> None:
    CheckRenderSize(config, 1)
    try:
        config.MakeCameras()
    except Exception as e:  # Drake lists every problem, one per line
        raise FieldError("", " ".join(str(e).split())) from None


def CheckRenderSize(config: CameraConfig, supersampling: int, key: str = "") -> None:
    """Refuses a camera whose rendered image (width x height x supersampling^2) exceeds
    MAX_RENDER_PIXELS; `key` names the supersampling in the message."""
    pixels = config.width * config.height * supersampling**2
    if pixels > MAX_RENDER_PIXELS:
        by = f" x {key}^2 ({supersampling**2})" if key else ""
        raise FieldError(
            "",
            f"renders {config.width} x {config.height}{by} = {pixels:,} pixels, more than "
            f"{MAX_RENDER_PIXELS:,}",
        )


def _CheckPlantConfig(config: MultibodyPlantConfig) -> None:
    # Drake reads these names only when a plant is built; an empty one checks them.
    from pydrake.multibody.plant import AddMultibodyPlant
    from pydrake.systems.framework import DiagramBuilder

    try:
        AddMultibodyPlant(config, DiagramBuilder())
    except Exception as e:
        raise FieldError("", str(e).strip().splitlines()[0]) from None


def _CheckSimulatorConfig(config: SimulatorConfig) -> None:
    schemes = GetIntegrationSchemes()
    if config.integration_scheme not in schemes:
        raise FieldError(
            "integration_scheme",
            f"unknown scheme '{config.integration_scheme}' (known: {', '.join(schemes)})",
        )


# Bounds of the numeric fields of Drake's structs used inside our schemas (their floats
# are finite and their ints >= 0 by the general rules): a plant steps at most 0.1 s (0
# is continuous), a camera is at most 16384 pixels wide or high.
DRAKE_BOUNDS: dict[type, dict[str, Bound]] = {
    MultibodyPlantConfig: {
        "time_step": Bound(0.0, 0.1),
        "penetration_allowance": POSITIVE,
        "stiction_tolerance": POSITIVE,
        "sap_near_rigid_threshold": NON_NEGATIVE,
    },
    SimulatorConfig: {
        "max_step_size": POSITIVE,
        "accuracy": POSITIVE,
        "start_time": NON_NEGATIVE,
        "target_realtime_rate": NON_NEGATIVE,
    },
    CameraConfig: {
        "width": Bound(1, 16384),
        "height": Bound(1, 16384),
        "clipping_near": POSITIVE,
        "clipping_far": POSITIVE,
        "z_near": POSITIVE,
        "z_far": POSITIVE,
        "fps": POSITIVE,
        "capture_offset": NON_NEGATIVE,
        "output_delay": NON_NEGATIVE,
    },
    CameraConfig.FocalLength: {"x": POSITIVE, "y": POSITIVE},
    CameraConfig.FovDegrees: {
        "x": Bound(0.0, 180.0, True, True),
        "y": Bound(0.0, 180.0, True, True),
    },
    VisualizationConfig: {"publish_period": POSITIVE, "initial_proximity_alpha": UNIT_INTERVAL},
    Rgba: {"rgba": UNIT_INTERVAL},
}

# Rules between the fields of Drake's structs, checked after their bounds.
DRAKE_CHECKS: dict[type, Callable[[Any], None]] = {
    CameraConfig: _CheckCamera,
    MultibodyPlantConfig: _CheckPlantConfig,
    SimulatorConfig: _CheckSimulatorConfig,
}
