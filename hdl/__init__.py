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

__all__ = [
    "BestFitBeat",
    "CorrelatorParameters",
    "PatchWord",
    "StartCommand",
    "SurfaceBeat",
    "correlator_signature",
    "decode_payload",
    "encode_payload",
]
