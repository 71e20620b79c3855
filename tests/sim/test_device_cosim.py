"""The device top-level's Verilog on Verilator, driven through its UART pins by the host's driver.

One build (the 1-lane window core, 20 x 20 tile, 16 x 16 area, 6 x 6 patch: small, so that the
Verilator build and the bit-level UART stay quick) serves every test here: every command's reply against the reference
device, the protocol's robustness, and a short ``lost run`` bit for bit against the golden model.
"""

import struct
import time
from pathlib import Path

import numpy as np
import pytest

from lost import model
from lost.host.correlator import BACKENDS, configure_backend, correlation
from lost.host.correlator.driver import DeviceError
from lost.model.device import DeviceModel
from lost.model.protocol import ERROR, MAX_REPLY, Command, ErrorCode, FrameDecoder, encode_frame, patch_payload
from lost.sim.cosim import DeviceConfig

BUILD = Path(__file__).resolve().parents[2] / "build" / "sim" / "cosim"
SIZES = {"tile_shape": (20, 20), "area_shape": (16, 16), "patch_shape": (6, 6), "exclusion_radius": 3}
CONFIG = DeviceConfig(**SIZES)


@pytest.fixture(scope="module")
def device():
    backend = configure_backend("rtl", build_dir=BUILD, **SIZES)
    driver = backend.driver
    yield driver
    backend.close()
    BACKENDS["rtl"].close()


def _replies(transport, count, *, timeout_s=30.0):
    """Raw frames from the device until ``count`` arrived (errors of the reply decoder fail the test)."""
    decoder, frames = FrameDecoder(MAX_REPLY), []
    deadline = time.monotonic() + timeout_s
    while len(frames) < count and time.monotonic() < deadline:
        frames += decoder.feed(transport.read(4096, 0.2))
    assert not decoder.errors
    return frames


def _exchange(transport, data, count=1):
    transport.write(data)
    return _replies(transport, count)


def _without_cycles(frame):
    if frame.command in (Command.START | 0x80, Command.READ_RESULT | 0x80):
        return frame.seq, frame.command, frame.payload[:-4]
    return frame.seq, frame.command, frame.payload


def test_every_command_answers_as_the_reference_device(device):
    info = device.identify()
    assert (info.tile_shape, info.area_shape, info.patch_shape, info.variant_name) == (
        CONFIG.tile_shape, CONFIG.area_shape, CONFIG.patch_shape, CONFIG.variant)
    reference = DeviceModel(info)
    rng = np.random.default_rng(5)
    tile = rng.integers(-32768, 32768, info.tile_shape).astype(np.int16)
    patch = tile[7:13, 3:9].copy()
    patch[0, 0], patch[5, 5] = -32768, 32767
    mask = rng.random((6, 6)) < 0.85
    flat = tile.astype("<i2").ravel()
    requests = [encode_frame(1, Command.LOAD_TILE, struct.pack("<I", a) + flat[a : a + 510].tobytes()) for a in range(0, flat.size, 510)]
    requests += [
        encode_frame(2, Command.ORIGIN, struct.pack("<ii", -7, 70000)),
        encode_frame(3, Command.ORIGIN),
        encode_frame(4, Command.READ_RESULT),  # no result yet: STATE
        encode_frame(5, Command.LOAD_PATCH, patch_payload(patch, mask, True)),
        encode_frame(6, Command.START, struct.pack("<HH", 5, 0)),  # past the tile: RANGE
        encode_frame(7, Command.START, struct.pack("<HH", 3, 2)),
        encode_frame(8, Command.READ_SURFACE, struct.pack("<HH", 0, 121)),
        encode_frame(9, Command.READ_SURFACE, struct.pack("<HH", 100, 22)),  # past the surface: RANGE
        encode_frame(10, Command.READ_SURFACE, struct.pack("<HH", 0, 4097)),  # over a reply: LENGTH
        encode_frame(11, Command.READ_RESULT),
        encode_frame(12, Command.LOAD_PATCH, patch_payload(patch, np.zeros((6, 6), bool), False)),  # ARGUMENT
        encode_frame(13, Command.LOAD_PATCH, patch_payload(patch, mask, False)),
        encode_frame(14, Command.START, struct.pack("<HH", 0, 4)),
        encode_frame(15, Command.READ_SURFACE, struct.pack("<HH", 50, 71)),
        encode_frame(16, Command.IDENTIFY, b"x"),  # LENGTH
        encode_frame(17, Command.RESET),
        encode_frame(18, Command.START, struct.pack("<HH", 0, 0)),  # no patch after the reset: STATE
    ]
    for request in requests:
        (got,) = _exchange(device._transport, request)
        (expected,) = FrameDecoder(MAX_REPLY).feed(reference.receive(request))
        assert _without_cycles(got) == _without_cycles(expected), f"request seq {request[1]} command {request[2]}"


def test_start_takes_the_cycles_of_the_copy_and_the_cores_schedule(device):
    from lost.model.variants import variant

    info = device.identify()
    rng = np.random.default_rng(2)
    tile = rng.integers(-3000, 3000, info.tile_shape).astype(np.int16)
    device.load_tile(tile)
    mask = rng.random((6, 6)) < 0.7
    device.load_patch(tile[:6, :6], mask, True)
    result = device.start(1, 1)
    schedule = variant(CONFIG.variant).schedule(info.area_shape, info.patch_shape, mask, True, exclusion_radius=info.exclusion_radius)
    AH, AW = info.area_shape
    assert result.cycles == 2 * AH * AW + schedule.best + 1


