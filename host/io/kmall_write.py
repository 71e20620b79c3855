"""Pings as Kongsberg ``.kmall`` datagrams: #SPO position, #SKM attitude, #MRZ soundings; a file, or one datagram at a time.

The layouts are Kongsberg's (EMdgmFormat, as pykmall reads them: little-endian, packed), encoded with NumPy
structured arrays; what :mod:`lost.host.io.kmall` (pykmall) reads back is the test of this encoder.

Per ping, in this order:

- ``#SPO`` (version 0): the position as the active sensor gave it (latitude/longitude as doubles), speed and
  course over ground when given, and the raw sentence the sensor sent (the GGA) as its text;
- ``#SKM`` (version 1), only when the ping has roll, pitch and heave: one KM binary sample at the ping's
  time (roll, pitch, heading as float32 degrees, heave as float32 metres) with its delayed-heave block;
- ``#MRZ`` (version 0): one tx sector, one rx fan; heading, sound speed at the transducer (0 when unknown:
  the reader reads that as unknown), the position of the reference point (doubles); the water line's
  height re the reference point is ``-origin_depth_m`` (0 when the ping has none, as GSF's); per beam a
  120-byte sounding: x (along), y (across), z (the depth re the reference point) as float32, the
  detection type 0 (normal) and method 1 (amplitude) for a valid beam, type 2 (rejected) and method 0 (no
  valid detection) otherwise, delta latitude/longitude of the beam (spherical Earth), no seabed image.

An MRZ has no head serial number: a ping's ``head`` is written as the receiver transducer index, the heads
numbered 0, 1, ... in the order they first appear (:class:`HeadIndex`), and read back as that index. Times are kept to the
nanosecond (as the format's seconds and nanoseconds). An MRZ larger than a UDP datagram is split as the
K-Controller sends it (:func:`split_datagram`): each part a whole datagram (header, its partition
``numOfDgms``/``dgmNum``, a slice of the body, closing length); the receiver joins the slices.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from .crs import offset_degrees
from .kmall import MRZ_SOUNDING  # the 120-byte sounding: the reader's own layout, one place for it
from .survey import Ping

__all__ = ["write_kmall_pings", "ping_datagrams", "HeadIndex", "encode_mrz", "encode_skm", "encode_spo", "split_datagram",
           "HEADER", "PARTITION", "MRZ_VERSION", "UDP_PART_BYTES"]

MRZ_VERSION, SKM_VERSION, SPO_VERSION = 0, 1, 0
#: Largest part of a split datagram, bytes: within one UDP datagram (65,507 bytes of payload over IPv4).
UDP_PART_BYTES = 64_000

HEADER = np.dtype([("numBytesDgm", "<u4"), ("dgmType", "S4"), ("dgmVersion", "u1"), ("systemID", "u1"), ("echoSounderID", "<u2"),
                   ("time_sec", "<u4"), ("time_nanosec", "<u4")])
PARTITION = np.dtype([("numOfDgms", "<u2"), ("dgmNum", "<u2")])
_CMN_PART = np.dtype([("numBytesCmnPart", "<u2"), ("pingCnt", "<u2"), ("rxFansPerPing", "u1"), ("rxFanIndex", "u1"),
                      ("swathsPerPing", "u1"), ("swathAlongPosition", "u1"), ("txTransducerInd", "u1"), ("rxTransducerInd", "u1"),
                      ("numRxTransducers", "u1"), ("algorithmType", "u1")])
# EMdgmMRZ_pingInfo, version 0: pykmall's "2H1f6B1H11f2h2B1H1I3f2H1f2H6f4B" then "2d1f".
_PING_INFO = np.dtype([
    ("numBytesInfoData", "<u2"), ("padding0", "<u2"), ("pingRate_Hz", "<f4"), ("beamSpacing", "u1"), ("depthMode", "u1"),
    ("subDepthMode", "u1"), ("distanceBtwSwath", "u1"), ("detectionMode", "u1"), ("pulseForm", "u1"), ("padding1", "<u2"),
    ("frequencyMode_Hz", "<f4"), ("freqRangeLowLim_Hz", "<f4"), ("freqRangeHighLim_Hz", "<f4"), ("maxTotalTxPulseLength_sec", "<f4"),
    ("maxEffTxPulseLength_sec", "<f4"), ("maxEffTxBandWidth_Hz", "<f4"), ("absCoeff_dBPerkm", "<f4"), ("portSectorEdge_deg", "<f4"),
    ("starbSectorEdge_deg", "<f4"), ("portMeanCov_deg", "<f4"), ("stbdMeanCov_deg", "<f4"), ("portMeanCov_m", "<i2"),
    ("starbMeanCov_m", "<i2"), ("modeAndStabilisation", "u1"), ("runtimeFilter1", "u1"), ("runtimeFilter2", "<u2"),
    ("pipeTrackingStatus", "<u4"), ("transmitArraySizeUsed_deg", "<f4"), ("receiveArraySizeUsed_deg", "<f4"), ("transmitPower_dB", "<f4"),
    ("SLrampUpTimeRemaining", "<u2"), ("padding2", "<u2"), ("yawAngle_deg", "<f4"), ("numTxSectors", "<u2"), ("numBytesPerTxSector", "<u2"),
    ("headingVessel_deg", "<f4"), ("soundSpeedAtTxDepth_mPerSec", "<f4"), ("txTransducerDepth_m", "<f4"), ("z_waterLevelReRefPoint_m", "<f4"),
    ("x_kmallToall_m", "<f4"), ("y_kmallToall_m", "<f4"), ("latLongInfo", "u1"), ("posSensorStatus", "u1"), ("attitudeSensorStatus", "u1"),
    ("padding3", "u1"), ("latitude_deg", "<f8"), ("longitude_deg", "<f8"), ("ellipsoidHeightReRefPoint_m", "<f4"),
])
# EMdgmMRZ_txSectorInfo, version 0: "4B7f2B1H".
_TX_SECTOR = np.dtype([("txSectorNumb", "u1"), ("txArrNumber", "u1"), ("txSubArray", "u1"), ("padding0", "u1"),
                       ("sectorTransmitDelay_sec", "<f4"), ("tiltAngleReTx_deg", "<f4"), ("txNominalSourceLevel_dB", "<f4"),
                       ("txFocusRange_m", "<f4"), ("centreFreq_Hz", "<f4"), ("signalBandWidth_Hz", "<f4"), ("totalSignalLength_sec", "<f4"),
                       ("pulseShading", "u1"), ("signalWaveForm", "u1"), ("padding1", "<u2")])
# EMdgmMRZ_rxInfo: "4H4f4H".
_RX_INFO = np.dtype([("numBytesRxInfo", "<u2"), ("numSoundingsMaxMain", "<u2"), ("numSoundingsValidMain", "<u2"), ("numBytesPerSounding", "<u2"),
                     ("WCSampleRate", "<f4"), ("seabedImageSampleRate", "<f4"), ("BSnormal_dB", "<f4"), ("BSoblique_dB", "<f4"),
                     ("extraDetectionAlarmFlag", "<u2"), ("numExtraDetections", "<u2"), ("numExtraDetectionClasses", "<u2"),
                     ("numBytesPerClass", "<u2")])
# EMdgmScommon: "4H"; EMdgmSPOdataBlock: "2I1f" "2d3f" then the sensor's own text.
_S_COMMON = np.dtype([("numBytesCmnPart", "<u2"), ("sensorSystem", "<u2"), ("sensorStatus", "<u2"), ("padding", "<u2")])
_SPO_DATA = np.dtype([("timeFromSensor_sec", "<u4"), ("timeFromSensor_nanosec", "<u4"), ("posFixQuality_m", "<f4"),
                      ("correctedLat_deg", "<f8"), ("correctedLong_deg", "<f8"), ("speedOverGround_mPerSec", "<f4"),
                      ("courseOverGround_deg", "<f4"), ("ellipsoidHeightReRefPoint_m", "<f4")])
# EMdgmSKMinfo: "1H2B4H"; a KM binary sample "4B" "2H3I" "2d" "21f" (120 bytes) and its delayed heave "2I1f".
_SKM_INFO = np.dtype([("numBytesInfoPart", "<u2"), ("sensorSystem", "u1"), ("sensorStatus", "u1"), ("sensorInputFormat", "<u2"),
                      ("numSamplesArray", "<u2"), ("numBytesPerSample", "<u2"), ("sensorDataContents", "<u2")])
_KM_BINARY = np.dtype([("dgmType", "S4"), ("numBytesDgm", "<u2"), ("dgmVersion", "<u2"), ("time_sec", "<u4"), ("time_nanosec", "<u4"),
                       ("status", "<u4"), ("latitude_deg", "<f8"), ("longitude_deg", "<f8"), ("ellipsoidHeight_m", "<f4"),
                       ("roll_deg", "<f4"), ("pitch_deg", "<f4"), ("heading_deg", "<f4"), ("heave_m", "<f4"), ("rates", "<f4", (3,)),
                       ("velocities", "<f4", (3,)), ("errors", "<f4", (7,)), ("accelerations", "<f4", (3,))])
_DELAYED_HEAVE = np.dtype([("time_sec", "<u4"), ("time_nanosec", "<u4"), ("delayedHeave_m", "<f4")])
_VALID_DETECTION, _REJECTED_DETECTION = 0, 2  # detectionType: normal; rejected
_AMPLITUDE_METHOD, _NO_DETECTION_METHOD = 1, 0
_SKM_CONTENTS = 0b1110  # roll and pitch, heading, heave
_KM_BINARY_POSITION_INVALID = 0b1  # status bit 0: horizontal position and velocity invalid (the SKM carries attitude only)


def _time_parts(time_s: float) -> tuple[int, int]:
    sec = math.floor(time_s)
    nanosec = round((time_s - sec) * 1e9)
    if nanosec >= 1_000_000_000:
        sec, nanosec = sec + 1, nanosec - 1_000_000_000
    return sec, nanosec


def _framed(kind: bytes, version: int, time_s: float, body: bytes, *, system_id: int, echo_sounder_id: int) -> bytes:
    header = np.zeros(1, HEADER)
    header["numBytesDgm"] = HEADER.itemsize + len(body) + 4
    header["dgmType"], header["dgmVersion"] = kind, version
    header["systemID"], header["echoSounderID"] = system_id, echo_sounder_id
    header["time_sec"], header["time_nanosec"] = _time_parts(time_s)
    size = int(header["numBytesDgm"][0])
    return header.tobytes() + body + size.to_bytes(4, "little")


def _finite_or(value: float, default: float) -> float:
    return value if math.isfinite(value) else default


class HeadIndex(dict):
    """Head serial number -> MRZ receiver transducer index, 0, 1, ... in the order the heads first appear."""

    def __call__(self, head: int) -> int:
        if head not in self:
            if len(self) == 256:
                raise ValueError(f"a 257th sonar head ({head}): the MRZ's receiver index is one byte")
            self[head] = len(self)
        return self[head]


def encode_mrz(ping: Ping, *, rx_index: int = 0, ping_count: int = 0, system_id: int = 0, echo_sounder_id: int = 2040) -> bytes:
    """One ``#MRZ`` datagram of ``ping`` (see the module), unsplit; ``rx_index`` stands for its head."""
    if not (math.isfinite(ping.lat_deg) and math.isfinite(ping.lon_deg) and math.isfinite(ping.heading_deg)):
        raise ValueError(f"ping at t={ping.time_s} has no position or heading; an MRZ needs both")
    origin = _finite_or(ping.origin_depth_m, 0.0)
    partition = np.ones(1, PARTITION)
    cmn = np.zeros(1, _CMN_PART)
    cmn["numBytesCmnPart"], cmn["pingCnt"] = _CMN_PART.itemsize, ping_count & 0xFFFF
    cmn["rxFansPerPing"], cmn["swathsPerPing"], cmn["numRxTransducers"] = 1, 1, 1
    cmn["rxTransducerInd"] = rx_index
    info = np.zeros(1, _PING_INFO)
    info["numBytesInfoData"], info["numTxSectors"], info["numBytesPerTxSector"] = _PING_INFO.itemsize, 1, _TX_SECTOR.itemsize
    info["headingVessel_deg"] = ping.heading_deg % 360.0
    info["soundSpeedAtTxDepth_mPerSec"] = _finite_or(ping.sound_speed_mps, 0.0)
    info["txTransducerDepth_m"], info["z_waterLevelReRefPoint_m"] = origin, -origin
    info["latitude_deg"], info["longitude_deg"] = ping.lat_deg, ping.lon_deg
    sector = np.zeros(1, _TX_SECTOR)
    rx = np.zeros(1, _RX_INFO)
    rx["numBytesRxInfo"], rx["numSoundingsMaxMain"], rx["numBytesPerSounding"] = _RX_INFO.itemsize, ping.beams, MRZ_SOUNDING.itemsize
    rx["numSoundingsValidMain"] = int(np.count_nonzero(ping.valid))
    rx["numBytesPerClass"] = 4
    beams = np.zeros(ping.beams, MRZ_SOUNDING)
    valid = np.asarray(ping.valid, dtype=bool)
    beams["soundingIndex"] = np.arange(ping.beams)
    beams["detectionType"] = np.where(valid, _VALID_DETECTION, _REJECTED_DETECTION)
    beams["detectionMethod"] = np.where(valid, _AMPLITUDE_METHOD, _NO_DETECTION_METHOD)
    beams["x_reRefPoint_m"], beams["y_reRefPoint_m"] = ping.along_m, ping.across_m
    beams["z_reRefPoint_m"] = np.asarray(ping.depth_m, dtype=np.float64) - origin
    h = math.radians(ping.heading_deg)
    north = ping.along_m * math.cos(h) - ping.across_m * math.sin(h)
    east = ping.along_m * math.sin(h) + ping.across_m * math.cos(h)
    beams["deltaLatitude_deg"], beams["deltaLongitude_deg"] = offset_degrees(north, east, ping.lat_deg)
    body = b"".join(a.tobytes() for a in (partition, cmn, info, sector, rx, beams))
    return _framed(b"#MRZ", MRZ_VERSION, ping.time_s, body, system_id=system_id, echo_sounder_id=echo_sounder_id)


