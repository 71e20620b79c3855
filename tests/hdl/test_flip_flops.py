# amaranth: UnusedElaboratable=no
"""The flip-flop diet's blocks against NumPy models: the block-RAM delay line, the window with its
middle in block RAM, and adder trees with two adder levels between registers."""

import numpy as np
import pytest

from lost.hdl.blocks import MemoryDelayLine, shape_for

from .test_blocks import check_adder_tree, loads_model, run


@pytest.mark.parametrize("depth, load_rate", [(3, 1.0), (3, 0.6), (4, 0.5), (17, 0.9), (17, 1.0), (6, 0.3)])
def test_memory_delay_line_is_the_input_of_depth_loads_before(depth, load_rate):
    cycles = 120
    rng = np.random.default_rng([depth, int(load_rate * 10)])
    values = rng.integers(-(2**15), 2**15, cycles).tolist()
    # Runs of consecutive loads and of idle clocks both occur at these rates.
    enables = (rng.random(cycles) < load_rate).tolist()
    dut = MemoryDelayLine(shape_for(-(2**15), 2**15 - 1), depth)
    assert dut.entries >= depth - 1

    def drive(ctx, t):
        ctx.set(dut.i, values[t])
        ctx.set(dut.en, enables[t])

    seen = run(dut, cycles, drive, lambda ctx, t: ctx.get(dut.o))
    assert sum(enables) > 2 * depth
    # From reset on, zero before ``depth`` loads as a register chain's.
    assert seen == loads_model(values, enables, depth)


def test_memory_delay_line_refuses_a_short_delay():
    with pytest.raises(ValueError, match="depth must be an integer of at least 3"):
        MemoryDelayLine(8, 2)