def _raw(transport, frame):
    transport.write(frame)


def test_damaged_frames_get_an_error_and_the_next_good_frame_works(device):
    transport = device._transport
    good = encode_frame(40, Command.IDENTIFY)
    corrupted = bytearray(encode_frame(41, Command.ORIGIN, struct.pack("<ii", 1, 2)))
    corrupted[8] ^= 0x04
    cases = [
        (bytes(corrupted), ErrorCode.CRC),
        (encode_frame(42, 0x55), ErrorCode.COMMAND),
        (bytes([0xA5, 43, Command.LOAD_TILE, 0x01, 0x08]), ErrorCode.LENGTH),  # 2049 bytes announced: oversized
        (encode_frame(44, Command.LOAD_TILE, bytes(40))[:20], ErrorCode.TIMEOUT),  # truncated
    ]
    for frame, code in cases:
        (reply,) = _exchange(transport, frame)
        assert reply.command == ERROR and reply.error == (code, frame[2]) and reply.seq == frame[1]
        (ok,) = _exchange(transport, good)
        assert ok.seq == 40 and ok.command == Command.IDENTIFY | 0x80


def test_garbage_between_frames_is_skipped_silently(device):
    transport = device._transport
    garbage = bytes(np.random.default_rng(3).integers(0, 256, 300, dtype=np.uint8).tolist())
    garbage = garbage.replace(b"\xa5", b"\x5a")
    frames = _exchange(transport, garbage + encode_frame(50, Command.IDENTIFY) + b"\x00\x13\x37", count=1)
    assert [(f.seq, f.command) for f in frames] == [(50, Command.IDENTIFY | 0x80)]
    assert _replies(transport, 1, timeout_s=1.0) == []  # nothing more: garbage is not answered


def test_a_reset_in_the_middle_of_a_transfer(device):
    """Half a LOAD_TILE, then a RESET frame: the RESET's bytes end the broken frame (an error reply); the retried RESET works."""
    transport = device._transport
    half = encode_frame(60, Command.LOAD_TILE, struct.pack("<I", 0) + bytes(64))[:30]
    transport.write(half + encode_frame(61, Command.RESET))
    (reply,) = _replies(transport, 1)
    assert reply.command == ERROR and reply.error[0] in (ErrorCode.CRC, ErrorCode.TIMEOUT)
    device.reset()
    with pytest.raises(DeviceError, match="READ_RESULT: error STATE"):
        device.read_result()


def test_a_host_that_stops_reading_gets_the_next_answer(device):
    transport = device._transport
    info = device.identify()
    device.load_tile(np.zeros(info.tile_shape, np.int16))
    device.load_patch(np.ones((6, 6), np.int16), np.ones((6, 6), bool), True)
    device.start(0, 0)
    transport.write(encode_frame(70, Command.READ_SURFACE, struct.pack("<HH", 0, 121)))  # its reply is never read
    # The next request arrives while the device still sends that reply: it is received and answered after it.
    start = time.monotonic()
    assert device.identify() == info  # the stale reply is dropped by its sequence number
    assert time.monotonic() - start < device._transport.timeout_s and device.stats["retries"] == 0
    assert device.stats["stale_replies"] >= 1


def test_correlation_on_the_device_is_the_models_with_its_own_best_fit(device):
    rng = np.random.default_rng(9)
    terrain = rng.integers(-32768, 32768, (40, 45)).astype(np.int16)
    patch = terrain[20:26, 11:17].copy()
    mask = rng.random((6, 6)) < 0.9
    result = correlation(terrain, patch, mask=mask, backend="rtl", area=(14, 4, 11, 11), exclusion_radius=3)
    expected = model.correlate(terrain[14:30, 4:20], patch, mask=mask)
    np.testing.assert_array_equal(result.surface, expected)
    assert result.best_from == "hardware" and result.best == model.Placement(20, 11, int(expected[6, 7]))
    fit = model.best_fit(expected, exclusion_radius=3)
    assert result.runner_up == model.Placement(fit.runner_up.i + 14, fit.runner_up.j + 4, fit.runner_up.value)


def test_a_short_lost_run_is_bit_identical_to_the_golden_model(device):
    from lost.host.nav import NavParameters, run_lost
    from lost.host.scenario import CableSpec, Scenario, SensorSpec, ShipSpec, SonarSpec, TerrainSpec

    scenario = Scenario(
        seed=4, duration_s=14.0,
        terrain=TerrainSpec(shape=(80, 120), mean_depth_m=250.0, roughness_m=10.0, hurst=0.5),  # 200 m of cable reach 170 m down
        ship=ShipSpec(waypoints_m=((300.0, 400.0), (1100.0, 400.0))),
        cable=CableSpec(out_m=200.0),
        sensors={"sonar": SonarSpec(noise=0.2, interval_s=2.0, shape=(6, 6)), "velocity": SensorSpec(noise=0.02)},
    )
    from lost.host.scenario import simulate

    grid, records = simulate(scenario)
    tracks = {}
    for backend in ("model", "rtl"):
        tracks[backend] = run_lost(records, grid, NavParameters(backend=backend, search_half_width_m=40.0))
    golden, device_run = tracks["model"], tracks["rtl"]
    assert (golden.mle_source == "patch").sum() >= 5
    np.testing.assert_array_equal(device_run.estimate, golden.estimate)
    np.testing.assert_array_equal(device_run.mle_source, golden.mle_source)
