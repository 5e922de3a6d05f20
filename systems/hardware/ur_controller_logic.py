"""An emulated UR e-Series controller's bookkeeping, without a simulation: RTDE registers,
the program state, the register protocol of ur_rtde's control script, its servo loop and
its RTDE watchdog, and the dashboard server's replies.

ur_rtde's RTDEControlInterface uploads a URScript program (`def rtde_control(): ... end`)
to the script port and then talks to it through RTDE registers only: it writes a command
number to input_int_register_0 and its arguments to input_double_register_0.. , and the
program answers on output_int_register_0 (1: ready for a command, 2: done with it). The
emulator does not interpret URScript: it recognises that program and runs its register
protocol (`Cycle`, once per controller step), with the commands a servo stream needs:

| command | number | emulated |
|---|---|---|
| servoJ(q, _, _, time, ...) | 11 | q tracked over `time` s within the limits (ServoTracker) |
| servoStop(a) | 16 | the arm brakes to standstill |
| stopJ(a, async) | 34 | the arm brakes; done at standstill (at once if async) |
| setWatchdog(f) | 35 | the program stops when input_int_register_0 is not written for 1/f s |
| kickWatchdog | 0 (NO_CMD) | writes input_int_register_0 |
| stopScript | 255 | the program ends |

Other commands are answered `done` without effect and counted in `unsupported`. When the
program is not running (never started, ended, stopped from the dashboard or by the
watchdog), the arm brakes and the client refuses further commands itself.
"""

from __future__ import annotations

import collections
import threading

import numpy as np

from guidedarm.systems.hardware.servo_tracker import ServoTracker

CONTROLLER_VERSION = (5, 15, 0, 0)  # major, minor, bugfix, build (RTDE)
POLYSCOPE_VERSION = "URSoftware 5.15.0.0 (emulated)"
SERIAL_NUMBER = "20000000000"
CONTROL_SCRIPT_HEADER = "def rtde_control():"

READY, DONE = 1, 2  # output_int_register_0
NO_CMD, SERVOJ, SERVO_STOP, STOPJ, SET_WATCHDOG, STOP_SCRIPT = 0, 11, 16, 34, 35, 255
REALTIME_COMMANDS = {6, 9, 10, 11, 24, 25, 26, 27, 38, 58}  # answered `ready` at once
# lockstep only: the number of servoJ targets the emulator has run (mod 2^31), which the
# link waits for; a register ur_rtde leaves to the user (its receive interface reads 12-19).
LOCKSTEP_COUNT_REGISTER = "output_int_register_18"
STOPPED, PLAYING = 1, 2  # runtime_state
POWER_ON, PROGRAM_RUNNING = 1 << 0, 1 << 1  # robot_status_bits
NORMAL_MODE = 1 << 0  # safety_status_bits
ROBOT_MODE_RUNNING, SAFETY_MODE_NORMAL = 7, 1


