"""cocotb 2 bench of a correlator core's Verilog: every value, the best fit and every beat's cycle.

Either variant (recursive or window, any lane count) is checked the same way, through the ports of the
contract (:func:`lost.hdl.interface.correlator_signature`): the map goes in through ``map_in``, the
patch through ``patch_in``, one ``start`` beat runs a correlation, ``surface`` and ``best`` are drained.
The transaction-level model is :mod:`lost.model`: :func:`~lost.model.correlate` gives every ``V(i, j)``,
:func:`~lost.model.best_fit` the best beat, and the variant's cycle model
(:mod:`lost.model.cycles_recursive` or :mod:`lost.model.cycles_window`) the cycle of every beat when
``surface.ready`` and ``best.ready`` are held high. An in-order checker compares each beat as it
transfers.

The pytest side (``tests/sim``) passes the parameters as JSON in the environment variable
``LOST_BENCH`` (see :class:`BenchConfig`); the tests here draw their maps, patches and masks from a
generator seeded by it, so a failure reproduces.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from typing import Any

import cocotb
import numpy as np
from amaranth.hdl import signed
from cocotb.handle import HierarchyObject
from cocotb.triggers import ClockCycles, ReadOnly, RisingEdge, with_timeout

from lost.hdl.interface import CorrelatorParameters, PatchWord, StartCommand, best_fit_payload, comparable_best
from lost.model import best_fit, correlate
from lost.model.variants import Variant, of_kind

from .streams import Clocking, StreamSink, StreamSource, Transfer, pattern

__all__ = ["BenchConfig", "ENVIRONMENT_VARIABLE", "expected_beats", "expected_cycles"]

ENVIRONMENT_VARIABLE = "LOST_BENCH"


@dataclass(frozen=True)
class BenchConfig:
    """What the bench simulates: the core's variant and parameters, and the seed of its inputs.

    Raises
    ------
    ValueError
        An unknown variant, or parameters :class:`~lost.hdl.interface.CorrelatorParameters` refuses.
    """

    variant: str
    map_shape: tuple[int, int]
    patch_shape: tuple[int, int]
    lanes: int = 1
    depth_bits: int = 16
    exclusion_radius: int = 1
    seed: int = 0

    def cycle_budget(self) -> int:
        """A generous bound on the clocks of one load or one correlation, so a hang fails the test."""
        (H, W), (h, w) = self.map_shape, self.patch_shape
        terms = (H - h + 1) * (W - w + 1) * (h * w if self.variant == "recursive" else 1)
        return 20 * (H * W + h * w + terms) + 10_000

    def __post_init__(self) -> None:
        of_kind(self.variant, self.lanes)  # a ValueError names a wrong kind or lane count
        object.__setattr__(self, "map_shape", tuple(self.map_shape))
        object.__setattr__(self, "patch_shape", tuple(self.patch_shape))
        _ = self.parameters  # validates the rest

    @property
    def registered(self) -> Variant:
        """The variant table's entry of this kind and lane count (its module name, cycle model)."""
        return of_kind(self.variant, self.lanes)

    @property
    def parameters(self) -> CorrelatorParameters:
        return CorrelatorParameters(
            map_shape=self.map_shape,
            patch_shape=self.patch_shape,
            depth_bits=self.depth_bits,
            lanes=self.lanes,
            exclusion_radius=self.exclusion_radius,
        )

    def to_json(self) -> str:
        return json.dumps(self.__dict__)

    @classmethod
    def from_environment(cls) -> BenchConfig:
        text = os.environ.get(ENVIRONMENT_VARIABLE)
        if text is None:
            raise ValueError(f"the bench reads its parameters from ${ENVIRONMENT_VARIABLE} (JSON); it is not set")
        return cls(**json.loads(text))


def expected_cycles(
    config: BenchConfig, mask: np.ndarray, mean_compensation: bool
) -> tuple[list[int], int]:
    """The cycle model's cycle of every surface beat and of the best beat (ready held high)."""
    result = config.registered.schedule(
        config.map_shape, config.patch_shape, mask, mean_compensation, exclusion_radius=config.exclusion_radius
    )
    return [int(c) for c in result.surface], int(result.best)


