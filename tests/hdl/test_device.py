# amaranth: UnusedElaboratable=no
"""The device top-level in the Amaranth simulator, at bit level on its UART pins, against the reference device."""

import struct

import pytest
from amaranth.hdl import Module
from amaranth.sim import Simulator

from lost.hdl.device import CorrelatorDevice
from lost.model.device import DeviceModel
from lost.model.protocol import Command, ErrorCode, FrameDecoder, encode_frame
from lost.sim.serial_line import line_listener, send_bytes

DIVISOR = 4
TIMEOUT = 60 * DIVISOR
SIZES = {"tile_shape": (10, 12), "area_shape": (7, 8), "patch_shape": (3, 3), "exclusion_radius": 1}


class DeviceBench:
    """The device with a line listener on tx; ``exchange`` sends bytes and waits for the replies."""

    def __init__(self, variant="window_correlator_l1"):
        self.dut = CorrelatorDevice(variant=variant, divisor=DIVISOR, frame_timeout=TIMEOUT, **SIZES)
        self.model = DeviceModel(self.dut.info)
        m = Module()
        m.submodules.dut = self.dut
        self.sim = Simulator(m)
        self.sim.add_clock(1e-8)
        self.received = []
        self.sim.add_testbench(line_listener(self.dut.tx, self.received, divisor=DIVISOR), background=True)

    async def exchange(self, ctx, data, *, replies=1, clocks=100_000):
        """Send ``data``; wait until ``replies`` frames came back (or ``clocks``); return their bytes."""
        start = len(self.received)
        await send_bytes(ctx, self.dut.rx, data, divisor=DIVISOR)
        for _ in range(clocks // 16):
            await ctx.tick().repeat(16)
            got = bytes(self.received[start:])
            if len(FrameDecoder().feed(got)) >= replies:
                await ctx.tick().repeat(12 * DIVISOR)  # a last byte in flight would be a protocol error
                break
        got = bytes(self.received[start:])
        assert all(isinstance(b, int) for b in self.received[start:]), "a character with a low stop bit"
        return got

    def run(self, testbench, clocks=3_000_000):
        self.sim.add_testbench(testbench)
        self.sim.run_until(clocks * 1e-8)


def test_identify_and_error_replies_at_bit_level():
    """Every reply byte as the reference device's; the full command set runs on Verilator (tests/sim/test_device_cosim.py)."""
    bench = DeviceBench()
    corrupted = bytearray(encode_frame(2, Command.ORIGIN, struct.pack("<ii", -5, 123456)))
    corrupted[6] ^= 0x80
    requests = [
        encode_frame(1, Command.IDENTIFY),
        bytes(corrupted),
        b"\x00\x11" + encode_frame(3, 0x42),  # garbage, then an unknown command
        encode_frame(4, Command.ORIGIN, struct.pack("<ii", -5, 123456)),
        encode_frame(5, Command.ORIGIN),
    ]
    replies = []

    async def testbench(ctx):
        for request in requests:
            replies.append(await bench.exchange(ctx, request, clocks=4000))

    bench.run(testbench, clocks=40_000)
    for request, reply in zip(requests, replies, strict=True):
        assert reply == bench.model.receive(request)
    assert FrameDecoder().feed(replies[1])[0].error == (ErrorCode.CRC, Command.ORIGIN)


def test_a_search_area_past_the_tile_is_refused():
    with pytest.raises(ValueError, match="must fit in the tile"):
        CorrelatorDevice(tile_shape=(8, 8), area_shape=(9, 4), patch_shape=(3, 3))
