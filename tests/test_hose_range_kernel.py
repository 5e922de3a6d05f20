"""hose_range_model's compiled kernel (csrc/hose_range.c) against its Python reference
(tests/hose_range_model_reference.py) on random inputs on the tool's own geometry: the
ranges and the centre fit to the last bit, the radius fit to 1e-12 (its least squares is a
Jacobi SVD in the kernel, LAPACK's in the reference)."""

import math

import hose_range_model_reference as reference
import numpy as np
import pytest
from pydrake.math import RollPitchYaw, RotationMatrix

from guidedarm.systems.tof import _hose_range
from guidedarm.systems.tof.hose_range_model import HoseRangeModel, RadiusFit

# The MZ04D ToF tool's sensors in T (MakeDetectionGrid): rows 1-3 look along -z_T from
# 55 mm above the detection field's centre O, columns 4-6 along +y_T from 55 mm beside it,
# 22 mm apart (the grid spacing).
_EMITTERS = [(0.0, y, 0.055) for y in (-0.022, 0.0, 0.022)]
_EMITTERS += [(0.0, -0.055, z) for z in (-0.022, 0.0, 0.022)]
_AXES = [(0.0, 0.0, -1.0), (0.0, 1.0, 0.0)]
R = 0.010


def _Models(radius: float = R) -> tuple[HoseRangeModel, reference.HoseRangeModel]:
    axes = [_AXES[0]] * 3 + [_AXES[1]] * 3
    angle = math.radians(25.0)
    return (
        HoseRangeModel(_EMITTERS, axes, radius, angle),
        reference.HoseRangeModel(_EMITTERS, axes, radius, angle),
    )


def _Axis(rng: np.random.Generator) -> np.ndarray | None:
    """None (a perpendicular hose) one time in three, else x_T tilted up to 40 deg."""
    if rng.uniform() < 1 / 3:
        return None
    tilt = RollPitchYaw(0.0, *rng.uniform(-0.7, 0.7, 2))
    return RotationMatrix(tilt).matrix()[:, 0]


def _Reading(rng, model, axis) -> tuple[tuple, list[float], list[int]]:
    """A start (the true centre moved up to 4 mm), the six ranges of a hose of a random
    radius (0.7 to 1.4 r) at a random centre with 1 mm of noise, and the sensors with a
    return."""
    centre = (rng.uniform(-0.003, 0.003), *rng.uniform(-0.012, 0.012, 2))
    radius = rng.uniform(0.7, 1.4) * R
    axis_floats = None if axis is None else tuple(axis.tolist())
    ranges, sensors = [], []
    for k in range(6):
        if axis_floats is None:
            r = model.PlaneRange(k, centre, radius)
        else:
            r = model.CylinderRange(k, centre, axis_floats, radius)
        ranges.append(0.1 if r is None else r + rng.normal(0.0, 0.001))
        if r is not None:
            sensors.append(k)
    start = tuple((np.array(centre) + rng.uniform(-0.004, 0.004, 3) * [0, 1, 1]).tolist())
    return start, ranges, sensors


def test_the_ranges_equal_the_reference():
    """Centres over the field and beyond, radii from 0.5 to 2 r, perpendicular and tilted
    hoses: the same range to the last bit, and None where the reference has None."""
    kernel, python = _Models()
    rng = np.random.default_rng(1)
    hits = 0
    for _ in range(4000):
        c = tuple(rng.uniform(-0.04, 0.04, 3).tolist())
        k = int(rng.integers(6))
        radius = rng.choice([None, rng.uniform(0.5, 2.0) * R])
        axis = _Axis(rng)
        if axis is None:
            got, expected = kernel.PlaneRange(k, c, radius), python.PlaneRange(k, c, radius)
        else:
            a = tuple(axis.tolist())
            got = kernel.CylinderRange(k, c, a, radius)
            expected = python.CylinderRange(k, c, a, radius)
        assert got == expected
        hits += got is not None
    assert hits > 1000


def test_the_centre_fit_equals_the_reference():
    """Noisy readings of perpendicular and tilted hoses of other radii, all sensors with a
    return or a random subset of them: the same centre as the reference; to the last bit
    except where the normal equations are ill-conditioned and both take the minimum-norm
    least squares (LAPACK's SVD there, a Jacobi SVD here)."""
    kernel, python = _Models()
    rng = np.random.default_rng(2)
    exact = moved = 0
    for n in range(1500):
        axis = _Axis(rng)
        start, ranges, sensors = _Reading(rng, python, axis)
        if n % 2:
            sensors = sorted(rng.choice(sensors, rng.integers(len(sensors) + 1), replace=False))
            sensors = [int(k) for k in sensors]
        got = kernel.Refine(start, ranges, sensors, axis, 0.011)
        expected = python.Refine(start, ranges, sensors, axis, 0.011)
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)
        exact += tuple(got) == tuple(expected)
        moved += tuple(expected) != start
    assert exact >= 0.99 * 1500
    assert moved > 500


def test_the_radius_fit_equals_the_reference():
    """The same readings with five or six sensors: the same centre and radius to 1e-10
    (the reference's least squares is LAPACK's SVD, the kernel's a Jacobi SVD: they round
    differently, and a fit with rows past a cone's rim is conditioned worse), and None
    where the reference finds none."""
    kernel, python = _Models()
    rng = np.random.default_rng(3)
    fitted = 0
    for _ in range(1500):
        axis = _Axis(rng)
        start, ranges, sensors = _Reading(rng, python, axis)
        got = RadiusFit(kernel, start, ranges, sensors, axis, 0.011)
        expected = reference.RadiusFit(python, start, ranges, sensors, axis, 0.011)
        assert (got is None) == (expected is None)
        if got is not None:
            fitted += 1
            np.testing.assert_allclose(got[0], expected[0], rtol=0, atol=1e-10)
            assert got[1] == pytest.approx(expected[1], rel=0, abs=1e-10)
    assert fitted > 300


@pytest.mark.parametrize("columns", [2, 3])
def test_the_least_squares_is_lstsq(columns):
    """The fits' least squares give lstsq's solution (the centre fit's 2 x 2 normal
    equations, the radius fit's Jacobi SVD), and a rank-deficient Jacobian (parallel
    columns) lstsq's minimum-norm one."""
    rng = np.random.default_rng(5)
    for n in (columns, 4, 6):
        for _ in range(50):
            J, r = rng.normal(size=(n, columns)), rng.normal(size=n)
            expected = np.linalg.lstsq(J, r, rcond=None)[0]
            got = _hose_range.LeastSquares(J.tolist(), r.tolist())
            np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12)
    J = np.array([[1.0, 2.0, 0.5], [2.0, 4.0, 1.0], [-1.0, -2.0, 3.0]])[:, :columns]
    J[:, -1] = J[:, 0] * 2 if columns == 2 else J[:, -1]
    J[:, 1] = 2 * J[:, 0]
    r = np.array([1.0, 0.5, -2.0])
    got = _hose_range.LeastSquares(J.tolist(), r.tolist())
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got, np.linalg.lstsq(J, r, rcond=None)[0], atol=1e-12)


def test_bad_arguments_raise():
    kernel, _ = _Models()
    with pytest.raises(ValueError, match="k: 6"):
        kernel.PlaneRange(6, (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="sensors: 7"):
        kernel.Refine((0.0, 0.0, 0.0), [0.05] * 6, [0, 1, 7], None, 0.01)
    with pytest.raises(ValueError, match="ranges: 6 floats"):
        kernel.Refine((0.0, 0.0, 0.0), [0.05] * 5, [0, 1, 2], None, 0.01)
