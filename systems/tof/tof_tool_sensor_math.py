"""Mathematics of the six-sensor ToF detection tool (Wawrzyniak et al., sections 2.2 and 3.1).

Ray casting. Each VL6180X-like sensor S sees a cone (25 deg vertex angle) around its +z
axis. The cone is sampled by rays (a centre ray and rings of rays); the sensor reports the
nearest surface any ray meets within max_range. A ray is cast by sphere tracing against the
scene's proximity geometry with QueryObject.ComputeSignedDistanceToPoint: at a point p the
nearest surface is at least the minimum signed distance d away, so the ray advances by d
until d < hit_tolerance (a hit) or it leaves the range (no return). This senses whatever
geometry SceneGraph holds (hose, table, brackets, the robot), is exact for every shape that
query supports (all Drake primitives), and costs only a broadphase check for a sensor with
nothing within range. A depth camera per sensor would also work, but six VTK renders cost
more than the handful of distance queries a reading needs, and rendered depth is quantised
by the pixel grid.

Readings: noise and quantisation (Measure), the calibrated offsets (CalibratedRanges), the
range drift (DriftStep), the mean of readings at rest (AverageReadings) and the seeded
generator of each reading's noise (SeededGenerator). What the six
ranges say about the hose: detection_grid (the 3 x 3 grid and the estimators of the hose
centre) and hose_range_model (the ranges a hose gives, for the ranging estimator).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pydrake.geometry import GeometryId, QueryObject
from pydrake.math import RigidTransform

from guidedarm.systems.tof import _seed_sequence


def ConeRays(cone_angle: float, rings: int) -> np.ndarray:
    """Unit ray directions (K, 3) in the sensor frame: the +z axis and `rings` rings up to
    the cone's half angle, with 6 k rays on ring k."""
    half = cone_angle / 2
    rays = [np.array([0.0, 0.0, 1.0])]
    for k in range(1, rings + 1):
        theta = half * k / rings
        for j in range(6 * k):
            phi = 2 * math.pi * j / (6 * k)
            rays.append(
                np.array(
                    [
                        math.sin(theta) * math.cos(phi),
                        math.sin(theta) * math.sin(phi),
                        math.cos(theta),
                    ]
                )
            )
    return np.array(rays)


@dataclass(frozen=True)
class RayCaster:
    """Sphere tracing of cone rays against a QueryObject (ranges in m, poses in world W)."""

    rays_S: np.ndarray
    max_range: float
    ignored: frozenset[GeometryId] = frozenset()
    hit_tolerance: float = 2e-4
    max_iterations: int = 48

    def Range(self, query: QueryObject, X_WS: RigidTransform) -> float:
        """Nearest return within the cone (m), or math.inf when nothing is in range."""
        origin = X_WS.translation()
        d_origin = self._Distance(query, origin, self.max_range)
        if d_origin is None:
            return math.inf
        directions = X_WS.rotation().matrix() @ self.rays_S.T
        best = math.inf
        for k in range(directions.shape[1]):
            best = min(best, self._Trace(query, origin, directions[:, k], best, d_origin))
        return best

    def _Trace(self, query, origin: np.ndarray, u: np.ndarray, limit: float, d: float) -> float:
        """Distance along u to the first surface within limit (m), or math.inf; d is the
        distance from the origin to the nearest surface. The distance field is 1-Lipschitz,
        so after an advance by d the nearest surface is at most 2 d away: querying only
        that far skips the hose's other capsules and gives the same distances."""
        t = 0.0
        limit = min(limit, self.max_range)
        if d > limit:
            return math.inf
        for _ in range(self.max_iterations - 1):
            if d < self.hit_tolerance:
                return t
            t += d
            if t > limit:
                return math.inf
            d = self._Distance(query, origin + t * u, min(limit - t, 2 * d + 1e-6))
            if d is None:
                return math.inf
        return t if d < self.hit_tolerance else math.inf

    def _Distance(self, query: QueryObject, p_W: np.ndarray, threshold: float):
        """Smallest signed distance to a non-ignored geometry within threshold, or None."""
        if threshold <= 0:
            return None
        best = None
        for result in query.ComputeSignedDistanceToPoint(p_W, threshold):
            if result.id_G in self.ignored:
                continue
            if best is None or result.distance < best:
                best = result.distance
        return None if best is None else max(best, 0.0)


def Measure(
    true_ranges: np.ndarray,
    rng: np.random.Generator,
    noise_std: float,
    quantization: float,
    max_range: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Noisy, quantised readings (m) and validity flags. An invalid reading (no return, or
    noise pushing it past max_range) reports max_range, as the device reports its limit."""
    noise = rng.normal(0.0, noise_std, size=true_ranges.shape)
    finite = np.isfinite(true_ranges)
    noisy = np.where(finite, true_ranges, max_range) + noise
    # rint and maximum: np.round's and np.clip's values (half to even; no upper bound)
    # without their wrappers' overhead, which a reading at 50 Hz pays.
    if quantization > 0:
        noisy = np.rint(noisy / quantization) * quantization
    noisy = np.maximum(noisy, 0.0)
    valid = finite & (noisy <= max_range)
    return np.where(valid, noisy, max_range), valid


def SeededGenerator(
    generator: np.random.Generator, entropy: tuple[int, ...]
) -> np.random.Generator:
    """`generator` (a PCG64 Generator, reused from reading to reading) set to the state
    np.random.default_rng(entropy) starts in, and returned: the same draws, without the
    SeedSequence and BitGenerator objects default_rng makes, about 25 us a call (the state
    from the compiled kernel csrc/seed_sequence.c, tested against default_rng)."""
    state_high, state_low, inc_high, inc_low = _seed_sequence.PcgState(entropy)
    generator.bit_generator.state = {
        "bit_generator": "PCG64",
        "state": {"state": state_high << 64 | state_low, "inc": inc_high << 64 | inc_low},
        "has_uint32": 0,
        "uinteger": 0,
    }
    return generator


def CalibratedRanges(ranges: np.ndarray, valid: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Readings (m) with each sensor's calibrated offset (m, how much it reads too long;
    `guidedarm calibrate tof`) subtracted where valid; an invalid reading keeps the device's
    report (its limit)."""
    return np.where(valid, ranges - offset, ranges)


def DriftStep(
    drift: np.ndarray, rng: np.random.Generator, rate: float, dt: float, bound: float
) -> np.ndarray:
    """The range drift (m) of each sensor dt seconds later: a random walk whose change over
    one second has standard deviation `rate` (m), reflected at +-bound (the datasheet's
    temperature drift reaches 9 mm)."""
    drift = drift + rng.normal(0.0, rate * math.sqrt(dt), size=drift.shape)
    drift = np.where(drift > bound, 2 * bound - drift, drift)
    drift = np.where(drift < -bound, -2 * bound - drift, drift)
    return np.clip(drift, -bound, bound)


def AverageReadings(
    readings: Sequence[tuple[np.ndarray, np.ndarray]],
) -> tuple[np.ndarray, np.ndarray]:
    """One reading (ranges, valid) from N readings (ranges, valid) of the same sensors at
    rest: a sensor is valid when more than half of its readings are, with the mean of those
    as its range; an invalid one keeps the device's report (its limit)."""
    ranges = np.array([r for r, _ in readings])
    valid = np.array([v for _, v in readings], bool)
    count = valid.sum(axis=0)
    mean = np.where(valid, ranges, 0.0).sum(axis=0) / np.maximum(count, 1)
    averaged_valid = 2 * count > len(ranges)
    return np.where(averaged_valid, mean, ranges.max(axis=0)), averaged_valid
