"""The device's serial pins, bridged to the host's Unix socket (:mod:`lost.sim.cosim`).

Not a check: the host's driver and the tests check what comes back. Bytes read from the socket are
driven on ``rx`` as 8N1 characters at the device's divisor; characters seen on ``tx`` (sampled at bit
middles) are written to the socket. While nothing is to be sent and the device is not busy, the
bench waits on the socket in wall-clock time (a few ms at a time) rather than burning clocks, then
lets a thousand clocks pass so a frame timeout can still expire. The test ends when the host closes
the socket.
"""

from __future__ import annotations

import json
import os
import select
import socket

import cocotb
from cocotb.clock import Clock
from cocotb.handle import HierarchyObject
from cocotb.triggers import ClockCycles, FallingEdge

IDLE_WAIT_S = 0.005
IDLE_CLOCKS = 1000


async def _transmit_to_host(dut: HierarchyObject, connection: socket.socket, divisor: int, state: dict) -> None:
    while True:
        await FallingEdge(dut.tx)
        state["tx_active"] = True
        await ClockCycles(dut.clk, divisor // 2)
        if int(dut.tx.value):  # a glitch, not a start bit
            state["tx_active"] = False
            continue
        byte = 0
        for k in range(8):
            await ClockCycles(dut.clk, divisor)
            byte |= int(dut.tx.value) << k
        await ClockCycles(dut.clk, divisor)
        connection.sendall(bytes([byte]))
        state["tx_active"] = False


@cocotb.test()
async def serve(dut: HierarchyObject) -> None:
    """Bridge the socket and the pins until the host hangs up."""
    config = json.loads(os.environ["LOST_COSIM_CONFIG"])
    divisor = int(config["divisor"])
    connection = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    connection.connect(os.environ["LOST_COSIM_SOCKET"])
    connection.setblocking(False)
    Clock(dut.clk, 10, unit="ns").start()
    dut.rx.value = 1
    dut.rst.value = 1
    await ClockCycles(dut.clk, 4)
    dut.rst.value = 0
    state = {"tx_active": False}
    cocotb.start_soon(_transmit_to_host(dut, connection, divisor, state))
    while True:
        busy = int(dut.busy.value) or state["tx_active"]
        readable, _, _ = select.select([connection], [], [], 0 if busy else IDLE_WAIT_S)
        if not readable:
            await ClockCycles(dut.clk, 64 if busy else IDLE_CLOCKS)
            continue
        try:
            data = connection.recv(65536)
        except BlockingIOError:
            continue
        if not data:
            break  # the host closed the socket
        for byte in data:
            for bit in (0, *((byte >> k) & 1 for k in range(8)), 1):
                dut.rx.value = bit
                await ClockCycles(dut.clk, divisor)
    connection.close()
