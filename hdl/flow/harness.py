"""A synthesis top-level for measuring a correlator core on an FPGA: not a host link.

A correlator core has hundreds of port bits (the surface beat alone is ``lanes`` accumulator values
wide) and a device has a few hundred pins, so :class:`MeasurementHarness` brings the core to a few pins
in the one way that keeps the measurement honest:

* every core input is driven by a register of a scan chain that shifts ``scan_bits`` new bits in per
  clock from registered pins, so no input is constant and none can be optimised away;
* every core output is registered, then XOR-folded into ``fold_bits`` registered pins through a tree
  of registered 4-input XORs, so every output bit stays live and the fold never sets Fmax;
* with ``global_reset`` (the synthesis builds), the reset pin drives the core's reset through a
  ``DCCA`` clock buffer onto a global net, as an ECP5 design with a reset fanning out to thousands of
  flip-flops does (nextpnr promotes only clocks to globals): else the reset net itself is the
  longest path. The pin sits on a primary clock input (:data:`RESET_SITE`), whose pad reaches an edge
  clock buffer over dedicated wires. A register before the buffer (as this harness had) must enter the
  clock network from the fabric, whose entries to an edge buffer are LUT inputs of fixed tiles
  (``JD7`` of ``X75/Y1`` to ``TDCC0``, ``JD7`` of ``X61/Y1`` to ``TDCC1``, in nextpnr's routed
  netlist): when the placer puts a LUT there, router2 reserves that input for the LUT's own net
  (``common/route/router2.cc``, reserved wires), and the register may not reach its buffer at all
  (``Failed to route arc 0.0 of net 'reset_pin'``, two of the 4-lane builds). The reset then
  arrives unsynchronised: nextpnr times it as an input path (``<async> -> posedge``, not in the
  Fmax), which a measurement harness may; a board's top-level synchronises its reset;
* the core's ``map_read`` port, when it has one (the external-memory build), goes to its own pins,
  address and enable out through one register each, data in through one register: the pins an
  external memory would drive. Those registers add two cycles to the one-cycle latency the core
  expects, so the harness does not run a correlation correctly; it only times the core's paths, every
  one of which starts and ends at a register.

No stimulus is meaningful here. Functional checks live in the simulations (``tests/hdl``, ``tests/sim``);
this module only makes place-and-route see the core as it would be used, with IO out of the way.
"""

from __future__ import annotations

from typing import Any

from amaranth.hdl import Cat, ClockDomain, ClockSignal, Const, Instance, Module, Signal, Value
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from lost.hdl.blocks import RegisteredProduct, check_count

__all__ = ["CLOCK_SITE", "ECP5_MULTIPLIER_BITS", "ECP5RegisteredProduct", "RESET_SITE", "MeasurementHarness", "ecp5_global_buffer"]

#: The ball of the harness's reset pin (``LOC``; the flow's LFE5U-85F in CABGA381): ``PCLKT6_1``, a primary
#: clock input whose pad nextpnr routes through ``JINCK`` to the left edge's ``LDCC1`` on dedicated wires, so
#: the reset's ``DCCA`` needs no fabric route.
RESET_SITE = "G2"

#: The ball of the harness's clock pin: ``PCLKT6_0``, the other primary clock input of the same IO group (PL47),
#: so the clock too reaches its global buffer on dedicated wires whatever the placement (unplaced, a
#: clock pin may land on a plain IO and enter the clock network from the fabric, as the reset once did).
CLOCK_SITE = "H2"


def ecp5_global_buffer(m: Module, signal: Value) -> Value:
    """``signal`` through an ECP5 ``DCCA`` clock buffer onto a global net (synthesis only: the simulators
    know no ``DCCA``). nextpnr promotes only clocks to globals, so a reset or enable that fans out to
    thousands of flip-flops is routed this way, or its net alone is the longest path. The window core
    takes it as its ``enable_buffer``; the harness routes the core's reset through it."""
    buffered = Signal(name=f"{signal.name}_global" if isinstance(signal, Signal) else "global")
    m.submodules[f"{buffered.name}_buffer"] = Instance("DCCA", i_CLKI=signal, i_CE=1, o_CLKO=buffered)
    return buffered


