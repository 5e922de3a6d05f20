"""Byte transports of the ToF tool, each feeding a ToFLineCollector from its own thread:
pyserial (USB or classic-Bluetooth SPP serial ports) and bleak (BLE UART notifications)."""

from __future__ import annotations

import asyncio
import contextlib
import select
import threading

import serial

from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware.tof_protocol import ToFLineCollector

# Nordic UART Service TX characteristic: the tool notifies its lines on it.
BLE_UART_TX = "6e400003-b5a3-f393-e0a9-e50e24dcca9e"


class SerialTransport:
    """Reads `device` (e.g. /dev/ttyACM0, /dev/rfcomm0) at `baudrate` into `collector`, from
    its own thread as bytes arrive, and on demand (Drain)."""

    def __init__(self, collector: ToFLineCollector, device: str, baudrate: int) -> None:
        try:
            self._port = serial.Serial(device, baudrate, timeout=0.05)
        except serial.SerialException as e:
            raise ConfigurationError(f"tof: cannot open serial device {device!r}: {e}") from None
        self._collector = collector
        self._lock = threading.Lock()
        self._closing = threading.Event()
        self._thread = threading.Thread(target=self._Run, name="tof-serial", daemon=True)
        self._thread.start()

    def _Run(self) -> None:
        while not self._closing.is_set():
            try:
                ready, _, _ = select.select([self._port.fileno()], [], [], 0.05)
                if ready:
                    self._ReadArrived()
            except (serial.SerialException, OSError, ValueError):
                return  # device gone: the driver's watchdog reports it

    def _ReadArrived(self) -> None:
        """Feeds what has arrived, without waiting for more."""
        with self._lock:
            # Drain may have taken the bytes since select saw them: read only what is still
            # there, but read a disconnected device (ready, nothing waiting) so that it
            # raises. What has arrived and not read(n): that would wait for n bytes, and
            # every line of the chunk would get its late receive time (measured_at).
            if select.select([self._port.fileno()], [], [], 0.0)[0]:
                self._collector.Feed(self._port.read(max(1, self._port.in_waiting)))

    def Drain(self) -> None:
        """Feeds the collector every byte that has reached the host by now (without waiting):
        after it, the collector holds each line the tool wrote before the call, whatever the
        reading thread's scheduling."""
        # A device gone: the driver's watchdog reports it.
        with contextlib.suppress(serial.SerialException, OSError, ValueError):
            self._ReadArrived()

    def close(self) -> None:
        self._closing.set()
        self._thread.join(timeout=1.0)
        self._port.close()


class BleTransport:
    """Subscribes to the tool's BLE UART TX notifications at `address` (bleak, own event
    loop thread); each notification payload is fed to `collector` as it arrives."""

    def __init__(self, collector: ToFLineCollector, address: str) -> None:
        self._collector = collector
        self._address = address
        self._loop = asyncio.new_event_loop()
        self._done: asyncio.Future | None = None
        self._thread = threading.Thread(target=self._loop.run_forever, daemon=True)
        self._thread.start()
        connected = asyncio.run_coroutine_threadsafe(self._Connect(), self._loop)
        try:
            connected.result(timeout=20.0)
        except Exception as e:
            raise ConfigurationError(f"tof: cannot connect BLE device {address!r}: {e}") from None

    def OnNotify(self, _characteristic: object, data: bytearray) -> None:
        self._collector.Feed(bytes(data))

    async def _Connect(self) -> None:
        from bleak import BleakClient

        self._client = BleakClient(self._address)
        await self._client.connect()
        await self._client.start_notify(BLE_UART_TX, self.OnNotify)

    def close(self) -> None:
        asyncio.run_coroutine_threadsafe(self._client.disconnect(), self._loop).result(5.0)
        self._loop.call_soon_threadsafe(self._loop.stop)
