"""A serial line in the Amaranth simulator: bytes to 8N1 bits on a pin, and bits from a pin back to bytes.

Shared by the UART's and the device's tests (``tests/hdl``). ``divisor`` is the clocks per bit.
"""

from __future__ import annotations

from collections.abc import Iterable

__all__ = ["line_listener", "send_bytes"]


async def send_bytes(ctx, line, data: Iterable[int], *, divisor: int, stop: int = 1) -> None:
    """Drive each byte on ``line`` as an 8N1 character (LSB first); the line is left idle (high)."""
    for byte in data:
        for bit in [0, *((byte >> k) & 1 for k in range(8)), stop]:
            ctx.set(line, bit)
            await ctx.tick().repeat(divisor)
    ctx.set(line, 1)


def line_listener(line, received: list, *, divisor: int):
    """A background testbench appending every character ``line`` carries to ``received`` (as ints).

    It sleeps until a start bit, then samples each bit at its middle; a low stop bit is recorded as
    ``("frame error", byte)``.
    """

    async def listen(ctx):
        while True:
            # Polled a clock at a time: a background testbench suspended inside ``until`` at the
            # simulation's end leaves an async generator that cannot be closed.
            while ctx.get(line):
                await ctx.tick()
            await ctx.tick().repeat(divisor // 2)
            byte = 0
            for k in range(8):
                await ctx.tick().repeat(divisor)
                byte |= ctx.get(line) << k
            await ctx.tick().repeat(divisor)
            received.append(byte if ctx.get(line) else ("frame error", byte))

    return listen
