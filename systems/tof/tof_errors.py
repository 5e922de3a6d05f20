"""ToFErrors: how a real six-sensor ToF tool reads differently from the truth."""

from dataclasses import dataclass, field

import numpy as np

from guidedarm.systems.cell_errors.distributions import ScalarError, VectorError
from guidedarm.systems.config_checks import CheckFields
from guidedarm.systems.errors import ConfigurationError

NUM_TOF_SENSORS = 6
# The largest offset a sensor may have (m): the sensor's whole range.
MAX_OFFSET = 0.1


@dataclass
class ToFErrors:
    """The errors of one ToF tool (station.errors.tof_tools.<tool>); numbers or Drake
    distributions, drawn once per run.

    offset: how much longer each of the six sensors reads than the truth (m); empty: 0.
    crosstalk: each sensor's reading falls short of the truth by this fraction of the
        range (a cover glass's crosstalk return pulls ranges in, the more the weaker the
        target's return); empty: 0.
    drift_rate: each sensor's slow range drift (the VL6180X's temperature drift), a random
        walk whose change over one second has this standard deviation (m); 0: no drift.
    drift_max: the drift stays within +-drift_max (m).
    """

    offset: VectorError = field(default_factory=list)
    crosstalk: VectorError = field(default_factory=list)
    drift_rate: ScalarError = 0.0
    drift_max: ScalarError = 0.009

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad field (drawn values only)."""
        CheckFields(self)
        for name in ("offset", "crosstalk"):
            values = getattr(self, name)
            if isinstance(values, list) and len(values) not in (0, NUM_TOF_SENSORS):
                raise ConfigurationError(
                    f"{name} must hold {NUM_TOF_SENSORS} values, one a sensor (got {len(values)})"
                )
        for i, value in enumerate(self.offset if isinstance(self.offset, list) else []):
            if not abs(value) <= MAX_OFFSET:
                raise ConfigurationError(
                    f"offset[{i}] = {value:g} m is outside [-{MAX_OFFSET}, {MAX_OFFSET}]"
                )
        for name in ("drift_rate", "drift_max"):
            value = getattr(self, name)
            if isinstance(value, float | int) and not value >= 0:
                raise ConfigurationError(f"{name} must be >= 0, got {value}")
        drawn = all(isinstance(v, float | int) for v in (self.drift_rate, self.drift_max))
        if drawn and self.drift_rate > 0 and self.drift_max == 0:
            raise ConfigurationError(
                f"drift_rate ({self.drift_rate} m/sqrt(s)) needs drift_max > 0: the drift "
                "is bounded by drift_max"
            )

    def Offsets(self) -> np.ndarray:
        """The six offsets (m) of a drawn model."""
        return _SixValues(self.offset)

    def Crosstalk(self) -> np.ndarray:
        """The six crosstalk fractions of a drawn model."""
        return _SixValues(self.crosstalk)


def ErrorReadings(true_ranges: np.ndarray, errors: ToFErrors, drift: np.ndarray) -> np.ndarray:
    """What the six sensors read before noise (m) for `true_ranges` (m, inf: no return):
    the truth shortened by crosstalk, plus offset and drift."""
    return true_ranges * (1.0 - errors.Crosstalk()) + errors.Offsets() + drift


def _SixValues(values) -> np.ndarray:
    return np.zeros(NUM_TOF_SENSORS) if len(values) == 0 else np.asarray(values, float)
