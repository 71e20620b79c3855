"""Valid/ready stream source and sink for cocotb 2, payloads coded from the Amaranth layouts.

An Amaranth ``stream.Signature`` port ``name`` appears in the generated Verilog as ``name__payload``,
``name__valid`` and ``name__ready``; a struct payload is one flat vector, first field in the lowest
bits. Payloads are encoded and decoded by ``lost.hdl.interface.encode_payload``/``decode_payload``
from the very layout the gateware was built from, so the bench never restates a field offset.

Timing convention (cocotb's ``RisingEdge`` then ``ReadOnly``): after clock edge ``e`` the settled
values are those the design samples on edge ``e + 1``, so ``valid and ready`` seen there is a
transfer on edge ``e + 1``. Sources and sinks record the simulation time of every transfer edge;
:meth:`Clocking.cycle` turns a time into a cycle count from a reference edge. Both sleep on a value
change of ``valid`` rather than waking every clock while their stream is idle, which keeps a long
correlation (one surface beat per 100 clocks in the recursive core) fast on Verilator.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Any

import cocotb
from amaranth.hdl import Shape
from cocotb.clock import Clock
from cocotb.handle import HierarchyObject
from cocotb.simtime import convert, get_sim_time
from cocotb.triggers import Event, ReadOnly, RisingEdge
from cocotb.types import Logic, LogicArray

from lost.hdl.interface import decode_payload, encode_payload

__all__ = ["Clocking", "StreamSink", "StreamSource", "Transfer", "always", "pattern"]


def always() -> Iterator[int]:
    """The pattern of a stream that is never idle and never back-pressured."""
    return itertools.repeat(1)


def pattern(bits: Iterable[int]) -> Iterator[int]:
    """A repeating valid/ready pattern, cocotbext-axi's habit (e.g. ``[1, 1, 0, 1, 0, 0]``)."""
    bits = list(bits)
    if not bits or not any(bits):
        raise ValueError(f"a valid/ready pattern needs at least one 1, got {bits!r}")
    return itertools.cycle(bits)


class Clocking:
    """The clock of a bench: starts it, and converts simulation times to cycle counts.

    Times are integer simulator steps: nanoseconds as floats lose the last digit after some 10^8 ns,
    which a full-size recursive correlation reaches.

    Parameters
    ----------
    clock : handle
        The clock input (Amaranth's ``clk``).
    period_ns : int
        The clock period; any value works, it only scales simulation time.
    """

    def __init__(self, clock: Any, *, period_ns: int = 10) -> None:
        self.clock = clock
        self.period_ns = period_ns
        self.period_steps = convert(period_ns, "ns", to="step")
        Clock(clock, period_ns, unit="ns").start()

    def now(self) -> int:
        return get_sim_time("step")

    def next_edge_time(self) -> int:
        """Time of the next rising edge, when called on a rising edge (or in its ReadOnly phase)."""
        return self.now() + self.period_steps

    def cycle(self, time: int, *, since: int) -> int:
        """Whole clock periods from the edge at ``since`` to the edge at ``time`` (both in steps)."""
        cycles, remainder = divmod(time - since, self.period_steps)
        if remainder:
            raise ValueError(f"step {time} is not a clock edge: {since} + k * {self.period_steps}")
        return cycles


@dataclass(frozen=True)
class Transfer:
    """One beat of a stream: its decoded payload and the simulation time (steps) of its clock edge."""

    payload: Any
    time: int


def _bits(value: Logic | LogicArray) -> int:
    """The unsigned integer of a handle value (a 1-bit payload reads as ``Logic``); X or Z raise."""
    return int(value) if isinstance(value, Logic) else value.to_unsigned()


class _Port:
    def __init__(self, dut: HierarchyObject, name: str, shape: Any) -> None:
        self.payload = getattr(dut, f"{name}__payload")
        self.valid = getattr(dut, f"{name}__valid")
        self.ready = getattr(dut, f"{name}__ready")
        self.shape = shape
        width = Shape.cast(shape).width
        if len(self.payload) != width:
            raise ValueError(f"{name}__payload has {len(self.payload)} bits, but its layout has {width}")


