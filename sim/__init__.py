"""Running the gateware: Amaranth simulator helpers, cocotb benches, the Verilator runner."""
