"""The streaming (servo) mode of an emulated arm controller: a joint setpoint that tracks a
stream of targets within joint velocity and acceleration limits, as a real controller's
servo mode interpolates the targets a PC streams to it.

Each target q_k comes with its interval t_k (s, the time the PC means between q_{k-1} and
q_k). The reference moves linearly from where it is to q_k over t_k and then holds, so a
late target makes the reference wait rather than jump. The setpoint (q, v) follows the
reference every servo tick dt with

    v_des = v_ref + sign(e) min(gain |e|, sqrt(2 a_max |e|)),   e = r - q,

the square-root branch being the speed from which the joint can still brake onto the
reference; v_des is clipped to the velocity limit, and v moves towards it by at most
a_max dt. So |v| <= v_max and |dv/dt| <= a_max hold at every tick, whatever arrives.
`Brake` replaces the reference by standstill: the joints decelerate at a_max and hold,
within max|v| / a_max seconds.
"""

from __future__ import annotations

import numpy as np

from guidedarm.systems.hardware.lockstep_clock import SAME_INSTANT

DEFAULT_GAIN = 50.0  # 1/s; position error to velocity correction


class ServoTracker:
    """Setpoint q (rad), v (rad/s) of an arm's joints; `velocity`, `acceleration`: per-joint
    limits (rad/s, rad/s^2)."""

    def __init__(
        self,
        q0: np.ndarray,
        velocity: np.ndarray,
        acceleration: np.ndarray,
        time: float,
        gain: float = DEFAULT_GAIN,
    ) -> None:
        self.q = np.array(q0, float)
        self.v = np.zeros_like(self.q)
        self.velocity = np.asarray(velocity, float)
        self.acceleration = np.asarray(acceleration, float)
        self.gain = gain
        self.braking = False
        self.time = time
        # Reference: r(t) = start + rate (min(t, end) - t0).
        self._start, self._rate = self.q.copy(), np.zeros_like(self.q)
        self._t0 = self._end = time
        self.target = self.q.copy()  # the latest target (the reference's end)

    def Reference(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The reference position and velocity at time t (s); at its end, the velocity of
        the ramp that ends there (a tick ending where a target's interval ends, as every
        tick in lockstep, still moves with it, whatever the rounding)."""
        moving = t < self._end + SAME_INSTANT
        r = self._start + self._rate * (min(t, self._end) - self._t0)
        return r, (self._rate if moving else np.zeros_like(self._rate))

    def SetTarget(self, q: np.ndarray, interval: float, t: float) -> None:
        """The reference goes from where it is at t to q (rad) over `interval` (s)."""
        r, _ = self.Reference(t)
        self._start, self._rate = r, (np.asarray(q, float) - r) / interval
        self._t0, self._end = t, t + interval
        self.target = np.array(q, float)

    def Brake(self) -> None:
        """From now on the setpoint decelerates to standstill at the acceleration limit."""
        self.braking = True

    def Standstill(self) -> bool:
        return not np.any(self.v)

    def Step(self, t: float) -> np.ndarray:
        """Advances the setpoint to time t (s); returns q."""
        dt = t - self.time
        if dt <= 0.0:
            return self.q.copy()
        self.time = t
        if self.braking:
            v_desired = np.zeros_like(self.v)
        else:
            r, v_ref = self.Reference(t)
            e = r - self.q
            braking_speed = np.sqrt(2.0 * self.acceleration * np.abs(e))
            correction = np.minimum(self.gain * np.abs(e), braking_speed)
            v_desired = np.clip(v_ref + np.sign(e) * correction, -self.velocity, self.velocity)
        step = self.acceleration * dt
        v = self.v + np.clip(v_desired - self.v, -step, step)
        self.q = self.q + 0.5 * (self.v + v) * dt
        self.v = v
        return self.q.copy()
