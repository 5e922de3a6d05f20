"""Errors that guidedarm reports to the user as one line, naming the cause."""


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
