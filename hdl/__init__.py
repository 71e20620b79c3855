"""Amaranth gateware of the correlator (the HDL issue)."""

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
