"""Errors that guidedarm reports to the user as one line, naming the cause."""

import re


class GuidedArmError(RuntimeError):
    """Base of every expected failure (bad input, unreachable target, lost sensor, ...)."""


class ConfigurationError(GuidedArmError, ValueError):
    """A parameter, scenario key or model is invalid; raised before any motion."""


class RunFailedError(GuidedArmError):
    """A run that started cannot go on (a lost sensor, a refused command, a planner that
    cannot continue). The run command catches it, writes summary.json with `failure` set to
    the message and exits 1; tasks may also report failures in their metrics."""


class HardwareFaultError(RunFailedError):
    """A device fault during a hardware run: the link, what happened and when.

    device: the link's name (e.g. `mz04d`, `tof`); what: the fault; t: the diagram time (s)
    at which it was detected, or None. `stop_errors` lists errors of stopping the robot
    after the fault, recorded beside the cause, never instead of it.
    """

    def __init__(
        self, device: str, what: str, t: float | None = None, stop_errors: list[str] | None = None
    ) -> None:
        self.device = device
        self.what = what
        self.t = t
        self.stop_errors = list(stop_errors or [])
        when = f" at t = {t:.3f} s" if t is not None else ""
        stops = f" (stopping it also failed: {'; '.join(self.stop_errors)})" if stop_errors else ""
        super().__init__(f"hardware fault on {device}{when}: {what}{stops}")


_DRAKE_FAILURE = re.compile(r"Failure at (?:.*/)?([^/:]+):(\d+) in (.*?\)): (.*)", re.DOTALL)


def DrakeCheckFailure(error: BaseException) -> str | None:
    """One line for a failed Drake check (pydrake raises it as a SystemExit whose code is
    "Failure at FILE:LINE in FUNCTION(): condition '...' failed."), naming the function and
    condition without the build path; None for any other exception."""
    code = getattr(error, "code", None) if isinstance(error, SystemExit) else None
    match = _DRAKE_FAILURE.match(code) if isinstance(code, str) else None
    if match is None:
        return None
    file, line, function, condition = match.groups()
    return f"a Drake check failed in {function} ({file}:{line}): {condition.strip()}"
