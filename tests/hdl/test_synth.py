# amaranth: UnusedElaboratable=no
# (the bad-argument tests build a design that the flow rightly refuses to use)
import pytest
from amaranth import Module, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import Out

from lost.hdl.synth import FlowError, parse_nextpnr_report, place_and_route


class Counter(wiring.Component):
    count: Out(8)

    def elaborate(self, platform):
        m = Module()
        value = Signal(8)
        m.d.sync += value.eq(value + 1)
        m.d.comb += self.count.eq(value)
        return m


@pytest.mark.fpga
def test_a_counter_routes_on_the_85f(tmp_path):
    result = place_and_route(Counter(), "counter", tmp_path, target_mhz=100, seed=3)
    assert result.device == "LFE5U-85F" and result.seed == 3
    assert result.ff == 8
    assert 0 < result.lut4 < 40
    assert result.fmax_mhz > 100 and result.met
    assert (result.ebr, result.dsp) == (0, 0)
    assert result.lut4_available == 83640 and result.ebr_available == 208
    assert (tmp_path / "counter-report.json").exists()


def test_report_without_a_clock_is_named():
    with pytest.raises(FlowError, match="no clock"):
        parse_nextpnr_report({"fmax": {}, "utilization": {}})


def test_report_with_several_clocks_needs_a_name():
    report = {"fmax": {"a": {"achieved": 100.0}, "b": {"achieved": 50.0}},
              "utilization": {"TRELLIS_FF": {"used": 3, "available": 10}}}
    with pytest.raises(FlowError, match="several clocks"):
        parse_nextpnr_report(report)
    figures = parse_nextpnr_report(report, clock="b")
    assert figures["fmax_mhz"] == 50.0 and figures["ff"] == 3 and figures["ebr"] == 0


def test_bad_target_is_named(tmp_path):
    with pytest.raises(ValueError, match="target_mhz"):
        place_and_route(Counter(), "counter", tmp_path, target_mhz=0)
