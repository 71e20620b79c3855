"""Throughput of the device per ping: bytes on the wire, round trips and device cycles, and the time at a baud rate.

``python -m lost.host.correlator.throughput`` prints, for the board's build (256 x 256 tile, 70 x 70 search area,
10 x 10 patch: the navigation's default search of +/-300 m at 10 m nodes), a ping with the tile
resident (patch upload, START, the 61 x 61 surface read back) and a tile reload:

* bytes each way and request/reply round trips, counted by running :class:`CorrelatorDriver` against
  the reference device (the same frames the board exchanges);
* device cycles of START: measured on the Verilator co-simulation of the device at these sizes with
  ``--cosim`` (a build of some minutes; its tile is the area, START's clocks do not depend on it), else from ``2 * area words + core schedule + 1``, the count
  ``tests/sim/test_device_cosim.py`` checks on the co-simulated device;
* milliseconds at ``--baud`` (8N1: 10 bits a byte), with ``--latency-ms`` per round trip (an FTDI
  adapter's latency timer, 1 ms once set so; 16 ms by default on Linux) and the cycles at ``--clock-mhz``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

import numpy as np

from lost.model.device import DeviceModel, reference_info
from lost.model.variants import DEFAULT_VARIANT, variant

from .driver import CorrelatorDriver
from .transports import InProcessTransport

__all__ = ["measure", "main"]


class _Counting:
    """A transport wrapper counting bytes and round trips (one per write)."""

    def __init__(self, inner):
        self.inner, self.timeout_s = inner, inner.timeout_s
        self.bytes_out = self.bytes_in = self.round_trips = 0

    def write(self, data: bytes) -> None:
        self.bytes_out += len(data)
        self.round_trips += 1
        self.inner.write(data)

    def read(self, size: int, timeout: float) -> bytes:
        data = self.inner.read(size, timeout)
        self.bytes_in += len(data)
        return data

    def close(self) -> None:
        self.inner.close()

    def snapshot(self) -> tuple[int, int, int]:
        return self.bytes_out, self.bytes_in, self.round_trips


def _ping_inputs(info, seed: int = 1):
    rng = np.random.default_rng(seed)
    terrain = rng.integers(-2000, 2000, (600, 600)).astype(np.int16)
    patch = terrain[300:310, 300:310].copy()
    return terrain, patch, rng.random(info.patch_shape) < 0.9


def measure(*, tile_shape=(256, 256), area_shape=(70, 70), patch_shape=(10, 10), exclusion_radius=5,
            variant_name: str = DEFAULT_VARIANT, cosim: bool = False) -> dict:
    """Bytes, round trips and cycles of one ping with the tile resident, and of a tile reload."""
    registered = variant(variant_name)
    info = reference_info(variant=registered.ident, tile_shape=tile_shape, area_shape=area_shape,
                          patch_shape=patch_shape, exclusion_radius=exclusion_radius)
    counting = _Counting(InProcessTransport(DeviceModel(info)))
    driver = CorrelatorDriver(counting)
    driver.identify()
    terrain, patch, mask = _ping_inputs(info)
    rows, cols = info.surface_shape
    before = counting.snapshot()
    driver.correlate(terrain, patch, mask, True, area=(100, 100, rows, cols), exclusion_radius=exclusion_radius)
    after_first = counting.snapshot()
    # The next ping: the area moved by a node inside the resident tile, a new patch.
    driver.correlate(terrain, patch[::-1].copy(), mask, True, area=(101, 100, rows, cols), exclusion_radius=exclusion_radius)
    after_ping = counting.snapshot()
    ping = [b - a for a, b in zip(after_first, after_ping)]
    reload = [b - a for a, b in zip(before, after_first)]
    reload = [r - p for r, p in zip(reload, ping)]  # the first ping minus an ordinary one: the tile load
    AH, AW = area_shape
    schedule = registered.schedule(area_shape, patch_shape, mask, True, exclusion_radius=exclusion_radius)
    cycles = {"start_cycles_formula": 2 * AH * AW + int(schedule.best) + 1, "start_cycles_cosim": None}
    if cosim:
        # START's clocks do not depend on the tile's size: the co-simulated tile is the area, a smaller build.
        cycles["start_cycles_cosim"] = _cosim_cycles(registered.name, area_shape, area_shape, patch_shape,
                                                     exclusion_radius, mask)
    return {"info": info, "ping": dict(zip(("bytes_out", "bytes_in", "round_trips"), ping)),
            "tile_reload": dict(zip(("bytes_out", "bytes_in", "round_trips"), reload)), **cycles}


def _cosim_cycles(name, tile_shape, area_shape, patch_shape, exclusion_radius, mask) -> int:
    from .transports import CosimTransport

    transport = CosimTransport(name, tile_shape=tile_shape, area_shape=area_shape, patch_shape=patch_shape,
                               exclusion_radius=exclusion_radius)
    try:
        driver = CorrelatorDriver(transport)
        info = driver.identify()
        rng = np.random.default_rng(3)
        driver.load_tile(rng.integers(-2000, 2000, info.tile_shape).astype(np.int16))
        driver.load_patch(rng.integers(-2000, 2000, info.patch_shape).astype(np.int16), mask, True)
        return driver.start(0, 0).cycles
    finally:
        transport.close()


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m lost.host.correlator.throughput", description=__doc__.splitlines()[0])
    parser.add_argument("--baud", type=int, default=3_000_000)
    parser.add_argument("--clock-mhz", type=float, default=60.0, help="the ULX3S bitstream's clock")
    parser.add_argument("--latency-ms", type=float, default=1.0, help="per request/reply round trip")
    parser.add_argument("--variant", default=DEFAULT_VARIANT)
    parser.add_argument("--cosim", action="store_true", help="measure START's cycles on Verilator (builds the device)")
    args = parser.parse_args(argv)
    result = measure(variant_name=args.variant, cosim=args.cosim)
    info, ping, reload = result["info"], result["ping"], result["tile_reload"]
    cycles = result["start_cycles_cosim"] or result["start_cycles_formula"]
    source = "co-simulation" if result["start_cycles_cosim"] else "the formula tests/sim/test_device_cosim.py checks in co-simulation"

    def ms(counts, with_cycles):
        wire = (counts["bytes_out"] + counts["bytes_in"]) * 10 / args.baud * 1e3
        device = cycles / (args.clock_mhz * 1e3) if with_cycles else 0.0
        return wire + counts["round_trips"] * args.latency_ms + device, wire, device

    print(f"device: {info.variant_name}, tile {info.tile_shape}, area {info.area_shape}, patch {info.patch_shape}, "
          f"surface {info.surface_shape}, {info.value_bytes} bytes a value")
    print(f"START: {cycles} cycles ({source}; formula {result['start_cycles_formula']})")
    total, wire, device = ms(ping, True)
    print(f"ping, tile resident: {ping['bytes_out']} B out, {ping['bytes_in']} B in, {ping['round_trips']} round trips: "
          f"{wire:.1f} ms on the wire at {args.baud} baud + {ping['round_trips'] * args.latency_ms:.1f} ms latency "
          f"+ {device:.3f} ms device at {args.clock_mhz:g} MHz = {total:.1f} ms ({1e3 / total:.1f} Hz)")
    total, wire, _ = ms(reload, False)
    print(f"tile reload: {reload['bytes_out']} B out, {reload['bytes_in']} B in, {reload['round_trips']} round trips: {total:.0f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
