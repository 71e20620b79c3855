"""Amaranth gateware of the correlator: the cores, their components and the shared pipeline blocks.

The tooling beside it (Verilog generation, the measurement harness, synthesis, the figures, the
bitstream) is :mod:`lost.hdl.flow`; the component map with each latency and test is ``docs/fpga.md``.
"""

from .interface import (
    BestFitBeat,
    CorrelatorParameters,
    PatchWord,
    StartCommand,
    SurfaceBeat,
    correlator_signature,
    decode_payload,
    encode_payload,
)
from .recursive import RecursiveCore, RecursiveCorrelator
from .reducer import BestFitReducer
from .sequencer import MapSequencer
from .window import WindowCore, WindowCorrelator

__all__ = [
    "BestFitBeat",
    "BestFitReducer",
    "CorrelatorParameters",
    "MapSequencer",
    "PatchWord",
    "RecursiveCore",
    "RecursiveCorrelator",
    "StartCommand",
    "SurfaceBeat",
    "WindowCore",
    "WindowCorrelator",
    "correlator_signature",
    "decode_payload",
    "encode_payload",
]
