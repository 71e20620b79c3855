# amaranth: UnusedElaboratable=no
"""The ECP5 product block: one MULT18X18D whose input registers hold the operands, as the generic block's two do."""

import re

import pytest
from amaranth.back import rtlil

from lost.hdl.flow.harness import ECP5_MULTIPLIER_BITS, ECP5RegisteredProduct
from lost.hdl.flow.synth import Configuration


def _cells(text: str, kind: str) -> list[str]:
    return re.findall(r"cell \\" + kind + r" .*?\n  end\n", text, flags=re.S)


def test_the_operands_enter_the_multipliers_input_registers_on_the_clock():
    dut = ECP5RegisteredProduct(7, 18)
    assert dut.p.shape().width == 25
    (cell,) = _cells(rtlil.convert(dut, name="top"), "MULT18X18D")
    for operand in "AB":
        assert re.search(rf'parameter \\REG_INPUT{operand}_CLK "CLK0"', cell)
        assert re.search(rf'parameter \\REG_INPUT{operand}_CE "CE0"', cell)
    # No register after the product (the lane's partial product is a fabric register), none reset by GSR.
    assert re.search(r'parameter \\REG_OUTPUT_CLK "NONE"', cell) and re.search(r'parameter \\REG_PIPELINE_CLK "NONE"', cell)
    assert re.search(r'parameter \\GSR "DISABLED"', cell)
    assert re.search(r"connect \\CLK0 \\clk", cell)
    assert re.search(r"connect \\CE0 1'1", cell) and re.search(r"connect \\RST0 1'0", cell)
    assert re.search(r"connect \\SIGNEDA 1'0", cell) and re.search(r"connect \\SIGNEDB 1'0", cell)
    # a's 7 bits, then zeros up to the multiplier's 18.
    assert re.search(r"connect \\A6 \\a \[6\]", cell) and re.search(r"connect \\A7 1'0", cell)
    assert re.search(r"connect \\B17 \\b \[17\]", cell)


def test_operands_wider_than_the_multiplier_are_refused():
    with pytest.raises(ValueError, match="18 bits at most, got 19 x 7"):
        ECP5RegisteredProduct(ECP5_MULTIPLIER_BITS + 1, 7)


def test_the_flow_builds_each_lanes_value_products_on_ecp5_multipliers():
    # 12 x 12 / 3 x 4 at 2 lanes: each lane's f * P' and K * N, P' and N over 18 bits (12 nodes of up to
    # 2**17 - 1): two pieces of each, one multiplier a piece.
    config = Configuration("window", lanes=2, map_shape=(12, 12), patch_shape=(3, 4))
    text = rtlil.convert(config.core(), name="top")
    assert len(_cells(text, "MULT18X18D")) == 2 * (2 + 2)
