"""One correlation on the simulated gateware, for the host's ``rtl`` backend (:mod:`lost.sim.rtl`).

Not a check: the bench of :mod:`lost.sim.cocotb.correlator` compares the gateware with the model.
This runs what the host asks, as the host asks it: it reads the map, patch, mask and mode from the
``.npz`` named by ``$LOST_RTL_JOB``, loads them through ``map_in`` and ``patch_in``, starts one
correlation, drains every surface beat and the best beat, and writes what the gateware answered
(``surface``, ``best``) and the clocks it took (``cycles``) to the ``.npz`` named by ``$LOST_RTL_RESULT``.
The bench's parameters come from ``$LOST_BENCH`` like the correlator bench's.
"""

from __future__ import annotations

import os

import cocotb
import numpy as np
from cocotb.handle import HierarchyObject

from .correlator import BenchConfig, Testbench

__all__ = ["JOB_VARIABLE", "RESULT_VARIABLE"]

JOB_VARIABLE = "LOST_RTL_JOB"
RESULT_VARIABLE = "LOST_RTL_RESULT"


@cocotb.test()
async def correlate_the_job(dut: HierarchyObject) -> None:
    """Load, start, drain; write the surface the gateware produced."""
    config = BenchConfig.from_environment()
    tb = Testbench(dut, config)
    with np.load(os.environ[JOB_VARIABLE]) as job:
        terrain, patch, mask = job["terrain"], job["patch"], job["mask"]
        mean_compensation = bool(job["mean_compensation"])
    await tb.reset()
    await tb.load(terrain, patch, mask)
    (start_time,) = await tb._within_budget(tb.start.send([{"mean_compensation": int(mean_compensation)}]), "start beat")
    best = (await tb._within_budget(tb.best.wait_for(1), "best beat"))[0]

    rows, cols = config.parameters.surface_shape
    surface = np.full((rows, cols), -1, dtype=np.int64)
    seen = np.zeros((rows, cols), dtype=bool)
    for transfer in tb.surface.transfers:
        beat = transfer.payload
        i, j, count = int(beat["i"]), int(beat["j"]), int(beat["count"])
        surface[i, j : j + count] = beat["values"][:count]
        seen[i, j : j + count] = True
    # A beat the gateware never sent would leave a hole; say so rather than return -1 as a value.
    assert seen.all(), f"the gateware sent no value for {int((~seen).sum())} of {seen.size} placements"
    np.savez(
        os.environ[RESULT_VARIABLE],
        surface=surface,
        best=np.array([best.payload["i"], best.payload["j"], best.payload["value"]], dtype=np.int64),
        cycles=np.int64(tb.clocking.cycle(best.time, since=start_time)),
    )
