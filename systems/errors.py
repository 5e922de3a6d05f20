"""Errors that guidedarm reports to the user as one line, naming the cause."""


class GuidedArmError(RuntimeError):
    """Base of every expected failure (bad input, unreachable target, lost sensor, ...)."""


class ConfigurationError(GuidedArmError, ValueError):
    """A parameter, scenario key or model is invalid; raised before any motion."""