def encode_skm(time_s: float, *, roll_deg: float, pitch_deg: float, heave_m: float, heading_deg: float,
               system_id: int = 0, echo_sounder_id: int = 2040) -> bytes:
    """One ``#SKM`` datagram of one KM binary attitude sample at ``time_s``."""
    info = np.zeros(1, _SKM_INFO)
    info["numBytesInfoPart"], info["sensorInputFormat"], info["numSamplesArray"] = _SKM_INFO.itemsize, 1, 1
    info["numBytesPerSample"] = _KM_BINARY.itemsize + _DELAYED_HEAVE.itemsize
    info["sensorStatus"], info["sensorDataContents"] = 1, _SKM_CONTENTS
    sample = np.zeros(1, _KM_BINARY)
    sample["dgmType"], sample["numBytesDgm"], sample["dgmVersion"] = b"#KMB", _KM_BINARY.itemsize, 1
    sample["time_sec"], sample["time_nanosec"] = _time_parts(time_s)
    sample["status"] = _KM_BINARY_POSITION_INVALID
    sample["roll_deg"], sample["pitch_deg"], sample["heave_m"] = roll_deg, pitch_deg, heave_m
    sample["heading_deg"] = _finite_or(heading_deg, 0.0) % 360.0
    delayed = np.zeros(1, _DELAYED_HEAVE)
    delayed["time_sec"], delayed["time_nanosec"] = sample["time_sec"], sample["time_nanosec"]
    delayed["delayedHeave_m"] = heave_m
    body = info.tobytes() + sample.tobytes() + delayed.tobytes()
    return _framed(b"#SKM", SKM_VERSION, time_s, body, system_id=system_id, echo_sounder_id=echo_sounder_id)


