"""lost.model.protocol: the frame codec the driver, the reference device and the gateware's tests share."""

import random

import numpy as np
import pytest

from lost.model.device import reference_info
from lost.model.protocol import MAX_PAYLOAD, MAX_REPLY, DeviceInfo, ErrorCode, FrameDecoder, Result, crc16, encode_frame, parse_patch_payload, patch_payload


def test_crc_is_ccitt_false():
    assert crc16(b"123456789") == 0x29B1 and crc16(b"") == 0xFFFF


@pytest.mark.parametrize("chunk", [1, 3, 7, 100, 100_000])
def test_frames_between_garbage_decode_in_any_chunking(chunk):
    rng = random.Random(1)
    frames = [encode_frame(rng.randrange(256), rng.randrange(256), bytes(rng.randrange(256) for _ in range(n))) for n in (0, 1, 5, 300, 5000)]
    stream = b"".join(b"\x00\x13" + f for f in frames)
    decoder, out = FrameDecoder(MAX_REPLY), []
    for at in range(0, len(stream), chunk):
        out += decoder.feed(stream[at : at + chunk])
    assert [encode_frame(f.seq, f.command, f.payload) for f in out] == frames
    assert decoder.skipped == 10 and not decoder.errors


def test_bad_crc_and_oversized_frames_are_errors_and_the_decoder_resynchronizes():
    bad = bytearray(encode_frame(3, 4, b"abc"))
    bad[-2] ^= 1
    decoder = FrameDecoder()
    oversized = bytes([0xA5, 9, 2]) + (MAX_PAYLOAD + 1).to_bytes(2, "little")
    frames = decoder.feed(bytes(bad) + oversized + encode_frame(5, 6, b"ok"))
    assert [(f.seq, f.payload) for f in frames] == [(5, b"ok")]
    assert decoder.errors == [(ErrorCode.CRC, 3, 4), (ErrorCode.LENGTH, 9, 2)]


def test_payload_codecs_round_trip():
    info = reference_info(tile_shape=(300, 200), area_shape=(70, 70), patch_shape=(10, 10), exclusion_radius=5, clock_hz=75_000_000)
    assert DeviceInfo.decode(info.encode()) == info and info.value_bytes == 4 and info.surface_shape == (61, 61)
    for result in (Result(1, 2, 2**30 - 1, (40, 50, 7), 12345), Result(0, 0, 0, None, 1)):
        assert Result.decode(result.encode(4), 4) == result
    rng = np.random.default_rng(1)
    patch = rng.integers(-32768, 32768, (7, 5)).astype(np.int16)
    mask = rng.random((7, 5)) < 0.5
    back = parse_patch_payload(patch_payload(patch, mask, True), (7, 5))
    np.testing.assert_array_equal(back[0], patch)
    np.testing.assert_array_equal(back[1], mask)
    assert back[2] is True
    with pytest.raises(ValueError, match="a 7 x 5 patch payload has 76 bytes, got 75"):
        parse_patch_payload(patch_payload(patch, mask, True)[:-1], (7, 5))