@dataclass(frozen=True)
class ExpectedBeat:
    i: int
    j: int
    values: tuple[int, ...]
    last: bool


def expected_beats(surface: np.ndarray, lanes: int) -> list[ExpectedBeat]:
    """The surface beats a core with ``lanes`` lanes must emit, in raster order."""
    rows, cols = surface.shape
    beats = []
    for i in range(rows):
        for j in range(0, cols, lanes):
            values = tuple(int(v) for v in surface[i, j : j + lanes])
            beats.append(ExpectedBeat(i, j, values, last=(i == rows - 1 and j + lanes >= cols)))
    return beats




class InOrderChecker:
    """Compares each surface beat with the next expected one as it transfers; keeps every mismatch."""

    def __init__(self, expected: list[ExpectedBeat]) -> None:
        self.expected = expected
        self.received = 0
        self.mismatches: list[str] = []

    def __call__(self, transfer: Transfer) -> None:
        beat, k = transfer.payload, self.received
        self.received += 1
        if k >= len(self.expected):
            self.mismatches.append(f"beat {k} beyond the surface's {len(self.expected)} beats: {beat}")
            return
        want = self.expected[k]
        got = {
            "i": beat["i"],
            "j": beat["j"],
            "values": tuple(beat["values"][: beat["count"]]),
            "last": bool(beat["last"]),
        }
        if got != {"i": want.i, "j": want.j, "values": want.values, "last": want.last}:
            self.mismatches.append(f"beat {k}: got {got}, expected {want}")

    def verdict(self) -> None:
        shown = "\n".join(self.mismatches[:10])
        assert not self.mismatches, f"{len(self.mismatches)} surface beats differ from lost.model:\n{shown}"
        assert self.received == len(self.expected), f"{self.received} beats, expected {len(self.expected)}"


@dataclass
class Run:
    """One correlation as the bench saw it."""

    start_time: int
    surface: list[Transfer] = field(default_factory=list)
    best: Transfer | None = None