class StreamSource:
    """Drives a valid/ready stream input of the DUT with words, idling by a pattern.

    Parameters
    ----------
    dut : HierarchyObject
        The toplevel.
    name : str
        The stream port's name (``map_in``).
    shape : ShapeCastable
        Its payload shape, from ``lost.hdl.interface``.
    clocking : Clocking
        The bench's clock.
    """

    def __init__(self, dut: HierarchyObject, name: str, shape: Any, clocking: Clocking) -> None:
        self.name = name
        self._port = _Port(dut, name, shape)
        self._clocking = clocking
        self._port.valid.value = 0

    async def send(self, words: Iterable[Any], *, valid: Iterator[int] | None = None) -> list[int]:
        """Transfer ``words`` in order; return the time of each one's transfer edge.

        Starts on the next rising edge and leaves ``valid`` low after the last transfer. ``valid``
        is an iterator of 0/1 consulted once per word offered (0 = one idle clock first).
        """
        port, clock = self._port, self._clocking.clock
        valid = always() if valid is None else valid
        times = []
        await RisingEdge(clock)
        for word in words:
            while not next(valid):
                port.valid.value = 0
                await RisingEdge(clock)
            port.payload.value = encode_payload(port.shape, word)
            port.valid.value = 1
            while True:
                await ReadOnly()
                if port.ready.value:
                    times.append(self._clocking.next_edge_time())
                    await RisingEdge(clock)
                    break
                await RisingEdge(clock)
        port.valid.value = 0
        return times


class StreamSink:
    """Takes every beat of a valid/ready stream output of the DUT, back-pressuring by a pattern.

    A monitor coroutine started with ``cocotb.start_soon``; each transfer is appended to
    :attr:`transfers` and handed to ``on_transfer``. While ``valid`` is low the monitor sleeps on its
    rising edge instead of waking every clock.

    Parameters
    ----------
    dut, name, shape, clocking
        As for :class:`StreamSource`.
    ready : iterator of int, optional
        0/1 per clock the sink is awake; always ready when omitted.
    on_transfer : callable, optional
        Called with each :class:`Transfer` as it is taken.
    """

    def __init__(
        self,
        dut: HierarchyObject,
        name: str,
        shape: Any,
        clocking: Clocking,
        *,
        ready: Iterator[int] | None = None,
        on_transfer: Callable[[Transfer], None] | None = None,
    ) -> None:
        self.name = name
        self.transfers: list[Transfer] = []
        self.transferred = Event()
        self._port = _Port(dut, name, shape)
        self._clocking = clocking
        self._ready = always() if ready is None else ready
        self._on_transfer = on_transfer
        self._port.ready.value = 0
        self._task = cocotb.start_soon(self._monitor())

    async def wait_for(self, count: int) -> list[Transfer]:
        """Sleep until at least ``count`` beats have been taken; return all taken so far."""
        while len(self.transfers) < count:
            self.transferred.clear()
            await self.transferred.wait()
        return self.transfers

    def stop(self) -> None:
        self._task.cancel()
        self._port.ready.value = 0

    def set_ready(self, ready: Iterator[int] | None) -> None:
        """Change the back-pressure pattern from the next clock on (or the next rise of ``valid``)."""
        self._ready = always() if ready is None else ready

    def set_callback(self, on_transfer: Callable[[Transfer], None] | None) -> None:
        """Hand each following transfer to ``on_transfer`` (None: to nobody)."""
        self._on_transfer = on_transfer

    async def _monitor(self) -> None:
        port, clock = self._port, self._clocking.clock
        await RisingEdge(clock)
        port.ready.value = next(self._ready)
        while True:
            await ReadOnly()
            if not port.valid.value:
                # Idle: sleep until valid rises (on a clock edge), then decide ready for the next edge.
                await RisingEdge(port.valid)
                port.ready.value = next(self._ready)
                continue
            if port.ready.value:
                transfer = Transfer(decode_payload(port.shape, _bits(port.payload.value)), self._clocking.next_edge_time())
                await RisingEdge(clock)
                port.ready.value = next(self._ready)
                self.transfers.append(transfer)
                if self._on_transfer is not None:
                    self._on_transfer(transfer)
                self.transferred.set()
                continue
            await RisingEdge(clock)
            port.ready.value = next(self._ready)