def encode_spo(time_s: float, lat_deg: float, lon_deg: float, *, speed_mps: float = math.nan, course_deg: float = math.nan,
               sensor_text: str = "", system_id: int = 0, echo_sounder_id: int = 2040) -> bytes:
    """One ``#SPO`` datagram: the active position sensor's fix at ``time_s`` (and its raw ``sensor_text``, a GGA)."""
    common = np.zeros(1, _S_COMMON)
    common["numBytesCmnPart"], common["sensorStatus"] = _S_COMMON.itemsize, 1  # bit 0: the active sensor, data OK
    data = np.zeros(1, _SPO_DATA)
    data["timeFromSensor_sec"], data["timeFromSensor_nanosec"] = _time_parts(time_s)
    data["correctedLat_deg"], data["correctedLong_deg"] = lat_deg, lon_deg
    data["speedOverGround_mPerSec"], data["courseOverGround_deg"] = speed_mps, course_deg
    text = sensor_text.encode("ascii")
    text += b"\x00" * (-len(text) % 4)  # the datagram keeps a 4-byte multiple
    return _framed(b"#SPO", SPO_VERSION, time_s, common.tobytes() + data.tobytes() + text,
                   system_id=system_id, echo_sounder_id=echo_sounder_id)


def split_datagram(datagram: bytes, max_bytes: int = UDP_PART_BYTES) -> list[bytes]:
    """An M datagram (``#MRZ``) as the parts a K-Controller sends when it exceeds ``max_bytes``; ``[datagram]`` when it does not.

    Each part is a datagram of its own: the original header (its length its own), the partition (``numOfDgms``,
    ``dgmNum`` from 1), a slice of the body after the partition, and its closing length.
    """
    if len(datagram) <= max_bytes:
        return [datagram]
    head = HEADER.itemsize + PARTITION.itemsize
    room = max_bytes - head - 4
    if room < 1:
        raise ValueError(f"max_bytes {max_bytes} leaves no room for data after the header and partition ({head + 4} bytes)")
    body = datagram[head:-4]
    slices = [body[k:k + room] for k in range(0, len(body), room)]
    if len(slices) > 0xFFFF:
        raise ValueError(f"a datagram of {len(datagram)} bytes would need {len(slices)} parts of {max_bytes} bytes")
    parts = []
    for number, piece in enumerate(slices, start=1):
        header = np.frombuffer(datagram[:HEADER.itemsize], HEADER).copy()
        header["numBytesDgm"] = head + len(piece) + 4
        partition = np.array([(len(slices), number)], PARTITION)
        parts.append(header.tobytes() + partition.tobytes() + piece + int(header["numBytesDgm"][0]).to_bytes(4, "little"))
    return parts


