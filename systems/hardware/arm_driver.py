"""ArmDriver: the hardware counterpart of a simulated arm's ports, on any ArmLink.

Every `period` seconds it takes the link's latest measured sample and streams the commanded
joint positions, with these safety rules:
- a link reporting a fault (refused command, lost connection) stops the arm and fails the
  run with the link's reason;
- a sample older than `watchdog` (host seconds) means the link is lost: the arm is stopped
  and the run fails;
- a sample older than `stale_after` is not acted on: no command is sent from it;
- a sample that cannot be the arm's (ImplausibleMeasurement: not finite, beyond the joint
  range, faster than the joint can move) stops the arm and fails the run;
- every command passes CheckCommand (position, velocity, acceleration limits) before it is
  sent; a refused command stops the arm and fails the run.
Every failure is a HardwareFaultError naming the link, the fault and the diagram time; the
errors of the stop itself (a dead link cannot confirm it) are recorded beside the cause.
"""

from __future__ import annotations

import time
from typing import NoReturn

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from guidedarm.systems.config_checks import POSITIVE, CheckArgument
from guidedarm.systems.errors import ConfigurationError, HardwareFaultError
from guidedarm.systems.hardware.arm_link import ArmLink, DescribeError, JointSample, StopArm
from guidedarm.systems.hardware.command_guard import (
    CheckCommand,
    CommandRefusedError,
    ImplausibleMeasurement,
    JointLimits,
)


def SampleAge(sample: JointSample | None, now: float) -> float:
    """Seconds since `sample` was received (infinite if nothing arrived yet)."""
    return np.inf if sample is None else now - sample.host_time