class UrControllerLogic:
    """Joint limits lower, upper (rad), velocity (rad/s), acceleration (rad/s^2) per joint;
    q0 (rad): where the arm stands. `lock` guards everything; the RTDE sessions write
    inputs, the stepping thread calls Step."""

    def __init__(
        self,
        lower: np.ndarray,
        upper: np.ndarray,
        q0: np.ndarray,
        velocity: np.ndarray,
        acceleration: np.ndarray,
        lockstep: bool = False,
    ) -> None:
        self.lock = threading.RLock()
        self.lockstep = lockstep
        # lockstep: every servoJ package received, in order, (q, interval): the emulator
        # advances the arm by each target's interval instead of sampling the registers.
        self.targets: collections.deque[tuple[np.ndarray, float]] = collections.deque()
        self.target_arrived = threading.Event()
        self.lower, self.upper = np.asarray(lower, float), np.asarray(upper, float)
        self.velocity = np.asarray(velocity, float)
        self.acceleration = np.asarray(acceleration, float)
        self.time = 0.0
        self.measured = np.array(q0, float)
        self.measured_velocity = np.zeros_like(self.measured)
        self.commanded = self.measured.copy()
        self.tracker: ServoTracker | None = None
        self.inputs: dict[str, float] = {}
        self.outputs = {"output_int_register_0": 0}
        self.running = False
        self.executing = False
        self.watchdog_period = np.inf  # s; 1 / the client's setWatchdog frequency
        self.last_kick = 0.0  # controller time input_int_register_0 was last written
        self.stop_reason = ""
        self.servo_targets = 0
        self.servo_packages = 0  # servoJ data packages received
        self.unsupported = 0
        self.waiting_standstill = False

    # --- what the clients send ---------------------------------------------------------

    def WriteInputs(self, values: dict[str, float]) -> None:
        """An input DATA_PACKAGE: register name -> value."""
        with self.lock:
            self.inputs.update(values)
            if "input_int_register_0" in values:
                self.last_kick = self.time
                if values["input_int_register_0"] == SERVOJ:
                    self.servo_packages += 1
                if self.lockstep and values["input_int_register_0"] == SERVOJ:
                    self.targets.append((self._RegisterTarget(), self._RegisterInterval()))
            # lockstep: any input wakes the stepping thread (a servoStop must be run too)
            self.target_arrived.set()

    def StartProgram(self, text: str) -> str:
        """A program received on the script port; returns what the controller did."""
        with self.lock:
            if not text.lstrip().startswith(CONTROL_SCRIPT_HEADER):
                first = text.strip().splitlines()[0][:60] if text.strip() else ""
                return f"program refused (only ur_rtde's control script is emulated): {first!r}"
            self.running, self.executing = True, False
            self.watchdog_period, self.last_kick = np.inf, self.time
            self.outputs["output_int_register_0"] = READY
            self.stop_reason = ""
            return "rtde_control started"

    def StopProgram(self, reason: str) -> None:
        """Ends the program (dashboard `stop`, the watchdog, stopScript): the arm brakes."""
        with self.lock:
            if self.running:
                self.running, self.stop_reason = False, reason
            self.outputs["output_int_register_0"] = 0
            self._Brake()

    def Dashboard(self, line: str) -> str:
        """The dashboard server's reply to one request line."""
        request = line.strip()
        with self.lock:
            running = self.running
        replies = {
            "PolyscopeVersion": POLYSCOPE_VERSION,
            "get serial number": SERIAL_NUMBER,
            "is in remote control": "true",
            "robotmode": "Robotmode: RUNNING",
            "safetystatus": "Safetystatus: NORMAL",
            "running": f"Program running: {str(running).lower()}",
            "programState": "PLAYING rtde_control" if running else "STOPPED <unnamed>",
        }
        if request == "stop":
            self.StopProgram("stopped from the dashboard server")
            return "Stopped"
        return replies.get(request, f"could not understand: '{request}'")

    # --- the controller cycle ----------------------------------------------------------

    def Step(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Records the arm's joints at controller time t (s), runs one cycle of the
        program and the servo loop; returns the joint command for the next step."""
        with self.lock:
            self.time, self.measured, self.measured_velocity = t, np.array(q), np.array(v)
            if self.running and t - self.last_kick > self.watchdog_period:
                self.StopProgram(
                    f"RTDE watchdog: input_int_register_0 not written for "
                    f"{t - self.last_kick:.3f} s (minimum {1 / self.watchdog_period:g} Hz)"
                )
            if self.running:
                self._Cycle()
            if self.tracker is not None:
                self.commanded = self.tracker.Step(t)
                if self.tracker.braking and self.tracker.Standstill():
                    self.tracker = None
            if self.waiting_standstill and self.tracker is None:
                self.waiting_standstill = False
                self.outputs["output_int_register_0"] = DONE
            return self.commanded.copy()

    def _Cycle(self) -> None:
        """One pass of the control script's main loop."""
        cmd = int(self.inputs.get("input_int_register_0", NO_CMD))
        if cmd in REALTIME_COMMANDS:
            if cmd == SERVOJ and not self.lockstep:
                # The script reads the registers at every cycle: a target that another
                # command overwrote before this cycle is never seen, as on the controller.
                q = self._RegisterTarget()
                if self.tracker is None or np.any(self.tracker.target != q):
                    self.Servo(q, self._RegisterInterval())
            elif cmd != SERVOJ:
                self.unsupported += 1
            self.outputs["output_int_register_0"] = READY
        elif cmd == NO_CMD:
            self.executing = False
            if not self.waiting_standstill:
                self.outputs["output_int_register_0"] = READY
        elif not self.executing:
            self.executing = True
            self._Process(cmd)

    def _Process(self, cmd: int) -> None:
        """A command that the client waits for (`done`)."""
        argument = self.inputs.get("input_double_register_0", 0.0)
        done = True
        if cmd == SERVO_STOP:
            self._Brake()
        elif cmd == STOPJ:
            self._Brake()
            done = self.tracker is None or self.inputs.get("input_int_register_1", 0) == 1
            self.waiting_standstill = not done
        elif cmd == SET_WATCHDOG:
            self.watchdog_period = 1.0 / argument if argument > 0 else np.inf
            self.last_kick = self.time
        elif cmd == STOP_SCRIPT:
            self.StopProgram("stopScript from the client")
            return
        else:
            self.unsupported += 1
        if done:
            self.outputs["output_int_register_0"] = DONE

    def _RegisterTarget(self) -> np.ndarray:
        return np.array([self.inputs.get(f"input_double_register_{i}", 0.0) for i in range(6)])

    def _RegisterInterval(self) -> float:
        return float(self.inputs.get("input_double_register_8", 0.002))

    def Servo(self, q: np.ndarray, interval: float) -> None:
        """A servoJ target: tracked within the limits (a target beyond the position range
        is clipped to it, as a controller that protective-stops is not emulated); ignored
        once the program has stopped."""
        if self.lockstep:
            count = self.outputs.get(LOCKSTEP_COUNT_REGISTER, 0)
            self.outputs[LOCKSTEP_COUNT_REGISTER] = (count + 1) % 2**31
        if not self.running:
            return
        q = np.clip(q, self.lower, self.upper)
        if self.tracker is None or self.tracker.braking:
            self.tracker = ServoTracker(self.commanded, self.velocity, self.acceleration, self.time)
        self.tracker.SetTarget(q, max(float(interval), 1e-4), self.time)
        self.servo_targets += 1

    def _Brake(self) -> None:
        if self.tracker is not None:
            self.tracker.Brake()
        else:
            self.commanded = self.measured.copy()

    # --- what the controller publishes -------------------------------------------------

    def Output(self, name: str):
        """The value of an RTDE output variable now."""
        with self.lock:
            running = self.running
            values = {
                "timestamp": self.time,
                "actual_q": list(self.measured),
                "actual_qd": list(self.measured_velocity),
                "target_q": list(self.commanded),
                "target_qd": [0.0] * len(self.measured),
                "runtime_state": PLAYING if running else STOPPED,
                "robot_status_bits": POWER_ON | (PROGRAM_RUNNING if running else 0),
                "safety_status_bits": NORMAL_MODE,
                "robot_mode": ROBOT_MODE_RUNNING,
                "safety_mode": SAFETY_MODE_NORMAL,
            }
            if name in values:
                return values[name]
            return self.outputs.get(name, 0)
