"""cocotb 2 benches of the generated Verilog, run on Verilator by ``tests/sim`` (``lost.sim.verilator``).

``streams`` holds the stream source and sink and the payload codec (from the Amaranth layouts);
``loopback`` proves that harness on a one-register stream; ``correlator`` checks either correlator
variant bit for bit and cycle for cycle against ``lost.model``; ``device`` bridges the device
top-level's UART pins to the host's co-simulation transport (:mod:`lost.sim.cosim`).
"""
