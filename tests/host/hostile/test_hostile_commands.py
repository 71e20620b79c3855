"""Hostile input through the commands' own front doors: a bad patch file reaches `lost correlate` as the reader's named error."""

from __future__ import annotations

import numpy as np
import pytest

from lost.host.cli import EXIT_ERROR
from lost.host.grid import Grid
from lost.host.io import write_npz


@pytest.mark.parametrize(("text", "message"), [("1,2,3\n4,deep,6\n", "deep"), ("1,2,3\n4,5\n", "row"), ("(1+2j),2\n3,4\n", "")])
def test_lost_correlate_names_what_is_wrong_in_a_patch(tmp_path, run_cli, text, message):
    rng = np.random.default_rng(0)
    write_npz(Grid(depth_m=100.0 + rng.normal(size=(30, 30)), x0_m=0.0, y0_m=0.0, node_m=10.0), tmp_path / "map.npz")
    (tmp_path / "patch.csv").write_text(text)
    code, _, err = run_cli("correlate", tmp_path / "map.npz", tmp_path / "patch.csv")
    assert code == EXIT_ERROR and "patch.csv" in err and message in err
