"""Tooling beside the gateware: Verilog generation, the measurement harness, synthesis and the bitstream.

Nothing here is gateware the correlator is made of. :mod:`.generate` writes the Verilog the Verilator
benches and lint read; :mod:`.harness` brings a core to a few pins for place and route and holds the
ECP5-specific buffers the builds supply to the cores; :mod:`.synth` runs the open ECP5 flow (Yosys,
nextpnr) over every configuration and keeps its figures (:mod:`.figures`); :mod:`.bitstream` builds the
device for the ULX3S. Each module with a command line runs as ``python -m lost.hdl.flow.<name>``.
"""
