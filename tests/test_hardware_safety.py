"""Safety rules of ArmDriver and CheckCommand: limits from the MZ04D model, staleness."""

from __future__ import annotations

import re
import time

import numpy as np
import pytest
from hardware_doubles import FreezingNachiController, ScriptedArmLink, WaitUntil
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, EventStatus
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from guidedarm.diagrams.station.model_paths import MakeParser
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.diagrams.tasks.waypoints import MakePlannerSetup
from guidedarm.systems.errors import ConfigurationError, HardwareFaultError
from guidedarm.systems.hardware.arm_driver import ArmDriver
from guidedarm.systems.hardware.command_guard import (
    CheckCommand,
    CommandRefusedError,
    ImplausibleMeasurement,
    JointLimits,
)
from guidedarm.systems.hardware.nachi_link import NachiLink

DT = 0.002
ACCELERATION = [20.0, 20.0, 25.0, 30.0, 30.0, 40.0]


@pytest.fixture(scope="module")
def limits() -> JointLimits:
    plant = MultibodyPlant(0.0)
    (instance,) = MakeParser(plant).AddModelsFromUrl("package://guidedarm/mz04d/mz04d.urdf")
    plant.Finalize()
    return JointLimits.FromPlant(plant, instance, ACCELERATION)


def test_limits_come_from_the_model(limits):
    assert limits.names == [f"joint{i}" for i in range(1, 7)]
    np.testing.assert_allclose(limits.upper[:2], np.deg2rad([170.0, 180.0]))
    np.testing.assert_allclose(limits.velocity[0], np.deg2rad(450.0))
    np.testing.assert_allclose(limits.acceleration, ACCELERATION)


def test_missing_acceleration_limits_are_a_configuration_error():
    plant = MultibodyPlant(0.0)
    (instance,) = MakeParser(plant).AddModelsFromUrl("package://guidedarm/mz04d/mz04d.urdf")
    plant.Finalize()
    with pytest.raises(ConfigurationError, match="no finite acceleration limit"):
        JointLimits.FromPlant(plant, instance)


@pytest.mark.parametrize(
    "joint, q_step, v_previous, kind",
    [
        (1, 3.2, 0.0, "position"),  # beyond joint2's upper limit pi
        (0, 0.0158, 7.9, "velocity"),  # 7.9 rad/s > 7.854 rad/s on joint1
        (2, 0.0004, 0.0, "acceleration"),  # 0.2 rad/s in one period: 100 rad/s^2 > 25
    ],
)
def test_each_limit_refuses_the_command(limits, joint, q_step, v_previous, kind):
    q_previous = np.zeros(6)
    v = np.zeros(6)
    v[joint] = v_previous
    q = q_previous.copy()
    q[joint] = q_step
    with pytest.raises(CommandRefusedError, match=f"joint{joint + 1} {kind}"):
        CheckCommand(limits, q, q_previous, v, DT)


def test_command_at_the_limits_passes_and_returns_its_velocity(limits):
    q_previous = np.zeros(6)
    v_previous = np.full(6, 1.0)
    q = q_previous + DT * (v_previous + 0.99 * DT * limits.acceleration)
    v = CheckCommand(limits, q, q_previous, v_previous, DT)
    np.testing.assert_allclose(v, v_previous + 0.99 * DT * limits.acceleration)


def test_nan_command_is_refused(limits):
    q = np.zeros(6)
    q[3] = np.nan
    with pytest.raises(CommandRefusedError, match="finite"):
        CheckCommand(limits, q, np.zeros(6), np.zeros(6), DT)


@pytest.mark.parametrize(
    "q_offset, v, message",
    [
        (
            [3.2, 0, 0, 0, 0, 0],
            0.0,
            r"joint joint1 at 3\.2 rad, outside its range \[-2\.967, 2\.967\]",
        ),
        ([2.98, 0, 0, 0, 0, 0], 0.0, None),  # 0.013 rad past the limit: an encoder's reading
        ([0, 0, 0, 0, 0, 0], 1.51 * np.deg2rad(450), r"joint joint1 moving at 11\.86 rad/s"),
        ([0, 0, 0, 0, 0, 0], 1.49 * np.deg2rad(450), None),
        ([0, 0, np.nan, 0, 0, 0], 0.0, "measurement not finite"),
        ([0, 0, 0, 0, 0], 0.0, "measurement has 5 joint positions and 6 velocities, the arm 6"),
    ],
)
def test_a_measurement_the_arm_cannot_produce_is_named(limits, q_offset, v, message):
    q = np.asarray(q_offset, float)
    velocities = np.zeros(6)
    velocities[0] = v
    problem = ImplausibleMeasurement(limits, q, velocities)
    if message is None:
        assert problem is None
    else:
        assert re.search(message, problem), problem


