"""``lost correlate``: the hole policy from the one result type, and the hardware options."""

import json

import numpy as np

from lost.host.cli import main
from lost.host.grid import Grid
from lost.host.io import write_npz
from lost.host.terrain import synthetic_terrain


def _files(tmp_path, holes_every=None):
    depth = synthetic_terrain((40, 50), seed=11, roughness_m=10.0, hurst=0.5)
    patch = depth[10:20, 12:22] + 2.0
    if holes_every:
        depth = depth.copy()
        depth[::holes_every, ::holes_every] = np.nan
    map_path = write_npz(Grid(depth, 1000.0, 2000.0, 10.0), tmp_path / "map.npz")
    np.save(tmp_path / "patch.npy", patch)
    return str(map_path), str(tmp_path / "patch.npy")


def test_every_placement_touching_a_hole_is_said_plainly(tmp_path, capsys):
    map_path, patch_path = _files(tmp_path, holes_every=5)
    assert main(["correlate", map_path, patch_path]) == 0
    assert "no valid placement: every one of the 1271 placements touches a hole of the map" in capsys.readouterr().out
    assert main(["correlate", map_path, patch_path, "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["best"] is None and result["runner_up"] is None and result["valid_placements"] == 0


def test_placements_touching_holes_never_win(tmp_path, capsys):
    map_path, patch_path = _files(tmp_path, holes_every=None)
    depth = np.load(map_path)["depth_m"].copy()
    depth[12, 15] = np.nan  # under the true placement
    write_npz(Grid(depth, 1000.0, 2000.0, 10.0), tmp_path / "holed.npz")
    assert main(["correlate", str(tmp_path / "holed.npz"), patch_path, "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["excluded_placements"] == 100 and (result["best"]["i"], result["best"]["j"]) != (10, 12)


def test_the_fpga_backend_needs_a_port_and_names_a_bad_one(tmp_path, capsys):
    map_path, patch_path = _files(tmp_path)
    assert main(["correlate", map_path, patch_path, "--backend", "fpga"]) == 2
    assert "--backend fpga needs --port" in capsys.readouterr().err
    assert main(["correlate", map_path, patch_path, "--backend", "fpga", "--port", "/dev/lost-no-such-port"]) == 1  # an input error, not a usage one
    assert "cannot open the serial port '/dev/lost-no-such-port'" in capsys.readouterr().err
    assert main(["correlate", map_path, patch_path, "--port", "/dev/ttyUSB0"]) == 2
    assert "--port is for --backend fpga" in capsys.readouterr().err
