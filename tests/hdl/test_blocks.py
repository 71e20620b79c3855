# amaranth: UnusedElaboratable=no
"""lost.hdl.blocks against NumPy models: every output, at the latency each block's docstring states."""

import numpy as np
import pytest
from amaranth.hdl import ClockDomain, Module, unsigned
from amaranth.sim import Simulator

from lost.hdl.blocks import AdderTree, DelayLine, MinimumTree, RegisteredProduct, Replicas, shape_for, tree_levels


def simulate(dut, bench):
    """Run the testbench ``bench`` against ``dut`` on a 100 MHz clock."""
    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()


def run(dut, cycles, drive, sample):
    """Clock ``dut`` for ``cycles``: ``drive(ctx, t)`` before each edge, ``sample(ctx, t)`` after it."""
    seen = []

    async def bench(ctx):
        for t in range(cycles):
            drive(ctx, t)
            await ctx.tick()
            seen.append(sample(ctx, t))

    top = Module()
    top.domains.sync = ClockDomain()  # a one-leaf tree is a wire, with no domain of its own
    top.submodules.dut = dut
    simulate(top, bench)
    return seen


def loads_model(values, enables, depth):
    """After each edge: what a register chain of ``depth`` that loads on ``enables`` holds at its end."""
    chain, out = [0] * depth, []
    for value, enable in zip(values, enables):
        if enable and depth:
            chain = [value, *chain[:-1]]
        out.append(chain[-1] if depth else None)
    return out


@pytest.mark.parametrize("depth, enable", [(1, False), (4, False), (3, True)])
def test_delay_line_has_its_depth_in_loads(depth, enable):
    rng = np.random.default_rng(depth)
    values = rng.integers(-128, 128, 60).tolist()
    enables = (rng.random(60) < 0.6).tolist() if enable else [True] * 60
    dut = DelayLine(shape_for(-128, 127), depth, enable=enable)

    def drive(ctx, t):
        ctx.set(dut.i, values[t])
        if enable:
            ctx.set(dut.en, enables[t])

    seen = run(dut, 60, drive, lambda ctx, t: (ctx.get(dut.o), ctx.get(dut.taps[0])))
    assert [o for o, _ in seen] == loads_model(values, enables, depth)
    assert [first for _, first in seen] == loads_model(values, enables, 1)


def test_delay_line_of_depth_zero_is_a_wire():
    dut = DelayLine(8, 0)
    assert "taps" not in dut.signature.members

    async def bench(ctx):
        ctx.set(dut.i, 77)
        assert ctx.get(dut.o) == 77

    sim = Simulator(dut)
    sim.add_testbench(bench)
    sim.run()


@pytest.mark.parametrize("count, leaf, enable", [
    (1, (-8, 7), False), (2, (0, 1), False), (5, (-100, 100), False), (100, (-(2**15), 2**15 - 1), True),
    (17, (0, 2**17 - 1), False),
])
def test_adder_tree_sums_after_its_levels(count, leaf, enable):
    rng = np.random.default_rng(count)
    cycles = 40
    leaves = rng.integers(leaf[0], leaf[1] + 1, size=(cycles, count))
    enables = (rng.random(cycles) < 0.5).tolist() if enable else [True] * cycles
    dut = AdderTree(count=count, leaf=leaf, total=(count * leaf[0], count * leaf[1]), enable=enable)
    assert dut.latency == tree_levels(count) == int(np.ceil(np.log2(count)))
    check_adder_tree(dut, leaves, enables, enable)


@pytest.mark.parametrize("count, adders_per_register", [(2, 1), (5, 1), (100, 2), (20, 2), (12, 3)])
def test_adder_tree_may_leave_its_last_register_to_the_consumer(count, adders_per_register):
    rng = np.random.default_rng(count)
    leaves = rng.integers(0, 2**8, size=(40, count))
    enables = (rng.random(40) < 0.6).tolist()
    kept = AdderTree(count=count, leaf=(0, 2**8 - 1), total=(0, count * (2**8 - 1)), enable=True,
                     adders_per_register=adders_per_register)
    dut = AdderTree(count=count, leaf=(0, 2**8 - 1), total=(0, count * (2**8 - 1)), enable=True,
                    adders_per_register=adders_per_register, registered_sum=False)
    assert dut.latency == kept.latency - 1
    check_adder_tree(dut, leaves, enables, enable=True)


