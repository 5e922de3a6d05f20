"""Arithmetic on 3-vectors given as three floats, for code that runs at servo or sensor
rates: NumPy's per-call overhead on a 3-vector costs more than the arithmetic itself."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

# A 3-vector as floats (x, y, z).
Vector = Sequence[float]


def Dot(a: Vector, b: Vector) -> float:
    """a . b."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def Cross(a: Vector, b: Vector) -> Vector:
    """a x b."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def Distance(a: Vector, b: Vector) -> float:
    """|a - b|."""
    d0, d1, d2 = a[0] - b[0], a[1] - b[1], a[2] - b[2]
    return math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


def Norm(v: np.ndarray) -> float:
    """|v| of a small array: np.linalg.norm's value (the square root of the dot product)
    without its per-call overhead."""
    return math.sqrt(float(v.dot(v)))
