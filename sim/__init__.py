"""Running the gateware: Amaranth simulator testbench functions, cocotb benches, the Verilator runner."""
