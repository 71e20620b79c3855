"""`lost run --survey` on a simulated tow's export with the settings the export tests share (not a test module)."""

from __future__ import annotations

import json
from pathlib import Path

from lost.host.cli import main


def survey_run_summary(path: Path, map_path: Path, out: Path) -> dict:
    """The PMF's run of the export at ``path`` on the map at ``map_path`` into ``out`` (a start 30 m east and 20 m south, a
    dead-reckoning bias of 0.1, 0.05 m/s, 2 s records of 60 s of pings centred on the soundings, no figures): its summary."""
    code = main(["run", "--survey", str(path), "--bathy", str(map_path), "--start-offset", "30,-20", "--dr-bias", "0.1,0.05",
                 "--record-s", "2", "--window-s", "60", "--patch-centre", "soundings", "--estimator", "pmf", "--no-plots",
                 "--out", str(out)])
    assert code == 0
    return json.loads((out / "summary.json").read_text())
