"""The contract every correlator core keeps: payload layouts, parameters and port signature.

Both hardware variants (:mod:`lost.hdl.recursive`, :mod:`lost.hdl.window`) take the same parameters,
present the same ports and emit the same payloads, so a host driver, a testbench or a device top-level
never knows which one it talks to. Everything here is derived from :mod:`lost.model.widths`, so a width
is never written twice.

A struct payload becomes one flat vector in Verilog, first field in the lowest bits;
:func:`encode_payload` and :func:`decode_payload` turn Python values into such vectors and back, for
the Amaranth simulator and the cocotb harness alike.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from amaranth.hdl import Shape, ShapeCastable, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out
from amaranth.utils import bits_for

from lost.model.widths import CorrelatorWidths, correlator_widths, placement_widths

__all__ = [
    "best_fit_payload",
    "comparable_best",
    "BestFitBeat",
    "CorrelatorParameters",
    "PatchWord",
    "StartCommand",
    "SurfaceBeat",
    "checked_parameters",
    "correlator_signature",
    "decode_payload",
    "encode_payload",
]


class PatchWord(data.StructLayout):
    """One patch node: its depth word and its mask bit (``valid``)."""

    def __init__(self, depth_bits: int):
        super().__init__({"depth": signed(depth_bits), "valid": 1})


#: The payload of the ``start`` stream: one beat starts one correlation of the loaded map and patch.
StartCommand = data.StructLayout({"mean_compensation": 1})


class SurfaceBeat(data.StructLayout):
    """Up to ``lanes`` consecutive values of one surface row.

    ``values[0 .. count-1]`` are ``V(i, j), V(i, j+1), ...``; ``count < lanes`` only on a row's last
    beat; ``last`` marks the final beat of the correlation.
    """

    def __init__(self, lanes: int, value_bits: int, row_bits: int, col_bits: int):
        super().__init__({
            "values": data.ArrayLayout(unsigned(value_bits), lanes),
            "count": unsigned(bits_for(lanes)),
            "i": unsigned(row_bits),
            "j": unsigned(col_bits),
            "last": 1,
        })


class BestFitBeat(data.StructLayout):
    """The best fit and the runner-up, with the semantics of :func:`lost.model.best_fit`."""

    def __init__(self, value_bits: int, row_bits: int, col_bits: int):
        super().__init__({
            "value": unsigned(value_bits),
            "i": unsigned(row_bits),
            "j": unsigned(col_bits),
            "runner_up_value": unsigned(value_bits),
            "runner_up_i": unsigned(row_bits),
            "runner_up_j": unsigned(col_bits),
            "runner_up_valid": 1,
        })


def _check_shape(name: str, shape: Any) -> tuple[int, int]:
    if (not isinstance(shape, Sequence) or len(shape) != 2
            or not all(isinstance(side, int) and not isinstance(side, bool) and side >= 1 for side in shape)):
        raise ValueError(f"{name} must be a pair of positive integers (rows, columns), got {shape!r}")
    return int(shape[0]), int(shape[1])


def _check_count(name: str, value: Any, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise ValueError(f"{name} must be an integer of at least {minimum}, got {value!r}")
    return value


@dataclass(frozen=True)
class CorrelatorParameters:
    """The validated parameters of a correlator core and every width derived from them.

    Parameters
    ----------
    map_shape : (int, int)
        ``(H, W)``, the terrain map the core stores.
    patch_shape : (int, int)
        ``(h, w)``, the sonar patch; no larger than the map.
    depth_bits : int
        Width of a depth word (two's complement).
    lanes : int
        Surface values per beat (the recursive core has one).
    exclusion_radius : int
        Chebyshev radius around the best fit that the runner-up is searched outside of.

    Raises
    ------
    ValueError
        A shape that is not a pair of positive integers, a patch larger than the map, fewer than two
        depth bits, fewer than one lane, a negative exclusion radius.
    """

    map_shape: tuple[int, int]
    patch_shape: tuple[int, int]
    depth_bits: int = 16
    lanes: int = 1
    exclusion_radius: int = 1

    def __post_init__(self):
        map_shape = _check_shape("map_shape", self.map_shape)
        patch_shape = _check_shape("patch_shape", self.patch_shape)
        if patch_shape[0] > map_shape[0] or patch_shape[1] > map_shape[1]:
            raise ValueError(f"The patch of shape {patch_shape} is larger than the map of shape {map_shape}.")
        object.__setattr__(self, "map_shape", map_shape)
        object.__setattr__(self, "patch_shape", patch_shape)
        _check_count("depth_bits", self.depth_bits, 2)
        _check_count("lanes", self.lanes, 1)
        _check_count("exclusion_radius", self.exclusion_radius, 0)

    @property
    def widths(self) -> CorrelatorWidths:
        """Bounds of every intermediate (:func:`lost.model.correlator_widths`)."""
        return correlator_widths(*self.patch_shape, self.depth_bits)

    @property
    def surface_shape(self) -> tuple[int, int]:
        """``(H - h + 1, W - w + 1)``, the number of placements along each axis."""
        (H, W), (h, w) = self.map_shape, self.patch_shape
        return H - h + 1, W - w + 1

    @property
    def value_bits(self) -> int:
        return self.widths.accumulator.bits

    @property
    def row_bits(self) -> int:
        return placement_widths(self.map_shape, self.patch_shape)[0]

    @property
    def col_bits(self) -> int:
        return placement_widths(self.map_shape, self.patch_shape)[1]

    @property
    def patch_word(self) -> PatchWord:
        return PatchWord(self.depth_bits)

    @property
    def surface_beat(self) -> SurfaceBeat:
        return SurfaceBeat(self.lanes, self.value_bits, self.row_bits, self.col_bits)

    @property
    def best_fit_beat(self) -> BestFitBeat:
        return BestFitBeat(self.value_bits, self.row_bits, self.col_bits)


def checked_parameters(parameters: Any) -> CorrelatorParameters:
    """``parameters`` if it is a :class:`CorrelatorParameters`, else a ``ValueError`` saying what it is."""
    if not isinstance(parameters, CorrelatorParameters):
        raise ValueError(f"parameters must be a CorrelatorParameters, got {parameters!r}")
    return parameters


def correlator_signature(parameters: CorrelatorParameters) -> dict[str, wiring.Member]:
    """The ports of a correlator core, as the member dict of a :class:`wiring.Signature`.

    Members
    -------
    map_in : ``In(stream.Signature(signed(depth_bits)))``
        ``H * W`` map words in raster order, accepted only while idle.
    patch_in : ``In(stream.Signature(PatchWord(depth_bits)))``
        ``h * w`` patch words in raster order, accepted only while idle.
    start : ``In(stream.Signature(StartCommand))``
        One beat starts a correlation of the loaded map and patch.
    surface : ``Out(stream.Signature(SurfaceBeat(...)))``
        The surface, in raster order.
    best : ``Out(stream.Signature(BestFitBeat(...)))``
        One beat after the surface's last beat.
    busy : ``Out(1)``
        A correlation is under way.
    """
    return {
        "map_in": In(stream.Signature(signed(parameters.depth_bits))),
        "patch_in": In(stream.Signature(parameters.patch_word)),
        "start": In(stream.Signature(StartCommand)),
        "surface": Out(stream.Signature(parameters.surface_beat)),
        "best": Out(stream.Signature(parameters.best_fit_beat)),
        "busy": Out(1),
    }


def encode_payload(shape: Any, value: Any) -> int:
    """The bit pattern of a payload: a layout from a (nested) mapping or sequence, a plain shape from an int.

    Raises
    ------
    ValueError
        A value that does not fit its field.
    """
    if isinstance(shape, ShapeCastable):
        layout = data.Layout.cast(shape)
        if isinstance(value, Mapping):
            items = value.items()
        elif isinstance(value, Sequence):
            items = enumerate(value)
        else:
            raise ValueError(f"A payload of layout {layout!r} needs a mapping or a sequence, got {value!r}")
        bits = 0
        for key, field_value in items:
            field = layout[key]
            bits |= encode_payload(field.shape, field_value) << field.offset
        return bits
    plain = Shape.cast(shape)
    lo = -(1 << (plain.width - 1)) if plain.signed else 0
    hi = (1 << (plain.width - 1)) - 1 if plain.signed else (1 << plain.width) - 1
    if isinstance(value, bool):
        value = int(value)
    if not lo <= int(value) <= hi:
        raise ValueError(f"The value {value} does not fit a field of shape {plain!r}")
    return int(value) & ((1 << plain.width) - 1)


def decode_payload(shape: Any, bits: int) -> Any:
    """The Python value of a payload's bit pattern: a dict (struct), a list (array) or an int."""
    if isinstance(shape, ShapeCastable):
        layout = data.Layout.cast(shape)
        decoded = [(key, decode_payload(field.shape, (bits >> field.offset) & ((1 << field.width) - 1)))
                   for key, field in layout]
        if isinstance(layout, data.ArrayLayout):
            return [value for _, value in decoded]
        return dict(decoded)
    plain = Shape.cast(shape)
    bits &= (1 << plain.width) - 1
    if plain.signed and bits >> (plain.width - 1):
        bits -= 1 << plain.width
    return bits


def best_fit_payload(fit: Any) -> dict[str, int | None]:
    """The ``BestFitBeat`` a core must emit for a :class:`lost.model.BestFit`.

    Without a runner-up only ``runner_up_valid = 0`` is specified; the other runner-up fields are
    ``None`` then, as :func:`comparable_best` makes them in a received beat.
    """
    runner_up = fit.runner_up
    return {
        "value": fit.value,
        "i": fit.i,
        "j": fit.j,
        "runner_up_value": runner_up.value if runner_up else None,
        "runner_up_i": runner_up.i if runner_up else None,
        "runner_up_j": runner_up.j if runner_up else None,
        "runner_up_valid": int(runner_up is not None),
    }


def comparable_best(beat: Mapping[str, Any]) -> dict[str, Any]:
    """A received ``BestFitBeat`` with its unspecified fields (runner-up, when it has none) as ``None``."""
    beat = dict(beat)
    if not beat["runner_up_valid"]:
        beat.update(runner_up_value=None, runner_up_i=None, runner_up_j=None)
    return beat