#: The operand width of the ECP5's multiplier (``MULT18X18D``; unsigned with ``SIGNEDA``/``SIGNEDB`` low).
ECP5_MULTIPLIER_BITS = 18


class ECP5RegisteredProduct(RegisteredProduct):
    """A :class:`~lost.hdl.blocks.RegisteredProduct` in one ECP5 ``MULT18X18D`` whose input registers hold
    the operands (synthesis only: the simulators know no ``MULT18X18D``).

    Yosys maps a product to a ``MULT18X18D`` with every register bypassed and moves none into it (it does
    so for other devices' multipliers, not the ECP5's), so a product of fabric registers is one path from a
    register through a route into the block, the multiplier and a route out (13.75 ns, 9.3 ns of it routing,
    in the 4-lane build of 6e39ad9, seed 2). Here the block's own input registers (``REG_INPUTA_CLK``,
    ``REG_INPUTB_CLK`` on ``CLK0``; ``CE0`` high, ``RST0`` low, no ``GSR``: reset-less, as the generic block's)
    load the operands; nextpnr times the block by its registered inputs (``MULT18X18D_REGS_INPUT``).
    """

    def __init__(self, a_bits: int, b_bits: int):
        super().__init__(a_bits, b_bits)
        if max(a_bits, b_bits) > ECP5_MULTIPLIER_BITS:
            raise ValueError(f"An ECP5 MULT18X18D takes operands of {ECP5_MULTIPLIER_BITS} bits at most, got {a_bits} x {b_bits}.")

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        width = ECP5_MULTIPLIER_BITS
        a = Cat(self.a, Const(0, width - self.a_bits))
        b = Cat(self.b, Const(0, width - self.b_bits))
        p = Signal(2 * width, name="p_full")
        registered = {f"p_REG_INPUT{operand}_{setting}": f"{setting}0" for operand in "AB" for setting in ("CLK", "CE", "RST")}
        m.submodules.multiplier = Instance(
            "MULT18X18D", **registered, p_REG_PIPELINE_CLK="NONE", p_REG_OUTPUT_CLK="NONE", p_GSR="DISABLED",
            p_RESETMODE="SYNC", i_CLK0=ClockSignal(), i_CE0=1, i_RST0=0, i_SIGNEDA=0, i_SIGNEDB=0, i_SOURCEA=0,
            i_SOURCEB=0, **{f"i_A{k}": a[k] for k in range(width)}, **{f"i_B{k}": b[k] for k in range(width)},
            **{f"i_C{k}": 0 for k in range(width)}, **{f"o_P{k}": p[k] for k in range(2 * width)})
        m.d.comb += self.p.eq(p[:self.a_bits + self.b_bits])
        return m



def _fold(m: Module, bits: Value, fold_bits: int) -> Value:
    """XOR ``bits`` into ``fold_bits`` bits: bit ``k`` into output ``k % fold_bits``, one register per 4:1 level."""
    buckets = [[bits[k] for k in range(index, len(bits), fold_bits)] for index in range(fold_bits)]
    level = 0
    while any(len(bucket) > 1 for bucket in buckets):
        reduced = []
        for index, bucket in enumerate(buckets):
            next_bucket = []
            for start in range(0, len(bucket), 4):
                register = Signal(name=f"fold_l{level}_{index}_{start // 4}")
                m.d.sync += register.eq(Cat(*bucket[start:start + 4]).xor())
                next_bucket.append(register)
            reduced.append(next_bucket)
        buckets = reduced
        level += 1
    return Cat(*(bucket[0] if bucket else 0 for bucket in buckets))