def test_registered_product_multiplies_its_operands_a_clock_later():
    rng = np.random.default_rng(7)
    a_values, b_values = rng.integers(0, 2**7, size=30).tolist(), rng.integers(0, 2**18, size=30).tolist()
    a_values[:2], b_values[:2] = [2**7 - 1, 0], [2**18 - 1, 2**18 - 1]  # the largest product, and zero
    dut = RegisteredProduct(7, 18)
    assert dut.p.shape() == unsigned(25)

    def drive(ctx, t):
        ctx.set(dut.a, a_values[t])
        ctx.set(dut.b, b_values[t])

    # Sampled after the edge that loads the operands' registers: the product of the values driven before it.
    seen = run(dut, len(a_values), drive, lambda ctx, t: ctx.get(dut.p))
    assert seen == [a * b for a, b in zip(a_values, b_values)]


def check_adder_tree(dut: AdderTree, leaves: np.ndarray, enables: list[bool], enable: bool) -> None:
    """The tree's sum, clock by clock, against the leaves' sums through its latency's enabled registers."""
    count = leaves.shape[1]

    def drive(ctx, t):
        for k in range(count):
            ctx.set(dut.leaves[k], int(leaves[t, k]))
        if enable:
            ctx.set(dut.en, enables[t])

    seen = run(dut, len(leaves), drive, lambda ctx, t: ctx.get(dut.sum))
    sums = leaves.sum(axis=1).tolist()
    if dut.latency == 0:
        # A single leaf passes through: sampled after the edge, it is the value driven before it.
        assert seen == sums
    else:
        expected = loads_model(sums, enables, dut.latency)
        assert seen[dut.latency:] == expected[dut.latency:]


def test_adder_tree_registers_are_no_wider_than_the_total():
    # Ten leaves in [0, 1] summing to at most 10 (a count), not 16 at the last level.
    dut = AdderTree(count=10, leaf=(0, 1), total=(0, 10))
    assert [shape.width for shape in dut.level_shapes] == [2, 3, 4, 4]


@pytest.mark.parametrize("count, payload", [(1, True), (3, True), (4, False), (7, True), (16, True)])
def test_minimum_tree_takes_the_first_smallest_valid_leaf(count, payload):
    rng = np.random.default_rng(count)
    cycles = 50
    # Few distinct keys, so ties are common; some cycles have no valid leaf at all.
    keys = rng.integers(0, 4, size=(cycles, count))
    valid = rng.random((cycles, count)) < np.where(np.arange(cycles) % 7 == 0, 0.0, 0.6)[:, None]
    dut = MinimumTree(count=count, key=shape_for(0, 3), payload=shape_for(0, count) if payload else None)

    def drive(ctx, t):
        for k in range(count):
            ctx.set(dut.leaves[k].valid, bool(valid[t, k]))
            ctx.set(dut.leaves[k].key, int(keys[t, k]))
            if payload:
                ctx.set(dut.leaves[k].payload, k)

    def sample(ctx, t):
        root = dut.root
        return (ctx.get(root.valid), ctx.get(root.key), ctx.get(root.payload) if payload else None)

    seen = run(dut, cycles, drive, sample)
    latency = dut.latency
    for t in range(latency, cycles):
        source = t - latency + 1 if latency else t  # sampled after the edge that loads the root
        candidates = np.flatnonzero(valid[source])
        if candidates.size == 0:
            assert not seen[t][0]
            continue
        winner = candidates[np.argmin(keys[source, candidates])]  # argmin: the first of equal keys
        assert seen[t][:2] == (1, keys[source, winner])
        if payload:
            assert seen[t][2] == winner


def test_replicas_copy_their_input_one_clock_later():
    dut = Replicas(shape_for(0, 255), 3, init=1)
    values = list(range(3, 40, 3))
    seen = run(dut, len(values), lambda ctx, t: ctx.set(dut.i, values[t]),
               lambda ctx, t: [ctx.get(dut.o[k]) for k in range(3)])
    assert seen == [[v] * 3 for v in values]


def test_reset_values_and_parameter_errors():
    async def bench(ctx):
        assert [ctx.get(dut.o[k]) for k in range(2)] == [1, 1]

    dut = Replicas(1, 2, init=1)
    sim = Simulator(dut)
    sim.add_testbench(bench)
    sim.run()
    with pytest.raises(ValueError, match="count must be a positive integer"):
        AdderTree(count=0, leaf=(0, 1), total=(0, 0))
    with pytest.raises(ValueError, match="no register to leave out"):
        AdderTree(count=1, leaf=(0, 1), total=(0, 1), registered_sum=False)
    with pytest.raises(ValueError, match="b_bits must be a positive integer"):
        RegisteredProduct(4, 0)
    with pytest.raises(ValueError, match="depth must be a non-negative integer"):
        DelayLine(4, -1)