class Testbench:
    """Clock, reset, the three sources, the two sinks and the model of one correlator core."""

    def __init__(self, dut: HierarchyObject, config: BenchConfig) -> None:
        self.dut = dut
        self.config = config
        self.parameters = parameters = config.parameters
        self.rng = np.random.default_rng(config.seed)
        self.clocking = Clocking(dut.clk)
        self.map_in = StreamSource(dut, "map_in", signed(parameters.depth_bits), self.clocking)
        self.patch_in = StreamSource(dut, "patch_in", PatchWord(parameters.depth_bits), self.clocking)
        self.start = StreamSource(dut, "start", StartCommand, self.clocking)
        self.surface = StreamSink(dut, "surface", parameters.surface_beat, self.clocking)
        self.best = StreamSink(dut, "best", parameters.best_fit_beat, self.clocking)
        self.terrain: np.ndarray | None = None
        self.patch: np.ndarray | None = None
        self.mask: np.ndarray | None = None

    async def reset(self, cycles: int = 2) -> None:
        self.dut.rst.value = 1
        await ClockCycles(self.dut.clk, cycles)
        self.dut.rst.value = 0

    async def _within_budget(self, awaitable: Any, what: str) -> Any:
        budget = self.config.cycle_budget()
        try:
            return await with_timeout(awaitable, budget * self.clocking.period_ns, "ns")
        except TimeoutError:
            raise AssertionError(
                f"{what} did not complete within {budget} clocks "
                f"({len(self.surface.transfers)} surface beats so far, busy={self.dut.busy.value})"
            ) from None

    # ----- inputs -------------------------------------------------------------------------------------

    def random_inputs(self, *, full_range: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A terrain, a patch cut from it with noise, and a mask (full or random, never empty).

        ``full_range`` draws the terrain from the whole depth word and puts extreme words in the
        patch, so the widest intermediates are exercised; otherwise the terrain is a smooth random
        surface, and the patch's true placement is the best fit.
        """
        (H, W), (h, w) = self.config.map_shape, self.config.patch_shape
        lo, hi = -(2 ** (self.config.depth_bits - 1)), 2 ** (self.config.depth_bits - 1) - 1
        rng = self.rng
        if full_range:
            terrain = rng.integers(lo, hi + 1, size=(H, W))
            patch = rng.choice(np.array([lo, hi]), size=(h, w))
        else:
            slope = rng.normal(0, 40, size=(H, W)).cumsum(axis=0).cumsum(axis=1) / np.sqrt(H * W)
            terrain = np.clip(np.round(slope + rng.normal(0, 20, size=(H, W))) - 8000, lo, hi)
            i, j = rng.integers(0, H - h + 1), rng.integers(0, W - w + 1)
            patch = np.clip(terrain[i : i + h, j : j + w] + rng.integers(-3, 4, size=(h, w)), lo, hi)
        mask = rng.random((h, w)) < rng.choice([1.0, 0.7, 0.3])
        mask.flat[rng.integers(0, h * w)] = True
        return terrain.astype(np.int16), patch.astype(np.int16), mask

    async def load(
        self, terrain: np.ndarray | None, patch: np.ndarray, mask: np.ndarray, *, idle: list[int] | None = None
    ) -> None:
        """Load the map (unless ``terrain`` is None: the core keeps it) and the patch."""
        valid = None if idle is None else pattern(idle)
        if terrain is not None:
            _LOADED.pop("terrain", None)  # an interrupted load leaves the memory undefined
            await self._within_budget(self.map_in.send((int(v) for v in terrain.ravel()), valid=valid), "map load")
            self.terrain = _LOADED["terrain"] = terrain
        _LOADED.pop("patch", None)
        words = [{"depth": int(d), "valid": int(v)} for d, v in zip(patch.ravel(), mask.ravel())]
        await self._within_budget(self.patch_in.send(words, valid=valid), "patch load")
        self.patch, self.mask = _LOADED["patch"], _LOADED["mask"] = patch, mask

    # ----- one correlation ----------------------------------------------------------------------------

    async def correlate(
        self,
        *,
        mean_compensation: bool,
        surface_ready: list[int] | None = None,
        best_ready: list[int] | None = None,
        check_cycles: bool,
    ) -> Run:
        """Start a correlation of what is loaded, drain it, and check it all against the model."""
        assert self.terrain is not None and self.patch is not None, "load a map and a patch first"
        V = correlate(self.terrain, self.patch, mask=self.mask, mean_compensation=mean_compensation)
        fit = best_fit(V, exclusion_radius=self.config.exclusion_radius)
        checker = InOrderChecker(expected_beats(V, self.config.lanes))
        self.surface.transfers.clear()
        self.best.transfers.clear()
        self.surface.set_ready(None if surface_ready is None else pattern(surface_ready))
        self.best.set_ready(None if best_ready is None else pattern(best_ready))
        self.surface.set_callback(checker)

        (start_time,) = await self._within_budget(
            self.start.send([{"mean_compensation": int(mean_compensation)}]), "start beat"
        )
        best = (await self._within_budget(self.best.wait_for(1), "best beat"))[0]
        # The best beat comes after the surface's last beat; a few more clocks catch any extra beat.
        await ClockCycles(self.dut.clk, 4 * self.config.lanes + 8)
        run = Run(start_time, list(self.surface.transfers), best)
        self.surface.set_callback(None)

        checker.verdict()
        assert len(self.best.transfers) == 1, f"{len(self.best.transfers)} best beats, expected one"
        assert comparable_best(best.payload) == best_fit_payload(fit), f"best beat {best.payload}, lost.model.best_fit gives {fit}"
        assert best.time > run.surface[-1].time, "the best beat came before the surface's last beat"
        await ReadOnly()
        assert not self.dut.busy.value, "busy is still high after the best beat"
        await RisingEdge(self.dut.clk)

        if check_cycles:
            surface_cycles, best_cycle = expected_cycles(self.config, self.mask, mean_compensation)
            got_cycles = [self.clocking.cycle(t.time, since=start_time) for t in run.surface]
            if got_cycles != surface_cycles:
                first = next(
                    (k for k, (a, b) in enumerate(zip(got_cycles, surface_cycles)) if a != b),
                    min(len(got_cycles), len(surface_cycles)),
                )
                raise AssertionError(
                    f"surface beat {first} of {len(surface_cycles)} transferred on cycle "
                    f"{got_cycles[first] if first < len(got_cycles) else None}, the cycle model says "
                    f"{surface_cycles[first] if first < len(surface_cycles) else None} "
                    f"({len(got_cycles)} beats seen)"
                )
            got_best = self.clocking.cycle(best.time, since=start_time)
            assert got_best == best_cycle, f"best beat on cycle {got_best}, the cycle model says {best_cycle}"
        self.dut._log.info(
            "correlation of %s map, %s patch (n=%d, mean_compensation=%s): %d beats, best beat on cycle %d",
            self.config.map_shape, self.config.patch_shape, int(self.mask.sum()), mean_compensation,
            len(run.surface), self.clocking.cycle(best.time, since=start_time),
        )
        return run


# What this simulator's memories hold: they survive resets and the tests of one run (cocotb runs them
# in order in one simulation), so a test may reuse the 251 001-word map the test before loaded.
_LOADED: dict[str, np.ndarray] = {}


async def _bench(dut: HierarchyObject) -> Testbench:
    tb = Testbench(dut, BenchConfig.from_environment())
    tb.terrain, tb.patch, tb.mask = (_LOADED.get(k) for k in ("terrain", "patch", "mask"))
    await tb.reset()
    return tb


@cocotb.test()
async def every_value_and_every_cycle_with_ready_held_high(dut: HierarchyObject) -> None:
    """Both modes, random masks; each beat's value and cycle against the model and the cycle model."""
    tb = await _bench(dut)
    terrain, patch, mask = tb.random_inputs(full_range=False)
    await tb.load(terrain, patch, mask)
    await tb.correlate(mean_compensation=True, check_cycles=True)
    # The patch alone is reloaded: the map persists.
    _, patch, mask = tb.random_inputs(full_range=False)
    await tb.load(None, patch, mask)
    await tb.correlate(mean_compensation=False, check_cycles=True)


@cocotb.test()
async def a_reset_mid_correlation_then_a_full_correct_one(dut: HierarchyObject) -> None:
    """A reset while the surface streams leaves the core idle; the next correlation is exact and on time."""
    tb = await _bench(dut)
    if tb.terrain is None or tb.patch is None:  # run alone; else the test before loaded them
        terrain, patch, mask = tb.random_inputs(full_range=False)
        await tb.load(terrain, patch, mask)
    tb.surface.set_ready(pattern([1, 1, 0]))
    await tb.start.send([{"mean_compensation": 1}])
    beats = tb.parameters.surface_shape[0] * -(-tb.parameters.surface_shape[1] // tb.config.lanes)
    await tb._within_budget(tb.surface.wait_for(max(1, beats // 10)), "a tenth of the surface")
    await tb.reset(cycles=3)
    await ReadOnly()
    assert not dut.busy.value, "busy is still high after a reset"
    assert not dut.surface__valid.value and not dut.best__valid.value, "a reset left an output beat offered"
    await RisingEdge(dut.clk)
    # Memories are not cleared by reset: correlate again without reloading anything.
    await tb.correlate(mean_compensation=True, check_cycles=True)


@cocotb.test()
async def every_value_under_random_backpressure(dut: HierarchyObject) -> None:
    """Full-range words, idle loads and random ready patterns; values only (cycles depend on ready)."""
    tb = await _bench(dut)
    rng = tb.rng
    terrain, patch, mask = tb.random_inputs(full_range=True)
    await tb.load(terrain, patch, mask, idle=[1, 1, 0, 1, 0, 1, 1, 1])
    for mean_compensation in (True, False):
        surface_ready = [int(b) for b in rng.random(23) < 0.6] + [1]
        best_ready = [0] * int(rng.integers(1, 9)) + [1]
        await tb.correlate(
            mean_compensation=mean_compensation,
            surface_ready=surface_ready,
            best_ready=best_ready,
            check_cycles=False,
        )
