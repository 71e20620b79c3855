"""``python -m lost.sim.cycles``: the table the README quotes, from the cycle models."""

import numpy as np
import pytest

from lost.model import cycles_recursive, cycles_window
from lost.sim.cycles import cycle_table, main


def test_the_table_is_the_cycle_models_numbers():
    rows = cycle_table((23, 30), (5, 4), lanes=(1, 4), exclusion_radius=2)
    assert [(r["variant"], r["mean_compensation"]) for r in rows] == [
        (v, mc) for v in ("recursive", "window, 1 lane", "window, 4 lanes") for mc in (True, False)
    ]
    mask = np.ones((5, 4), dtype=bool)
    recursive = cycles_recursive.schedule((23, 30), (5, 4), mask, True, exclusion_radius=2)
    window4 = cycles_window.schedule((23, 30), (5, 4), 4, mask, False, exclusion_radius=2)
    assert (rows[0]["first_beat"], rows[0]["last_beat"], rows[0]["best_beat"]) == (
        recursive.surface[0], recursive.surface[-1], recursive.best)
    assert (rows[5]["first_beat"], rows[5]["last_beat"], rows[5]["best_beat"]) == (
        window4.surface[0], window4.surface[-1], window4.best)
    assert all(0 < r["first_beat"] <= r["last_beat"] < r["best_beat"] for r in rows)


def test_command_prints_every_variant(capsys):
    assert main(["--map", "30x20", "--patch", "4x3"]) == 0
    out = capsys.readouterr().out
    assert "30 x 20 map, 4 x 3 patch" in out
    assert out.count("recursive") >= 2 and out.count("window, 4 lanes") == 2


def test_command_refuses_a_patch_larger_than_the_map(capsys):
    with pytest.raises(SystemExit):
        main(["--map", "5x5", "--patch", "6x6"])
    assert "larger than the map" in capsys.readouterr().err
