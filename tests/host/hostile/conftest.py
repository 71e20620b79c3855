"""Shared helpers of the hostile-input suite: tiny inputs that run in a fraction of a second."""

from __future__ import annotations

import numpy as np
import pytest
from tiny import TINY_SCENARIO

from lost.host.cli import main

__all__ = ["TINY_SCENARIO"]



#: Twelve seconds of one diver in light clutter: a whole `lost track` run folder in a second.
TINY_TRACK_SCENARIO = """
name = "brief"
seed = 4
duration_s = 12.0
[sonar]
clutter_per_ping = 2.0
[[target]]
start_range_m = 300.0
start_bearing_deg = 10.0
speed_mps = 0.8
"""


def _written(folder, name: str, text: str):
    path = folder / name
    path.write_text(text)
    return path


@pytest.fixture
def tiny(tmp_path):
    """Path of the tiny scenario file."""
    return _written(tmp_path, "tiny.toml", TINY_SCENARIO)


@pytest.fixture
def tiny_track(tmp_path):
    """Path of the tiny tracker scenario file."""
    return _written(tmp_path, "brief.toml", TINY_TRACK_SCENARIO)


@pytest.fixture
def run_cli(capsys):
    """``main(argv)`` in-process: returns (exit code, stdout, stderr) and checks no traceback escaped."""

    def run(*argv: str) -> tuple[int, str, str]:
        code = main([str(a) for a in argv])
        out, err = capsys.readouterr()
        assert "Traceback" not in err, err
        # Errors are one line on stderr (the command's own reports go to stdout).
        if code:
            assert len(err.strip().splitlines()) == 1, err
        return code, out, err

    return run


@pytest.fixture
def recorded(tmp_path, tiny):
    """The tiny scenario written as recorded files: nav.csv, sonar.csv, map.npz and map.nc (elevation, no sign metadata)."""
    import xarray as xr

    from lost.host.io import write_npz
    from lost.host.io.navlog import write_navlog
    from lost.host.scenario import load_scenario, simulate

    grid, records = simulate(load_scenario(tiny))
    files = {"nav": tmp_path / "nav.csv", "sonar": tmp_path / "sonar.csv", "npz": write_npz(grid, tmp_path / "map.npz"),
             "nc": tmp_path / "map.nc"}
    write_navlog(records, files["nav"], sonar=files["sonar"])
    rows, cols = grid.shape
    xr.Dataset({"z": (("y", "x"), -grid.depth_m)},
               coords={"x": grid.x0_m + grid.node_m * np.arange(cols), "y": grid.y0_m + grid.node_m * np.arange(rows)}).to_netcdf(files["nc"])
    return files