@pytest.mark.parametrize(
    "offset, message",
    [
        # joint4 reads 20 deg away from one sample to the next (+-10 deg, flipping at every
        # reading; a single jump between two of the driver's samples goes unseen): 35-70
        # rad/s over the 5-10 ms
        (
            [0, 0, 0, 0.175, 0, 0],
            r"measured joint joint4 moving at -?\d+(\.\d+)? rad/s, beyond 1\.5 x its limit 9\.599",
        ),
        ([-3.0, 0, 0, 0, 0, 0], r"measured joint joint1 at -3 rad, outside its range"),
    ],
)
def test_a_corrupted_measurement_stops_the_arm_before_another_command(offset, message):
    """The controller's reply is corrupted (a jump, a joint beyond its range) while the
    driver streams over a real socket: STOP is the next request after the bad reply, the
    run fails naming the joint. The controller's clock advances 5 ms per request (a target
    and a reading per 10 ms poll), so the jump's speed is the same whatever the load."""
    q0 = np.array([0.0, np.pi / 2, 0.0, 0.0, -np.pi / 2, 0.0])
    controller = FreezingNachiController(q0, clock_step=0.005)
    link = NachiLink("mz04d", "127.0.0.1", controller.port, poll_period=0.01)
    plant = MultibodyPlant(0.0)
    (instance,) = MakeParser(plant).AddModelsFromUrl("package://guidedarm/mz04d/mz04d.urdf")
    plant.Finalize()
    driver = ArmDriver(link, JointLimits.FromPlant(plant, instance, ACCELERATION), 0.01, 0.5, 0.05)
    simulator = Simulator(driver)
    driver.get_input_port().FixValue(simulator.get_mutable_context(), q0)
    simulator.set_target_realtime_rate(1.0)
    try:
        simulator.AdvanceTo(0.2)
        assert controller.logic.moves >= 1  # streaming
        controller.measurement_offset = np.array(offset)
        controller.flip_offset = offset[3] != 0
        with pytest.raises(
            HardwareFaultError, match=r"on mz04d at t = 0\.\d+ s: " + message
        ) as fault:
            simulator.AdvanceTo(1.0)
        assert controller.logic.stopped
        # Caught by its plausibility, before the 0.5 s watchdog could have.
        assert fault.value.t < 0.2 + 0.5, fault.value
    finally:
        link.close()
        controller.close()


def _Simulate(link, limits, command, t_final, watchdog=0.1):
    driver = ArmDriver(link, limits, period=DT, watchdog=watchdog, stale_after=0.02)
    simulator = Simulator(driver)
    port = driver.get_input_port()
    port.FixValue(simulator.get_mutable_context(), command)
    simulator.Initialize()
    simulator.AdvanceTo(t_final)
    return driver


def test_refused_command_is_never_sent_and_stops_the_robot(limits):
    link = ScriptedArmLink(np.zeros(6))
    command = np.zeros(6)
    command[1] = 0.1  # 50 rad/s implied on joint2 in the first period
    with pytest.raises(
        HardwareFaultError, match=r"on scripted at t = 0.000 s: .*joint2 velocity .* arm stopped$"
    ):
        _Simulate(link, limits, command, 0.01)
    assert link.sent == []
    assert link.stops == 1


def test_stale_measurements_command_no_motion(limits):
    link = ScriptedArmLink(np.zeros(6))
    link.age = 0.05  # older than stale_after (0.02 s), younger than the watchdog (0.1 s)
    driver = _Simulate(link, limits, np.zeros(6), 0.1)
    assert link.sent == []
    assert driver.stale_skips == 50  # events at t = 0, 2, ..., 98 ms
    link.age = 0.0
    _Simulate(link, limits, np.zeros(6), 0.1)
    assert len(link.sent) == 50


def test_quiet_link_fails_with_the_watchdog_message(limits):
    link = ScriptedArmLink(np.zeros(6))
    link.age = 0.2
    with pytest.raises(
        HardwareFaultError, match=r"scripted at t = 0.000 s: link quiet for 0.2\d* s"
    ):
        _Simulate(link, limits, np.zeros(6), 0.1)
    assert link.stops == 1 and link.sent == []