class MeasurementHarness(wiring.Component):
    """A correlator core with registers on every pin, for place and route only.

    Parameters
    ----------
    core : wiring.Component
        A :class:`~lost.hdl.recursive.RecursiveCore`, :class:`~lost.hdl.window.WindowCore` (with a
        ``map_read`` port, which goes to pins) or a whole correlator with its own map memory.
    scan_bits : int
        Input pins feeding the scan chain of the core's inputs.
    fold_bits : int
        Output pins carrying the XOR fold of the core's outputs.
    global_reset : bool
        Define the ``sync`` domain here, clocked by the ``clk`` pin and reset from the ``reset`` pin
        (placed on :data:`RESET_SITE` by its ``LOC`` attribute) through an ECP5 ``DCCA`` global
        buffer (synthesis only: the simulator knows no ``DCCA``). Without it the domain is the
        caller's, with its ``rst`` port.

    Members
    -------
    scan_in : ``In(scan_bits)``
        Shifted into the chain that drives every core input (``map_read.data`` excepted).
    fold_out : ``Out(fold_bits)``
        The registered XOR fold of every core output (``map_read`` excepted).
    map_addr, map_en : ``Out(...)``
        Only with a ``map_read`` port: its address and enable, registered.
    map_data : ``In(...)``
        Only with a ``map_read`` port: its data, registered before it reaches the core.
    clk, reset : ``In(1)``
        Only with ``global_reset``: the clock pin (``LOC`` :data:`CLOCK_SITE`) and the reset pin
        (``LOC`` :data:`RESET_SITE`).
    """

    def __init__(self, *, core: wiring.Component, scan_bits: int = 4, fold_bits: int = 8, global_reset: bool = False):
        if not isinstance(core, wiring.Component):
            raise ValueError(f"core must be an amaranth wiring.Component, got {type(core).__name__}")
        self._core = core
        self._scan_bits = check_count("scan_bits", scan_bits)
        self._fold_bits = check_count("fold_bits", fold_bits)
        self._global_reset = bool(global_reset)
        members = {"scan_in": In(scan_bits), "fold_out": Out(fold_bits)}
        if self._global_reset:
            members |= {"clk": In(1), "reset": In(1)}
        self._external = "map_read" in core.signature.members
        if self._external:
            port = core.map_read
            members |= {
                "map_addr": Out(len(port.addr)),
                "map_en": Out(1),
                "map_data": In(len(Value.cast(port.data))),
            }
        super().__init__(members)
        if self._global_reset:
            self.clk.attrs["LOC"] = CLOCK_SITE
            self.reset.attrs["LOC"] = RESET_SITE

    @property
    def external_memory(self) -> bool:
        """The core reads its map through pins (``map_read``) rather than an on-chip memory."""
        return self._external

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        m.submodules.core = core = self._core

        if self._global_reset:
            m.domains.sync = sync = ClockDomain("sync")
            m.d.comb += sync.rst.eq(ecp5_global_buffer(m, self.reset))
            m.d.comb += sync.clk.eq(self.clk)

        inputs, outputs = [], []
        for path, member, value in core.signature.flatten(core):
            if path[0] == "map_read":
                continue
            (inputs if member.flow == In else outputs).append(Value.cast(value))

        # The scan chain: registered pins shift into a register per core input bit.
        scan_pins = Signal(self._scan_bits)
        m.d.sync += scan_pins.eq(self.scan_in)
        width = sum(len(value) for value in inputs)
        chain = Signal(max(width, self._scan_bits))
        m.d.sync += chain.eq(Cat(scan_pins, chain[:-self._scan_bits]))
        offset = 0
        for value in inputs:
            m.d.comb += value.eq(chain[offset:offset + len(value)])
            offset += len(value)

        # Every output registered, then folded.
        captured = Signal(sum(len(value) for value in outputs))
        m.d.sync += captured.eq(Cat(*outputs))
        fold = _fold(m, captured, self._fold_bits)
        m.d.sync += self.fold_out.eq(fold)

        if self._external:
            port = core.map_read
            data = Signal.like(Value.cast(port.data), name="map_data_reg")
            m.d.sync += [
                self.map_addr.eq(port.addr),
                self.map_en.eq(port.en),
                data.eq(self.map_data),
            ]
            m.d.comb += port.data.eq(data)
        return m
