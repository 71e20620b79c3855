"""The cocotb harness on Verilator, proven on a one-register stream (``lost.sim.cocotb.loopback``)."""

from pathlib import Path

from lost.hdl.flow.generate import write_verilog
from lost.sim.cocotb.loopback import Loopback
from lost.sim.verilator import build_and_test, build_folder_lock, lint

BUILD = Path(__file__).resolve().parents[2] / "build" / "sim"


def test_loopback_on_verilator():
    with build_folder_lock(BUILD / "loopback") as folder:
        source = write_verilog(Loopback(), name="loopback", out=folder)
        build_and_test(sources=[source], toplevel="loopback", test_module="lost.sim.cocotb.loopback", build_dir=folder)


def test_lint_passes_amaranth_verilog_and_fails_a_real_warning(tmp_path):
    clean = write_verilog(Loopback(), name="loopback", out=tmp_path / "clean")
    assert lint([clean]) == []
    # An undriven wire is a real -Wall warning that no waiver covers.
    broken = tmp_path / "broken" / "broken.v"
    broken.parent.mkdir()
    broken.write_text("module broken(input wire clk, output wire q);\n"
                      "  wire [3:0] floating;\n  assign q = clk & floating[0];\nendmodule\n")
    assert lint([broken]) == [broken]
