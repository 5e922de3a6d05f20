"""Values of an error model: numbers or Drake stochastic schema distributions, drawn once.

A field of an error model holds a number (list) or one of Drake's distributions (YAML tags
`!Gaussian`, `!Uniform`, `!GaussianVector`, `!UniformVector`, `!Deterministic...`), and a
pose error a Drake `Transform` whose translation and Rpy angles may be distributions.
`DrawErrors` replaces every distribution of an error-model tree by one draw; each leaf
field draws from its own stream, seeded by the run's random seed and the field's dotted
name (SourceGenerator), so adding, changing or removing one source leaves the draws of
the others as they were.
"""

from __future__ import annotations

import dataclasses
import hashlib
import typing
from typing import Any

import numpy as np
from pydrake.common import RandomGenerator
from pydrake.common.schema import (
    Deterministic,
    DeterministicVectorX,
    Gaussian,
    GaussianVectorX,
    Transform,
    Uniform,
    UniformVectorX,
)

from guidedarm.systems.errors import ConfigurationError

# A scalar error: a number, or a distribution of one.
ScalarError = typing.Union[float, Deterministic, Gaussian, Uniform]  # noqa: UP007
# A vector error (one value per joint, per sensor, ...): a list, or a distribution of one.
VectorError = typing.Union[  # noqa: UP007
    list[float], DeterministicVectorX, GaussianVectorX, UniformVectorX
]
_SCALAR_DISTRIBUTIONS = (Deterministic, Gaussian, Uniform)
_VECTOR_DISTRIBUTIONS = (DeterministicVectorX, GaussianVectorX, UniformVectorX)


def SourceGenerator(random_seed: int, source: str) -> RandomGenerator:
    """The random stream of one error source (its dotted name, e.g.
    `arms.ur10e.joint_offset`) in a run with `random_seed`: seeded by a hash of both."""
    digest = hashlib.sha256(f"{int(random_seed)}:{source}".encode()).digest()
    return RandomGenerator(int.from_bytes(digest[:4], "little"))


def IsDrawn(value: Any) -> bool:
    """Whether an error value holds no distribution: a number, a list of numbers, or a
    Transform whose translation and rotation are fixed."""
    if isinstance(value, _SCALAR_DISTRIBUTIONS + _VECTOR_DISTRIBUTIONS):
        return False
    if isinstance(value, Transform):
        return value.IsDeterministic()
    return True


def DrawValue(value: Any, generator: RandomGenerator | None) -> Any:
    """One draw of an error value: a float, a list of floats, or a fixed Transform. Without
    a generator a distribution is refused (ConfigurationError)."""
    if IsDrawn(value):
        if isinstance(value, Transform):
            return Transform(value.GetDeterministicValue())
        return value
    if generator is None:
        raise ConfigurationError("an error distribution needs a random seed to be drawn")
    drawn = value.Sample(generator)
    if isinstance(value, Transform):
        return Transform(drawn)
    if isinstance(value, _VECTOR_DISTRIBUTIONS):
        return [float(x) for x in np.asarray(drawn).ravel()]
    return float(drawn)


def DrawErrors(config: Any, random_seed: int | None, prefix: str = "") -> Any:
    """A copy of the error-model tree `config` (dataclasses and dicts of them) with every
    value drawn (DrawValue); the leaf at dotted name `prefix.field` draws from
    SourceGenerator(random_seed, that name). random_seed None refuses distributions,
    naming the field."""
    if isinstance(config, dict):
        return {k: DrawErrors(v, random_seed, _Join(prefix, k)) for k, v in config.items()}
    if dataclasses.is_dataclass(config):
        changes = {
            f.name: DrawErrors(getattr(config, f.name), random_seed, _Join(prefix, f.name))
            for f in dataclasses.fields(config)
        }
        return dataclasses.replace(config, **changes)
    if isinstance(config, list) and config and isinstance(config[0], Transform):
        return [DrawErrors(x, random_seed, f"{prefix}[{i}]") for i, x in enumerate(config)]
    if IsDrawn(config):
        return DrawValue(config, None)
    if random_seed is None:
        raise ConfigurationError(
            f"{prefix} is a distribution: draw it with the run's random_seed first "
            "(a task run does; MakeStation builds one drawn cell)"
        )
    try:
        return DrawValue(config, SourceGenerator(random_seed, prefix))
    except Exception as e:  # Drake refuses some distributions (e.g. Gaussian Rpy angles)
        why = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        why = why.split(" condition ", 1)[-1] if why.startswith("Failure at") else why
        raise ConfigurationError(f"{prefix}: Drake cannot draw this distribution ({why})") from None


def ErrorsAsData(config: Any) -> Any:
    """A drawn error-model tree as plain data for summary.json: dicts, floats and lists; a
    Transform as {translation (m), rpy_deg}; fields at their default left out (a value
    still a distribution stays as it is)."""
    if not IsDrawn(config):
        return config
    if isinstance(config, dict):
        return {k: ErrorsAsData(v) for k, v in config.items()}
    if dataclasses.is_dataclass(config):
        default = type(config)()
        data = {}
        for f in dataclasses.fields(config):
            value = getattr(config, f.name)
            if not _SameValue(value, getattr(default, f.name)):
                data[f.name] = ErrorsAsData(value)
        return data
    if isinstance(config, list):
        return [ErrorsAsData(x) for x in config]
    if isinstance(config, Transform):
        X = config.GetDeterministicValue()
        return {
            "translation": [float(x) for x in X.translation()],
            "rpy_deg": [float(np.degrees(a)) for a in X.rotation().ToRollPitchYaw().vector()],
        }
    return float(config) if isinstance(config, int | float) else config


def IsZeroError(config: Any) -> bool:
    """Whether a drawn error-model tree changes nothing: every field at its default."""
    return ErrorsAsData(config) in ({}, None)


def PoseError(value: Transform):
    """The RigidTransform of a drawn pose error."""
    return value.GetDeterministicValue()


def _SameValue(value: Any, default: Any) -> bool:
    if isinstance(value, Transform) and isinstance(default, Transform):
        if not (value.IsDeterministic() and default.IsDeterministic()):
            return False
        return value.GetDeterministicValue().IsExactlyEqualTo(default.GetDeterministicValue())
    if dataclasses.is_dataclass(value) or isinstance(value, dict):
        return ErrorsAsData(value) == ErrorsAsData(default)
    if not IsDrawn(value):
        return False
    try:
        return bool(np.array_equal(np.asarray(value, float), np.asarray(default, float)))
    except (TypeError, ValueError):
        return value == default


def _Join(prefix: str, name: str) -> str:
    return f"{prefix}.{name}" if prefix else str(name)
