"""The serial transport (pyserial) on a pseudo-terminal, the reference device answering on the other side."""

import os
import threading

import numpy as np
import pytest

from lost import model
from lost.host.correlator import configure_backend, correlation
from lost.model.device import DeviceModel, reference_info

INFO = reference_info(tile_shape=(24, 24), area_shape=(12, 12), patch_shape=(4, 4), exclusion_radius=1)
BOARD_INFO = reference_info(tile_shape=(48, 48), area_shape=(30, 30), patch_shape=(10, 10), exclusion_radius=5)


@pytest.fixture
def board(request):
    """A pty whose far end is the reference device, served by a thread until the test ends."""
    controller, terminal = os.openpty()
    os.set_blocking(controller, False)
    device = DeviceModel(getattr(request, "param", INFO))
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


@pytest.mark.parametrize("board", [BOARD_INFO], indirect=True)
def test_lost_correlate_on_the_fpga_backend_matches_the_software_one(board, tmp_path, capsys):
    import json

    from lost.host.cli import main
    from lost.host.grid import Grid
    from lost.host.io import write_npz
    from lost.host.terrain import synthetic_terrain

    depth = synthetic_terrain((50, 60), seed=3, roughness_m=10.0, hurst=0.5)
    write_npz(Grid(depth, 0.0, 0.0, 10.0), tmp_path / "map.npz")
    np.save(tmp_path / "patch.npy", depth[22:32, 30:40] + 1.5)
    answers = {}
    for backend in (["--backend", "software"], ["--backend", "fpga", "--port", board, "--baud", "115200"]):
        assert main(["correlate", str(tmp_path / "map.npz"), str(tmp_path / "patch.npy"), "--json", *backend]) == 0
        answers[backend[1]] = json.loads(capsys.readouterr().out)
    software, fpga = answers["software"], answers["fpga"]
    assert fpga["best"] == software["best"] == {"i": 22, "j": 30, "value": fpga["best"]["value"]}
    assert fpga["runner_up"] == software["runner_up"] and fpga["device_cycles"] == 0  # the reference device counts no clocks
    configure_backend("fpga", port=board).close()