@pytest.mark.parametrize("lanes, width, rows, pattern, stored", [
    (2, 4, 3, [1, 0, 1], range(1, 4)), (1, 5, 2, [1], range(2, 5)), (3, 4, 4, [1, 1, 0], range(1, 3)),
    (1, 3, 3, [1, 1, 1, 0, 0], range(1, 5)),
])
def test_step_window_with_stored_steps_holds_each_steps_columns(lanes, width, rows, pattern, stored):
    from lost.hdl.window_columns import StepWindow

    groups = -(-width // lanes)
    span = 6 * lanes
    height = rows + 4
    dut = StepWindow(lanes=lanes, rows=rows, groups=groups, span=span, depth_bits=16, stored=stored)
    kept = [c for c in range(span) if not stored.start * lanes <= c < stored.stop * lanes]
    assert len(dut.columns) == len(kept) == span - len(stored) * lanes
    terrain = np.random.default_rng(lanes).integers(-(2**15), 2**15, size=(height, groups * lanes)).astype(np.int16)
    steps = height * groups
    checked = set()

    def drive(ctx, c):
        r, g = divmod(drive.taken, groups)
        advance = bool(pattern[c % len(pattern)]) and drive.taken < steps
        for q in range(lanes):
            ctx.set(dut.word[q], int(terrain[r % height, g * lanes + q]))
        ctx.set(dut.group, g)
        ctx.set(dut.next_group, (g + 1) % groups)
        ctx.set(dut.is_word, 1)
        ctx.set(dut.advance, advance)
        drive.taken += advance

    drive.taken = 0

    def sample(ctx, c):
        # After the edge of step ``taken - 1``, step ``taken - 2 - a`` is ``a`` steps of L columns from the right.
        for port, column in enumerate(kept):
            a, q = divmod(span - 1 - column, lanes)
            q = lanes - 1 - q
            step = drive.taken - 2 - a
            r, g = divmod(step, groups)
            if step < 0 or r < rows - 1:
                continue  # the line buffers do not hold rows above the map yet
            assert [ctx.get(dut.columns[port][k]) for k in range(rows)] == \
                terrain[r - rows + 1:r + 1, g * lanes + q].tolist(), (step, column)
            checked.add((step, column))

    run(dut, 3 * steps, drive, sample)
    # Every kept column has shown a step of every map row below the first rows - 1.
    assert {column for _, column in checked} == set(kept)
    assert len({step for step, _ in checked}) >= steps - (rows - 1) * groups - span // lanes - 1


def test_step_window_refuses_stored_steps_it_cannot_hold():
    from lost.hdl.window_columns import StepWindow

    for stored in (range(0, 3), range(1, 2), range(2, 6), range(1, 5, 2)):
        with pytest.raises(ValueError, match="stored must be a range of at least two steps"):
            StepWindow(lanes=2, rows=3, groups=2, span=12, depth_bits=16, stored=stored)


@pytest.mark.parametrize("count, leaf, enable, every", [
    (100, (-(2**15), 2**15 - 1), True, 2), (100, (0, 2**17 - 1), False, 2), (100, (0, 1), False, 2),
    (5, (-100, 100), True, 2), (17, (0, 7), False, 3), (2, (0, 1), False, 2), (1, (-8, 7), True, 2),
])
def test_adder_tree_with_adders_between_registers_keeps_its_latency(count, leaf, enable, every):
    from lost.hdl.blocks import AdderTree, tree_levels

    rng = np.random.default_rng([count, every])
    cycles = 40
    leaves = rng.integers(leaf[0], leaf[1] + 1, size=(cycles, count))
    enables = (rng.random(cycles) < 0.5).tolist() if enable else [True] * cycles
    dut = AdderTree(count=count, leaf=leaf, total=(count * leaf[0], count * leaf[1]), enable=enable,
                    adders_per_register=every)
    assert dut.latency == tree_levels(count)
    registered = dut.registered_levels
    if registered:
        # The root and every ``every``-th level are registers: ``every`` adders at most between two.
        assert registered[-1] and sum(registered) == -(-len(registered) // every)
        assert all(any(registered[level:level + every]) for level in range(len(registered)))
    check_adder_tree(dut, leaves, enables, enable)


def synthesized_cells(design, name, out_dir):
    """Cells by type of the flow's ``synth_ecp5`` netlist of ``design`` (a few seconds)."""
    import json
    from collections import Counter

    from lost.hdl.flow.pnr import synthesize

    netlist = json.loads(synthesize(design, name, out_dir).read_text())
    return Counter(cell["type"] for cell in netlist["modules"]["top"]["cells"].values())


@pytest.mark.fpga  # Yosys comes with the fpga extra (`make synth`), not with `make test`
def test_a_tree_with_two_adders_between_registers_keeps_one_carry_chain_per_adder(tmp_path):
    from lost.hdl.blocks import AdderTree

    leaf, count = (0, 2**17 - 1), 100
    every = {k: synthesized_cells(AdderTree(count=count, leaf=leaf, total=(0, count * leaf[1]), adders_per_register=k),
                                  f"tree{k}", tmp_path) for k in (1, 2)}
    # The same carry chains (no adders merged into LUT compressor trees), far fewer flip-flops.
    assert every[2]["CCU2C"] == every[1]["CCU2C"] and every[2]["LUT4"] <= every[1]["LUT4"]
    assert every[2]["TRELLIS_FF"] < 0.45 * every[1]["TRELLIS_FF"]


@pytest.mark.fpga
def test_a_memory_delay_line_is_block_ram_and_its_two_registers(tmp_path):
    from amaranth.hdl import signed
    from amaranth.lib import data

    cells = synthesized_cells(MemoryDelayLine(data.ArrayLayout(signed(16), 10), 17), "delay", tmp_path)
    # 160 bits of 18 a block (one port's width): 9; the fetched word (inside the block RAM), the output
    # register and a 4-bit pointer; no read-before-write emulation (a register and a multiplexer per bit).
    assert cells["DP16KD"] == 9
    assert cells["TRELLIS_FF"] <= 160 + 4 and cells["LUT4"] <= 8
