"""The recursive core's address generator: one map read per valid node and placement, then a flush round."""

from __future__ import annotations

from typing import Any

from amaranth.hdl import Module, Mux, Signal, unsigned
from amaranth.lib import data, memory, stream, wiring
from amaranth.lib.wiring import In, Out
from amaranth.utils import ceil_log2

from lost.hdl.interface import CorrelatorParameters, checked_parameters
from lost.hdl.recursive_patch import node_layout
from lost.hdl.recursive_term import RecursiveShapes

__all__ = ["AddressGenerator", "address_tag_layout"]


def address_tag_layout(p: CorrelatorParameters) -> data.StructLayout:
    """What travels with a map read to its word: the node and the placements it serves."""
    h, w = p.patch_shape
    return data.StructLayout({
        "index": unsigned(max((h * w - 1).bit_length(), 1)),  # the node's place in the node list
        "first": 1,
        "last": 1,
        "centred": RecursiveShapes.of(p).centred,
        "current": 1,   # the word belongs to a placement (not the flush round)
        "previous": 1,  # a previous placement's terms are due on this step
    })


class AddressGenerator(wiring.Component):
    """Request the map word of every valid node of every placement, in raster order, then a flush round.

    The node list (:class:`~lost.hdl.recursive_patch.NodeCompaction`'s, ``n`` nodes of map offset and
    centred depth) is read through ``nodes_read``. For each placement ``(i, j)`` in raster order the
    generator requests address ``i * W + j + offset`` for nodes ``0 .. n - 1``; after the last placement
    one more round of ``n`` requests (the flush round, ``current`` low, at the last placement's addresses)
    pushes the last placement's terms through the core. With ``empty`` (no valid node) each placement,
    and the flush round, takes one request at the placement's corner. Each request's tag
    (:func:`address_tag_layout`) carries the node's index, whether it is its placement's first or last
    node, its centred depth, ``current`` and ``previous`` (a previous placement's terms are due: every
    placement but the first, and the flush round).

    Each request is registered before it is offered: the node memory's clock-to-output and the address
    sum are on separate clocks. That register is refilled on every edge on which it is empty or its
    request transfers, so requests flow one per clock while ``request.ready`` is high; while it is low,
    the generator holds. The node list's read port always holds the node the generator is at; its
    address is the generator's node index, which is 0 whenever the generator is idle (reset, and the
    end of each flush round), so the read in the start cycle returns node 0.

    Latency: with ``start`` high in the cycle ending on edge 0, ``request.valid`` is high from edge 1;
    with ``request.ready`` high throughout, one request transfers on every edge from edge 2, ``max(n, 1)
    * (Ho * Wo + 1)`` in all (the flush round's ``max(n, 1)`` last), and none after.

    Parameters
    ----------
    parameters : CorrelatorParameters

    Members
    -------
    request : ``Out(stream.Signature(StructLayout({"addr": unsigned(ceil_log2(H * W)), "tag": address_tag_layout})))``
        The map reads, as a :class:`~lost.hdl.sequencer.MapSequencer` takes them.
    nodes_read : ``In(memory.ReadPort.Signature(addr_width=ceil_log2(h * w), shape=node_layout))``
        A synchronous read port of the node list, transparent for its writes (the first node may be
        written on the edge it is first read).
    count_last : ``In(range(h * w))``
        ``n - 1``; held from ``start`` until the flush round ends.
    empty : ``In(1)``
        No valid node; held likewise.
    start : ``In(1)``
        Begin a correlation's requests (the placement counters and flags reset on this edge).
    """

    def __init__(self, *, parameters: CorrelatorParameters):
        checked_parameters(parameters)
        self._parameters = p = parameters
        (H, W), (h, w) = p.map_shape, p.patch_shape
        self.tag_layout = address_tag_layout(p)
        self.node_layout = node_layout(p)
        self.request_layout = data.StructLayout({"addr": unsigned(ceil_log2(H * W)), "tag": self.tag_layout})
        super().__init__({
            "request": Out(stream.Signature(self.request_layout)),
            "nodes_read": In(memory.ReadPort.Signature(addr_width=ceil_log2(h * w), shape=self.node_layout)),
            "count_last": In(range(h * w)),
            "empty": In(1),
            "start": In(1),
        })

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        p = self._parameters
        (H, W), (h, w) = p.map_shape, p.patch_shape
        rows, cols = p.surface_shape
        generating = Signal()
        flushing = Signal()
        has_previous = Signal()
        node_index = Signal(range(h * w))
        base = Signal(range(H * W))  # the placement's corner, i * W + j
        gen_i = Signal(range(rows))  # the placement, (i, j)
        gen_j = Signal(range(cols))
        node = self.nodes_read.data
        # The request register: the node memory's clock-to-output and the address sum on separate clocks.
        queued = Signal()
        queued_base = Signal.like(base)
        queued_offset = Signal(self.node_layout["offset"].shape)
        queued_tag = Signal(self.tag_layout)
        take = ~queued | self.request.ready
        advance = generating & take
        # Without a valid node each placement still takes one step, whose term is zero.
        last_node = (node_index == self.count_last) | self.empty
        m.d.comb += [
            self.request.valid.eq(queued),
            self.request.payload.addr.eq(queued_base + queued_offset),
            self.request.payload.tag.eq(queued_tag),
            # The read port always holds the node the generator is at.
            self.nodes_read.addr.eq(Mux(advance, Mux(last_node, 0, node_index + 1), node_index)),
        ]
        with m.If(take):
            m.d.sync += [
                queued.eq(generating),
                queued_base.eq(base),
                queued_offset.eq(Mux(self.empty, 0, node.offset)),
                queued_tag.index.eq(node_index),
                queued_tag.first.eq(node_index == 0),
                queued_tag.last.eq(last_node),
                queued_tag.centred.eq(node.centred),
                queued_tag.current.eq(~flushing),
                queued_tag.previous.eq(has_previous),
            ]
        with m.If(advance):
            m.d.sync += node_index.eq(Mux(last_node, 0, node_index + 1))
            with m.If(last_node):
                m.d.sync += has_previous.eq(1)
                with m.If(flushing):
                    m.d.sync += generating.eq(0)
                with m.Elif((gen_i == rows - 1) & (gen_j == cols - 1)):
                    m.d.sync += flushing.eq(1)
                with m.Elif(gen_j == cols - 1):
                    m.d.sync += [gen_j.eq(0), gen_i.eq(gen_i + 1), base.eq(base + w)]
                with m.Else():
                    m.d.sync += [gen_j.eq(gen_j + 1), base.eq(base + 1)]
        # Last, so that a start wins over the placement counters (as the core's state machine did).
        with m.If(self.start):
            m.d.sync += [generating.eq(1), flushing.eq(0), has_previous.eq(0), node_index.eq(0), base.eq(0),
                         gen_i.eq(0), gen_j.eq(0)]
        return m
