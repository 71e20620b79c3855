"""``lost.hdl.flow.generate``: the Verilog text of a variant, and its compacted memory initializers."""

import re

import pytest
from amaranth.hdl import Module, unsigned
from amaranth.lib import memory, wiring
from amaranth.lib.wiring import In, Out

from lost.hdl.flow.generate import compact_zero_initializers, main, to_verilog
from lost.model.variants import VARIANTS, variant
from lost.sim.verilator import lint


class _Rom(wiring.Component):
    addr: In(unsigned(6))
    data: Out(unsigned(12))

    def __init__(self, init):
        self._init = init
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        m.submodules.storage = storage = memory.Memory(shape=unsigned(12), depth=40, init=self._init)
        port = storage.read_port()
        m.d.comb += [port.addr.eq(self.addr), self.data.eq(port.data)]
        return m


def _elements(text):
    return re.findall(r"^    \S+\[\d+\] = ", text, re.MULTILINE)


def test_an_all_zero_memory_becomes_one_loop():
    raw = compact_zero_initializers("")  # nothing to do on an empty text
    assert raw == ""
    text = to_verilog(_Rom([]), name="rom")
    assert _elements(text) == []
    assert re.search(r"for \(lost_zero_init_0 = 0; lost_zero_init_0 < 40; ", text)
    assert "storage[lost_zero_init_0] = 12'h0;" in text


def test_a_memory_with_contents_keeps_its_initializer():
    text = to_verilog(_Rom([0, 0, 7]), name="rom")
    assert "lost_zero_init" not in text
    assert len(_elements(text)) == 40


def test_the_loop_passes_lint(tmp_path):
    path = tmp_path / "rom.v"
    path.write_text(to_verilog(_Rom([]), name="rom"))
    assert lint([path]) == []


def test_unknown_variant_is_refused_by_name():
    with pytest.raises(ValueError, match="unknown correlator variant 'cordic'.*recursive_correlator"):
        variant("cordic")
    assert set(VARIANTS) == {"recursive_correlator", "window_correlator_l1", "window_correlator_l4"}


def test_command_line_refuses_a_malformed_shape(capsys):
    with pytest.raises(SystemExit):
        main(["--map", "501by501"])
    assert "expected ROWSxCOLS" in capsys.readouterr().err
