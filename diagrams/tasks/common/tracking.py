"""How closely a measured arm followed its commands, allowing for a transport delay.

Against hardware the measured arm lags its stream by the link and the controller's own
interpolation (about 30 ms through the Nachi emulator): compared at the same instant, a
joint moving at 1 rad/s seems 0.03 rad off a path it follows exactly. The tasks judge
tracking at the delay, up to MAX_TRACKING_DELAY, that fits the measurement best, and
report that delay; the simulated station's stiff servo lags about one plant step.
"""

import math
from collections.abc import Callable

import numpy as np

# The longest lag (s) of the measured arm behind its commands that tracking allows for,
# and the step (s) of the delays tried (the station's plant step).
MAX_TRACKING_DELAY = 0.1
DELAY_STEP = 0.002


def DelayedTrackingError(
    times: np.ndarray,
    commanded_at: Callable[[np.ndarray], np.ndarray],
    measured: np.ndarray,
    norm: float = 2,
) -> tuple[float, float]:
    """(delay, error): the delay (s, 0..MAX_TRACKING_DELAY in DELAY_STEP) that minimises the
    worst distance `error` between measured[k] (N x d, sampled at times (N,), s) and the
    commands commanded_at(times - delay) (N x d; clamped before the first command), the
    distance of each sample being the vector norm of order `norm` (2: Euclidean, e.g. a
    TCP position in m; inf: the largest joint error in rad)."""
    best = (0.0, math.inf)
    for delay in np.arange(0.0, MAX_TRACKING_DELAY + DELAY_STEP / 2, DELAY_STEP):
        offsets = commanded_at(times - delay) - measured
        error = float(np.linalg.norm(offsets, ord=norm, axis=1).max())
        if error < best[1]:
            best = (round(float(delay), 4), error)
    return best


def SampledCommands(times: np.ndarray, values: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """The commands values (N x d) given at times (N, s) as a function of time, linear in
    between and held before the first and after the last."""

    def At(t: np.ndarray) -> np.ndarray:
        return np.column_stack([np.interp(t, times, column) for column in values.T])

    return At
