"""The serial transport (pyserial) on a pseudo-terminal, the reference device answering on the other side."""

import os
import threading

import numpy as np
import pytest

from lost import model
from lost.host.correlator import configure_backend, correlation
from lost.model.device import DeviceModel, reference_info

INFO = reference_info(tile_shape=(24, 24), area_shape=(12, 12), patch_shape=(4, 4), exclusion_radius=1)


@pytest.fixture
def board():
    """A pty whose far end is the reference device, served by a thread until the test ends."""
    controller, terminal = os.openpty()
    os.set_blocking(controller, False)
    device = DeviceModel(INFO)
    stop = threading.Event()

    def serve():
        while not stop.is_set():
            try:
                data = os.read(controller, 4096)
            except BlockingIOError:
                stop.wait(0.001)
                continue
            except OSError:
                return
            reply = device.receive(data)
            if reply:
                os.write(controller, reply)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    yield os.ttyname(terminal)
    stop.set()
    thread.join()
    os.close(controller)
    os.close(terminal)


def test_the_fpga_backend_over_a_serial_port_is_exact(board):
    backend = configure_backend("fpga", port=board, baud=115200)
    try:
        rng = np.random.default_rng(4)
        terrain = rng.integers(-32768, 32768, (30, 33)).astype(np.int16)
        patch = terrain[10:14, 12:16].copy()
        result = correlation(terrain, patch, backend="fpga", area=(5, 7, 9, 9), exclusion_radius=1)
        np.testing.assert_array_equal(result.surface, model.correlate(terrain[5:17, 7:19], patch))
        assert result.best_from == "hardware" and result.best == model.Placement(10, 12, 0)
        assert backend.driver.identify() == INFO
    finally:
        backend.close()
