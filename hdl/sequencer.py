"""The map-memory sequencer: a stream of addresses in, a stream of memory words out.

The map memory is a synchronous RAM (one cycle of read latency) that may live outside the correlator
(on an FPGA, in block RAM placed by the vendor's tools), so every correlator core reads it through
this one component and a :class:`lib.memory.ReadPort.Signature`-shaped port.
"""

from __future__ import annotations

from typing import Any

from amaranth.hdl import Module, Shape, ShapeLike, Signal, unsigned
from amaranth.lib import data, memory, stream, wiring
from amaranth.lib.wiring import In, Out

__all__ = ["MapSequencer"]


class MapSequencer(wiring.Component):
    """Read a memory word for every address of a stream, in order, under back-pressure.

    Each request carries a ``tag`` that travels with it and comes back beside the word, so a core can
    attach its own bookkeeping (which term, which pass, last of a placement) to every read.

    The memory's output register is the first of two pipeline stages: its ``en`` is held low while the
    word it holds cannot be passed on, and a skid register catches the one word in flight when the
    response stream stalls. ``request.ready`` is therefore a register (no combinational path from
    ``response.ready``), and the sequencer sustains one word per cycle.

    Latency: a request that transfers on clock edge ``t`` is offered on ``response`` from edge ``t``
    onwards and, with ``response.ready`` high, transfers on edge ``t + 1``.

    Parameters
    ----------
    addr_width : int
        Width of a memory address.
    shape : shape-like
        Shape of a memory word.
    tag_shape : shape-like
        Shape of the tag carried from a request to its response; none by default.

    Members
    -------
    request : ``In(stream.Signature(StructLayout({"addr": unsigned(addr_width), "tag": tag_shape})))``
        Addresses to read, in order.
    response : ``Out(stream.Signature(StructLayout({"data": shape, "tag": tag_shape})))``
        The word at each address, with its request's tag.
    read : ``In(memory.ReadPort.Signature(addr_width=addr_width, shape=shape))``
        The synchronous read port this component drives (``en``, ``addr``) and samples (``data``).

    Raises
    ------
    ValueError
        A negative address width, or a shape that is not shape-like.
    """

    def __init__(self, *, addr_width: int, shape: ShapeLike, tag_shape: ShapeLike = unsigned(0)):
        if isinstance(addr_width, bool) or not isinstance(addr_width, int) or addr_width < 0:
            raise ValueError(f"addr_width must be a non-negative integer, got {addr_width!r}")
        for name, value in (("shape", shape), ("tag_shape", tag_shape)):
            try:
                Shape.cast(value)
            except TypeError as error:
                raise ValueError(f"{name} must be a shape-like object, got {value!r}") from error
        self._addr_width = addr_width
        self._shape = shape
        self._tag_shape = tag_shape
        self.request_layout = data.StructLayout({"addr": unsigned(addr_width), "tag": tag_shape})
        self.response_layout = data.StructLayout({"data": shape, "tag": tag_shape})
        super().__init__({
            "request": In(stream.Signature(self.request_layout)),
            "response": Out(stream.Signature(self.response_layout)),
            "read": In(memory.ReadPort.Signature(addr_width=addr_width, shape=shape)),
        })

    def elaborate(self, platform: Any) -> Module:
        m = Module()

        # The read port's data register holds a requested word not yet passed on.
        pending = Signal()
        pending_tag = Signal(self._tag_shape)
        # The word caught when the response stalled while a new read was already issued.
        skid = Signal(self.response_layout)
        skid_full = Signal()

        issue = self.request.valid & self.request.ready
        m.d.comb += [
            self.request.ready.eq(~skid_full),
            # Holding en low keeps the pending word in the port's data register.
            self.read.en.eq(~skid_full),
            self.read.addr.eq(self.request.payload.addr),
        ]

        with m.If(skid_full):
            m.d.comb += [
                self.response.valid.eq(1),
                self.response.payload.eq(skid),
            ]
            with m.If(self.response.ready):
                m.d.sync += skid_full.eq(0)
        with m.Else():
            m.d.comb += [
                self.response.valid.eq(pending),
                self.response.payload.data.eq(self.read.data),
                self.response.payload.tag.eq(pending_tag),
            ]
            with m.If(pending & ~self.response.ready):
                m.d.sync += [
                    skid.eq(self.response.payload),
                    skid_full.eq(1),
                ]
            m.d.sync += pending.eq(issue)
            with m.If(issue):
                m.d.sync += pending_tag.eq(self.request.payload.tag)

        return m
