"""The correlator contract: parameters, derived widths, ports and the payload codec."""

import pytest
from amaranth.hdl import signed
from amaranth.lib import data

from lost.hdl.interface import (
    BestFitBeat,
    CorrelatorParameters,
    PatchWord,
    StartCommand,
    SurfaceBeat,
    correlator_signature,
    decode_payload,
    encode_payload,
)
from lost.model import correlator_widths, placement_widths


def test_widths_come_from_the_model():
    p = CorrelatorParameters(map_shape=(501, 501), patch_shape=(10, 10), lanes=4)
    assert p.value_bits == correlator_widths(10, 10).accumulator.bits == 30
    assert (p.row_bits, p.col_bits) == placement_widths((501, 501), (10, 10))
    assert p.surface_shape == (492, 492)
    assert p.surface_beat == SurfaceBeat(4, 30, 9, 9)
    assert p.best_fit_beat == BestFitBeat(30, 9, 9)
    assert p.patch_word == PatchWord(16)


def test_signature_members():
    members = correlator_signature(CorrelatorParameters(map_shape=(8, 8), patch_shape=(3, 3)))
    assert set(members) == {"map_in", "patch_in", "start", "surface", "best", "busy"}
    assert members["map_in"].signature.members["payload"].shape == signed(16)
    assert members["start"].signature.members["payload"].shape == StartCommand


def test_first_field_in_the_lowest_bits():
    layout = PatchWord(16)
    assert encode_payload(layout, {"depth": -1, "valid": 0}) == 0xFFFF
    assert encode_payload(layout, {"depth": 0, "valid": 1}) == 1 << 16
    beat = SurfaceBeat(3, 5, 2, 3)
    value = {"values": [1, 31, 7], "count": 2, "i": 3, "j": 5, "last": 1}
    bits = encode_payload(beat, value)
    assert bits & 0x1F == 1 and (bits >> 5) & 0x1F == 31
    assert decode_payload(beat, bits) == value
    # The same bits as Amaranth's own constant of the layout.
    assert data.Layout.cast(beat).const(value).as_bits() == bits


def test_codec_refuses_values_that_do_not_fit():
    with pytest.raises(ValueError, match="does not fit"):
        encode_payload(PatchWord(8), {"depth": 128, "valid": 1})
    with pytest.raises(ValueError, match="mapping or a sequence"):
        encode_payload(PatchWord(8), 5)


@pytest.mark.parametrize(("kwargs", "message"), [
    (dict(map_shape=(4,), patch_shape=(2, 2)), "map_shape"),
    (dict(map_shape=(4, 4), patch_shape=(0, 2)), "patch_shape"),
    (dict(map_shape=(4, 4), patch_shape=(5, 2)), "larger than the map"),
    (dict(map_shape=(4, 4), patch_shape=(2, 2), depth_bits=1), "depth_bits"),
    (dict(map_shape=(4, 4), patch_shape=(2, 2), lanes=0), "lanes"),
    (dict(map_shape=(4, 4), patch_shape=(2, 2), exclusion_radius=True), "exclusion_radius"),
])
def test_parameters_refuse_bad_values(kwargs, message):
    with pytest.raises(ValueError, match=message):
        CorrelatorParameters(**kwargs)
