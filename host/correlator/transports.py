"""Byte pipes to the correlator device: a serial port, the Verilator co-simulation, an in-process reference.

A :class:`Transport` writes bytes and reads what has arrived within a timeout; that is all
:class:`~lost.host.correlator.driver.CorrelatorDriver` uses, so the same driver talks to the board,
the simulator and the reference device.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from lost.model.device import DeviceModel

__all__ = ["CosimTransport", "InProcessTransport", "SerialTransport", "Transport"]


class Transport:
    """A byte pipe to a device.

    Attributes
    ----------
    timeout_s : float
        How long the driver waits for a reply before resending.
    """

    timeout_s: float = 1.0

    def write(self, data: bytes) -> None:
        raise NotImplementedError

    def read(self, size: int, timeout: float) -> bytes:
        """Up to ``size`` bytes, waiting at most ``timeout`` seconds for the first; b"" if none came."""
        raise NotImplementedError

    def close(self) -> None:
        """Release the port or stop the simulator."""


class InProcessTransport(Transport):
    """The reference device (:class:`lost.model.device.DeviceModel`) in this process, for unit tests.

    Parameters
    ----------
    device : DeviceModel
        The device answering.
    damage_out, damage_in : callable(bytes) -> bytes, optional
        Applied to every write and to every reply: fault injection (flip, drop or add bytes).
    timeout_s : float
        The driver's reply timeout; a read that finds nothing waits this long and lets the device's
        frame timeout expire (a partial request is answered with a TIMEOUT error).
    """

    def __init__(self, device: DeviceModel, *, damage_out: Callable[[bytes], bytes] | None = None,
                 damage_in: Callable[[bytes], bytes] | None = None, timeout_s: float = 0.01):
        self.device = device
        self._damage_out = damage_out or (lambda data: data)
        self._damage_in = damage_in or (lambda data: data)
        self.timeout_s = timeout_s
        self._pending = bytearray()

    def write(self, data: bytes) -> None:
        self._pending += self._damage_in(self.device.receive(self._damage_out(bytes(data))))

    def read(self, size: int, timeout: float) -> bytes:
        if not self._pending:
            time.sleep(min(timeout, self.timeout_s))
            self._pending += self._damage_in(self.device.timeout())
        data = bytes(self._pending[:size])
        del self._pending[:size]
        return data


class SerialTransport(Transport):
    """A board on a serial port (pyserial), 8N1, no flow control.

    Parameters
    ----------
    port : str
        ``/dev/ttyUSB0``, ``COM3``, or any pyserial URL (``loop://`` for a loopback).
    baud : int
        The device's UART rate (the ULX3S bitstream runs at 3 Mbaud).
    timeout_s : float
        Reply timeout; the slowest reply (a 1 kB surface chunk at 115200 baud) takes 0.1 s.
    """

    def __init__(self, port: str, *, baud: int = 3_000_000, timeout_s: float = 0.5):
        try:
            import serial
        except ImportError as error:  # pragma: no cover - pyserial is a main dependency
            raise ValueError(f"the serial transport needs pyserial: {error}") from None
        try:
            self._port = serial.serial_for_url(port, baudrate=baud, timeout=timeout_s)
        except (serial.SerialException, ValueError) as error:
            raise ValueError(f"cannot open the serial port {port!r}: {error}") from None
        self.timeout_s = timeout_s
        self._port.reset_input_buffer()

    def write(self, data: bytes) -> None:
        self._port.write(data)

    def read(self, size: int, timeout: float) -> bytes:
        self._port.timeout = max(timeout, 0.0)
        first = self._port.read(1)
        if not first:
            return b""
        return first + self._port.read(min(size - 1, self._port.in_waiting))

    def close(self) -> None:
        self._port.close()


class CosimTransport(Transport):
    """The device top-level's Verilog on Verilator, in a child process, through a Unix socket.

    The child (``python -m lost.sim.cosim``) builds the device for the variant and sizes given
    (cached under ``build_dir``; minutes the first time) and runs a cocotb bench that drives the
    device's UART receive pin bit by bit with the bytes written here and returns what its transmit
    pin sends.

    Parameters
    ----------
    variant : str, optional
        A name of :data:`lost.model.variants.VARIANTS` (default :data:`~lost.model.variants.DEFAULT_VARIANT`).
    build_dir : Path, optional
        Where builds are kept (default ``~/.cache/lost/cosim``).
    sizes : dict
        Device parameters (``tile_shape``, ``area_shape``, ``patch_shape``, ``exclusion_radius``,
        ``divisor``); see :class:`lost.sim.cosim.DeviceConfig`.
    timeout_s : float
        Reply timeout, in wall-clock seconds of simulation.
    """

    def __init__(self, variant: str | None = None, *, build_dir: Path | None = None, timeout_s: float = 60.0,
                 start_timeout_s: float = 1800.0, **sizes):
        from lost.sim.cosim import DeviceConfig

        config = DeviceConfig(**({"variant": variant} if variant else {}), **sizes)
        self.config = config
        self.timeout_s = timeout_s
        build_dir = Path(build_dir) if build_dir else Path.home() / ".cache" / "lost" / "cosim"
        self._folder = tempfile.TemporaryDirectory(prefix="lost-cosim-")
        path = os.path.join(self._folder.name, "device.sock")
        self._server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._server.bind(path)
        self._server.listen(1)
        self._log = open(os.path.join(self._folder.name, "cosim.log"), "w")  # noqa: SIM115 (closed in close())
        self._child = subprocess.Popen(
            [sys.executable, "-m", "lost.sim.cosim", "--socket", path, "--build-dir", str(build_dir), "--config", config.to_json()],
            stdout=self._log, stderr=subprocess.STDOUT)
        self._server.settimeout(1.0)
        deadline = time.monotonic() + start_timeout_s
        self._socket = None
        while self._socket is None:
            try:
                self._socket, _ = self._server.accept()
            except TimeoutError:
                if self._child.poll() is not None or time.monotonic() > deadline:
                    self.close()
                    raise RuntimeError(f"the co-simulation did not start (exit {self._child.returncode}); "
                                       f"see the build under {build_dir}") from None

    def write(self, data: bytes) -> None:
        self._socket.sendall(data)

    def read(self, size: int, timeout: float) -> bytes:
        self._socket.settimeout(max(timeout, 1e-3))
        try:
            data = self._socket.recv(size)
        except TimeoutError:
            return b""
        if not data:
            raise ConnectionError(f"the co-simulation ended (exit {self._child.poll()})")
        return data

    def close(self) -> None:
        if self._socket is not None:
            self._socket.close()
            self._socket = None
        self._server.close()
        if self._child.poll() is None:
            try:
                self._child.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self._child.kill()
                self._child.wait()
        self._log.close()
        self._folder.cleanup()
