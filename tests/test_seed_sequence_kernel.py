"""The ToF sensor's noise seeding (csrc/seed_sequence.c, tof_tool_sensor_math.SeededGenerator)
against numpy's own default_rng: the same PCG64 state and the same draws for the seeds a
run uses (seed, reading) and (seed, reading, 1), small and large."""

import numpy as np
import pytest

from guidedarm.systems.tof import _seed_sequence
from guidedarm.systems.tof.tof_tool_sensor_math import SeededGenerator


def _Seeds() -> list[tuple[int, ...]]:
    rng = np.random.default_rng(4)
    seeds = [(0, 0), (0, 1), (1, 2, 1), (), (5,), (2**32 - 1, 2**32), (2**70 + 3, 17, 1)]
    for _ in range(300):
        seed, k = int(rng.integers(0, 2**31)), int(rng.integers(0, 10**6))
        seeds += [(seed, k), (seed, k, 1)]
    return seeds


def test_the_generator_is_default_rngs():
    generator = np.random.Generator(np.random.PCG64())
    for entropy in _Seeds():
        expected = np.random.default_rng(entropy)
        got = SeededGenerator(generator, entropy)
        assert got.bit_generator.state == expected.bit_generator.state
        assert got.normal(0.0, 0.002, 6).tolist() == expected.normal(0.0, 0.002, 6).tolist()


def test_bad_entropy_is_refused():
    with pytest.raises(ValueError, match=">= 0"):
        _seed_sequence.PcgState((0, -1))
    with pytest.raises(TypeError):
        _seed_sequence.PcgState((0, 1.5))