def ping_datagrams(ping: Ping, *, rx_index: int = 0, ping_count: int = 0, speed_mps: float = math.nan, course_deg: float = math.nan,
                   position_text: str = "", system_id: int = 0, echo_sounder_id: int = 2040) -> list[bytes]:
    """The datagrams of one ping, in the order sent and written: ``#SPO``, ``#SKM`` (when it has attitude), ``#MRZ``."""
    ids = {"system_id": system_id, "echo_sounder_id": echo_sounder_id}
    out = [encode_spo(ping.time_s, ping.lat_deg, ping.lon_deg, speed_mps=speed_mps, course_deg=course_deg, sensor_text=position_text, **ids)]
    if all(math.isfinite(v) for v in (ping.roll_deg, ping.pitch_deg, ping.heave_m)):
        out.append(encode_skm(ping.time_s, roll_deg=ping.roll_deg, pitch_deg=ping.pitch_deg, heave_m=ping.heave_m,
                              heading_deg=ping.heading_deg, **ids))
    out.append(encode_mrz(ping, rx_index=rx_index, ping_count=ping_count, **ids))
    return out


def write_kmall_pings(pings: Iterable[Ping], path: str | os.PathLike, *, echo_sounder_id: int = 2040) -> Path:
    """Write pings as a ``.kmall`` file (per ping the datagrams of :func:`ping_datagrams`); returns the path.

    What :func:`lost.host.io.kmall.read_kmall_pings` reads back: times to the nanosecond (as float64 POSIX
    seconds), latitude and longitude as written (doubles), heading, roll, pitch, heave, sound speed and per
    beam along, across and depth to float32, the valid flag; ``origin_depth_m`` as written (0 when the ping
    had none); the head as its :class:`HeadIndex`. Pings are written as they come; the file is written whole to ``NAME.partial``, then renamed.
    """
    path = Path(path)
    partial = path.with_name(path.name + ".partial")
    try:
        with partial.open("wb") as out:
            heads = HeadIndex()
            for count, ping in enumerate(pings):
                for datagram in ping_datagrams(ping, rx_index=heads(ping.head), ping_count=count, echo_sounder_id=echo_sounder_id):
                    out.write(datagram)
        os.replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)
    return path