def test_skipped_periods_do_not_inflate_the_implied_velocity(limits):
    # joint1 accelerates at 10 rad/s^2 (limit 20); measurements go stale for 10 ms in the
    # middle. The first command after the gap spans 12 ms: implied 0.54 rad/s, not 3.24.
    link = ScriptedArmLink(np.zeros(6))
    t = np.arange(0.0, 0.2, DT)
    ramp = PiecewisePolynomial.FirstOrderHold(t, np.outer([1, 0, 0, 0, 0, 0], 5.0 * t**2))
    builder = DiagramBuilder()
    source = builder.AddSystem(TrajectorySource(ramp))
    driver = builder.AddSystem(ArmDriver(link, limits, DT, watchdog=0.1, stale_after=0.02))
    builder.Connect(source.get_output_port(), driver.get_input_port())
    simulator = Simulator(builder.Build())

    def monitor(context) -> EventStatus:
        link.age = 0.05 if 0.050 <= context.get_time() < 0.060 else 0.0
        return EventStatus.DidNothing()

    simulator.set_monitor(monitor)
    simulator.AdvanceTo(0.1)
    sent = np.array(link.sent)[:, 0]
    assert driver.stale_skips == 5
    assert len(sent) == 50 - 5
    assert np.max(np.diff(sent)) == pytest.approx(5.0 * (0.060**2 - 0.048**2))


def test_a_planner_initialized_from_the_driver_starts_where_the_arm_is():
    """The waypoints planner reads `state_estimated` in its initialization event, in the
    same pass as the driver's: it must see the arm as measured (the UR10e at the paper's
    q(0), served over a real socket), not the driver's unset state. With zeros it
    commanded shoulder_pan 1.57 rad away, refused at t = 0 (157 rad/s)."""
    _, scenario, _ = LoadScenario("ur10e_waypoints", [])
    setup = MakePlannerSetup(scenario)
    q0 = np.asarray(scenario.station.arms["ur10e"].initial_position)
    controller = FreezingNachiController(q0)
    link = NachiLink("ur10e", "127.0.0.1", controller.port, poll_period=0.01)
    try:
        builder = DiagramBuilder()
        limits = JointLimits.FromPlant(setup.plant, setup.planning.kinematics.instance, [5.0] * 6)
        driver = builder.AddSystem(ArmDriver(link, limits, 0.01, watchdog=0.5, stale_after=0.05))
        planner = builder.AddSystem(setup.planner)
        builder.Connect(driver.GetOutputPort("state_estimated"), planner.get_input_port())
        builder.Connect(planner.GetOutputPort("position_commanded"), driver.get_input_port())
        simulator = Simulator(builder.Build())
        simulator.set_target_realtime_rate(1.0)
        simulator.Initialize()
        commanded = planner.GetOutputPort("position_commanded").Eval(
            planner.GetMyContextFromRoot(simulator.get_context())
        )
        np.testing.assert_allclose(commanded, q0, atol=1e-6)  # the link's 1e-6 deg format
        # The commands pass the guard (a refusal would fail the run) and reach the
        # controller (up to ten; fewer when the load makes samples stale).
        simulator.AdvanceTo(0.1)
        assert WaitUntil(lambda: controller.logic.moves >= 1)
    finally:
        link.close()
        controller.close()


def test_a_link_without_measurements_is_refused_when_the_station_is_built():
    """A controller that accepts RESET and answers nothing after it: the driver is not
    built (a ConfigurationError, the run refused before any motion) within its watchdog."""
    controller = FreezingNachiController(np.zeros(6), answers=1)
    link = NachiLink("mz04d", "127.0.0.1", controller.port, poll_period=0.01)
    try:
        start = time.monotonic()
        with pytest.raises(
            ConfigurationError,
            match=r"^mz04d: connected, but no measurement within the watchdog 0\.1 s$",
        ):
            ArmDriver(link, _Ur10eLimits(), 0.01, watchdog=0.1, stale_after=0.02)
        assert time.monotonic() - start < 0.3
        assert [line for _, line in controller.received_frozen][:1] == ["READ_JOINTS"]
    finally:
        link.close()
        controller.close()


def _Ur10eLimits() -> JointLimits:
    plant = MultibodyPlant(0.0)
    (instance,) = MakeParser(plant).AddModelsFromUrl("package://guidedarm/ur10e/ur10e.urdf")
    plant.Finalize()
    return JointLimits.FromPlant(plant, instance, [10.0] * 6)
