# amaranth: UnusedElaboratable=no
"""SlotBand alone against a Python model: each slot's row and band flag at every edge, the free slot chosen."""

import numpy as np
import pytest
from amaranth.sim import Simulator

from lost.hdl.interface import CorrelatorParameters
from lost.hdl.reducer_slots import SlotBand
from lost.model.cycles import reducer_geometry


class BandModel:
    """The rows held and the band of the best row so far, by row numbers (what the flags stand for)."""

    def __init__(self, slots, radius):
        self.radius = radius
        self.rows = [None] * slots  # the row a slot holds; None: none since the surface began
        self.best = None

    def in_band(self):
        return [row is not None and abs(row - self.best) <= self.radius for row in self.rows]

    def free_slot(self):
        """The lowest slot not in the band; a row that begins is written there (row 0 into slot 0)."""
        band = self.in_band()
        assert not all(band), "no free slot"
        return band.index(False)

    def beat(self, i, first_in_row, becomes_best):
        if first_in_row and i == 0:
            # Row 0 begins a surface: nothing earlier is needed, and it is the best row at its end.
            self.rows, self.best = [0] + [None] * (len(self.rows) - 1), 0
        elif first_in_row:
            self.rows[self.free_slot()] = i
        if becomes_best:
            self.best = i


def beats(rng, rows, beats_per_row, surfaces, *, best_share, gap_share):
    """``(valid, first_in_row, i, becomes_best)`` per cycle: whole surfaces in raster order, random gaps between beats."""
    out = []
    for _ in range(surfaces):
        for i in range(rows):
            for b in range(beats_per_row):
                while rng.random() < gap_share:  # an idle slot stage: stale fields, never a new best
                    out.append((False, bool(rng.integers(2)), int(rng.integers(rows)), False))
                last = b == beats_per_row - 1
                out.append((True, b == 0, i, last and (i == 0 or bool(rng.random() < best_share))))
    return out


@pytest.mark.parametrize("surface_shape, lanes, radius, best_share", [
    ((9, 7), 2, 1, 0.3), ((12, 5), 1, 2, 0.25), ((8, 6), 3, 0, 0.4), ((3, 4), 4, 2, 0.5), ((14, 3), 3, 2, 0.15),
    ((10, 4), 2, 1, 0.0),
])
def test_band_flags_and_free_slot_match_the_model(surface_shape, lanes, radius, best_share):
    rows, cols = surface_shape
    rng = np.random.default_rng([rows, cols, lanes, radius])
    params = CorrelatorParameters(map_shape=(rows + 1, cols + 1), patch_shape=(2, 2), lanes=lanes, exclusion_radius=radius)
    slots, beats_per_row = reducer_geometry(surface_shape, lanes, radius)
    dut = SlotBand(parameters=params)
    assert dut.slots == slots == min(2 * radius + 2, rows)
    stimulus = beats(rng, rows, beats_per_row, 3, best_share=best_share, gap_share=0.3)
    model = BandModel(slots, radius)
    checked = {"choices": 0, "edges": 0}

    async def bench(ctx):
        assert [ctx.get(dut.in_band[s]) for s in range(slots)] == [0] * slots
        for valid, first_in_row, i, becomes_best in stimulus:
            ctx.set(dut.beat, {"valid": valid, "first_in_row": first_in_row, "i": i})
            ctx.set(dut.becomes_best, becomes_best)
            if valid and first_in_row:
                assert ctx.get(dut.slot) == (0 if i == 0 else model.free_slot()), (i, model.rows, model.best)
                checked["choices"] += 1
            await ctx.tick()
            if valid:
                model.beat(i, first_in_row, becomes_best)
            # From the edge that ends the beat's cycle: the flags and the rows of the slots in use.
            assert [bool(ctx.get(dut.in_band[s])) for s in range(slots)] == model.in_band(), (i, model.rows, model.best)
            for s, row in enumerate(model.rows):
                if row is not None:
                    assert ctx.get(dut.rows[s]) == row
            checked["edges"] += 1

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    assert checked["choices"] == 3 * rows and checked["edges"] == len(stimulus)


def test_rejects_bad_parameters():
    with pytest.raises(ValueError, match="CorrelatorParameters"):
        SlotBand(parameters=(9, 7))