class ArmDriver(LeafSystem):
    """Input `position_commanded` (rad); outputs `position_measured` (rad),
    `velocity_estimated` (rad/s), `state_estimated` ([q; v]). Joint order = the model's."""

    def __init__(
        self,
        link: ArmLink,
        limits: JointLimits,
        period: float,
        watchdog: float,
        stale_after: float,
    ) -> None:
        super().__init__()
        for name, value in (
            ("period", period),
            ("watchdog", watchdog),
            ("stale_after", stale_after),
        ):
            CheckArgument(name, value, POSITIVE)
        self._link = link
        self._limits = limits
        self._period = period
        self._watchdog = watchdog
        self._stale_after = stale_after
        self.stale_skips = 0
        self._stale_streak = 0  # periods skipped since the last command sent
        self._last_streak = (0, -np.inf)  # the last streak of 2+ periods, when it ended (s)
        n = limits.lower.size
        self._n = n
        # State: measured q, v; the last sent command q, its implied v, when it was sent
        # (context time) and the interval before it, so that skipped periods do not inflate
        # the implied velocity and acceleration. Its default is the arm as measured now:
        # systems that read the measurement in their own initialization event (the
        # waypoints planner starts where the arm is) see the state before this driver's
        # initialization event has run, which would otherwise be zeros.
        sample, problem = self._FirstSample()
        if problem is not None:
            raise ConfigurationError(f"{link.name}: connected, but {problem}")
        self._state = self.DeclareDiscreteState(_InitialState(sample, -period, period))
        self.DeclareVectorInputPort("position_commanded", n)
        self.DeclareVectorOutputPort("position_measured", n, self._CalcSlice(0, n))
        self.DeclareVectorOutputPort("velocity_estimated", n, self._CalcSlice(n, 2 * n))
        self.DeclareVectorOutputPort("state_estimated", 2 * n, self._CalcSlice(0, 2 * n))
        self.DeclareInitializationDiscreteUpdateEvent(self._Initialize)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._Update)

    def _CalcSlice(self, start: int, stop: int):
        def calc(context: Context, output: BasicVector) -> None:
            output.SetFromVector(context.get_discrete_state(self._state).value()[start:stop])

        return calc

    def _FirstSample(self) -> tuple[JointSample | None, str | None]:
        """The link's latest sample, waiting at most the watchdog for one, and why it
        cannot be used (None when it can): none came, the link reported a fault, or it
        cannot be the arm's."""
        deadline = time.monotonic() + self._watchdog
        sample = self._link.latest()
        while sample is None and time.monotonic() < deadline and not self._link.fault():
            time.sleep(0.001)
            sample = self._link.latest()
        if sample is None:
            return None, (
                self._link.fault() or f"no measurement within the watchdog {self._watchdog} s"
            )
        return sample, ImplausibleMeasurement(self._limits, sample.q, sample.v)

    def _Initialize(self, context: Context, state: DiscreteValues) -> None:
        sample, problem = self._FirstSample()
        if problem is not None:
            self._Fail(context, problem)
        # as if the current position had been sent one period ago
        t = context.get_time() - self._period
        state.set_value(self._state, _InitialState(sample, t, self._period))

    def _Update(self, context: Context, state: DiscreteValues) -> None:
        n = self._n
        x = context.get_discrete_state(self._state).value().copy()
        fault = self._link.fault()
        if fault is not None:
            self._Fail(context, fault + self._StaleStreakHint(context.get_time()))
        sample = self._link.latest()
        age = SampleAge(sample, time.monotonic())
        if age > self._watchdog:
            self._Fail(context, f"link quiet for {age:.3f} s (watchdog {self._watchdog} s)")
        implausible = ImplausibleMeasurement(self._limits, sample.q, sample.v)
        if implausible:
            self._Fail(context, implausible)
        x[: 2 * n] = np.concatenate([sample.q, sample.v])
        if age > self._stale_after:
            self.stale_skips += 1
            self._stale_streak += 1
        else:
            # the fault of a refused stream arrives with the reply to a target after the
            # streak, a period or more later: remember the streak and when it ended
            if self._stale_streak >= 2:
                self._last_streak = (self._stale_streak, context.get_time())
            self._stale_streak = 0
            q_command = self.get_input_port().Eval(context)
            t_sent, dt_sent = x[-2:]
            dt = context.get_time() - t_sent
            try:
                v = CheckCommand(
                    self._limits, q_command, x[2 * n : 3 * n], x[3 * n : 4 * n], dt, dt_sent
                )
            except CommandRefusedError as e:
                self._Fail(context, str(e))
            try:
                self._link.send_position(q_command, dt)
            except Exception as e:  # a vendor or socket error: the arm must still be stopped
                self._Fail(context, f"command not sent: {DescribeError(e)}")
            x[2 * n :] = np.concatenate([q_command, v, [context.get_time(), dt]])
        state.set_value(self._state, x)

    def _StaleStreakHint(self, t: float) -> str:
        """What to change when the link faults after the driver sent nothing for several
        periods because every measurement was stale (now, or a streak that ended within
        the watchdog before `t`, s): a controller that stops the arm when the stream
        pauses (a Nachi SERVO or UR servoJ timeout) refuses the next target."""
        streak, ended = self._last_streak
        if self._stale_streak >= 2:
            streak = self._stale_streak
        elif t - ended > self._watchdog:
            return ""
        return (
            f" (no command sent for {streak} periods, "
            f"{streak * self._period:.3f} s: every measurement was older than "
            f"stale_after {self._stale_after} s; raise station.hardware.arms.{self._link.name}"
            f".stale_after, at most the watchdog {self._watchdog} s, or the controller's "
            "streaming timeout)"
        )

    def _Fail(self, context: Context, what: str) -> NoReturn:
        """Stops the arm and raises the fault with the stop's error beside it."""
        stop_error = StopArm(self._link)
        stop_errors = [stop_error] if stop_error else []
        what = what if stop_errors else f"{what}; arm stopped"
        raise HardwareFaultError(self._link.name, what, context.get_time(), stop_errors)


def _InitialState(sample: JointSample, t_sent: float, period: float) -> np.ndarray:
    """The driver's state for an arm at rest where `sample` measured it: measured q, v;
    q sent at context time `t_sent` (s) with zero velocity, `period` (s) after the one
    before."""
    zeros = np.zeros_like(sample.q)
    return np.concatenate([sample.q, sample.v, sample.q, zeros, [t_sent, period]])
