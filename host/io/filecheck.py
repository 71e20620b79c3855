"""Is a grid file whole, and what is it really: checks that run before (and after) a reader trusts it.

- :func:`check_whole` compares a file's size with what its header says it holds: classic NetCDF
  (CDF-1, CDF-2, CDF-5: the netCDF library reads a cut-off classic file as zeros, without an
  error), HDF5 / NetCDF-4 (the superblock's end-of-file address) and TIFF / BigTIFF (the end of the
  last strip or tile of every image). A short file is refused with
  its name, both sizes and the likely cause.
- :func:`native_format` recognises the binary grid formats LOST does not read through a library:
  GMT's native binary grids (``=bf``, ``=bd``, ``=bs``, ``=bi``, ``=bb``: a 892-byte header, then
  the values, north row first) and Surfer's grids (``DSAA``, ``DSBB``, ``DSRB``).
- :func:`read_gmt_native` reads GMT's float and double native grids (NaN holes, like GMT's own).
  The integer ones are refused with the conversion to run, because their nodata value is not in the
  file (GMT takes it from the file name's ``+n`` suffix), so a hole would read as a depth.
- :func:`check_plausible` refuses values no sea floor or land has (farther from sea level than the
  Challenger Deep's depth): an untagged nodata value such as GDAL's -32768 of a 16-bit GeoTIFF, or a grid in
  centimetres or feet.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

__all__ = [
    "check_whole", "native_format", "read_gmt_native", "check_plausible", "GMT_NATIVE_HEADER_BYTES",
    "DEEPEST_M",
]

#: GMT's native binary grid header: 3 int32, 10 float64, then 80 * 4 + 320 + 160 characters.
GMT_NATIVE_HEADER_BYTES = 892
#: The deepest sounding known (Challenger Deep, about 10,935 m) with a margin; Everest is lower than this is deep.
DEEPEST_M = 11_100.0

_GMT_NATIVE = {"bf": np.float32, "bd": np.float64, "bs": np.int16, "bi": np.int32, "bb": np.uint8}
_SURFER = {b"DSAA": "Surfer ASCII grid (DSAA)", b"DSBB": "Surfer 6 binary grid (DSBB)", b"DSRB": "Surfer 7 binary grid (DSRB)"}
# netCDF classic external types: size in bytes (CDF-5 adds the unsigned and 64-bit ones).
_NC_TYPE_SIZE = {1: 1, 2: 1, 3: 2, 4: 4, 5: 4, 6: 8, 7: 1, 8: 2, 9: 4, 10: 8, 11: 8}


def check_whole(path: Path) -> None:
    """Refuse a NetCDF (classic or NetCDF-4/HDF5) or (Big)TIFF file shorter than its header says.

    Raises
    ------
    ValueError
        The file is cut short (named, with the sizes), or its header cannot be parsed.
    """
    size = path.stat().st_size
    with path.open("rb") as stream:
        head = stream.read(8)
        if head[:3] == b"CDF":
            expected = _classic_netcdf_size(stream, head[3], path)
        elif head.startswith(b"\x89HDF\r\n\x1a\n"):
            expected = _hdf5_size(stream)
        elif head[:4] in (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+"):
            expected = _tiff_size(stream, head, path)
        else:
            return
    if expected is not None and size < expected:
        raise ValueError(
            f"{path.name} is truncated: its header describes {expected:,} bytes but the file has {size:,} "
            "(an interrupted download or copy?); fetch or write it again"
        )


class _Header:
    """A reader of the classic NetCDF header's big-endian fields."""

    def __init__(self, stream, version: int, path: Path) -> None:
        self.stream, self.path = stream, path
        self.count = ">q" if version == 5 else ">i"  # NON_NEG: 64-bit in CDF-5
        self.offset = ">q" if version in (2, 5) else ">i"  # begin: 64-bit in CDF-2 and CDF-5

    def read(self, fmt: str) -> int:
        size = struct.calcsize(fmt)
        data = self.stream.read(size)
        if len(data) != size:
            raise ValueError(f"{self.path.name} is truncated: its NetCDF header ends early, at byte {self.stream.tell():,}")
        return struct.unpack(fmt, data)[0]

    def skip_name(self) -> None:
        n = self.read(self.count)
        self.stream.seek((n + 3) // 4 * 4, 1)

    def skip_attributes(self) -> None:
        tag, n = self.read(">i"), self.read(self.count)
        for _ in range(n if tag else 0):
            self.skip_name()
            kind, length = self.read(">i"), self.read(self.count)
            self.stream.seek((length * _NC_TYPE_SIZE.get(kind, 1) + 3) // 4 * 4, 1)


def _classic_netcdf_size(stream, version: int, path: Path) -> int | None:
    """The least file size the header of a classic NetCDF file implies (its last variable's end)."""
    if version not in (1, 2, 5):
        raise ValueError(f"{path.name} starts like a NetCDF file but has an unknown version byte {version}")
    stream.seek(4)
    header = _Header(stream, version, path)
    records = header.read(header.count)
    records = 0 if records in (-1, 2**32 - 1) else records  # streaming: the count is not known
    tag, n = header.read(">i"), header.read(header.count)
    dims = []
    for _ in range(n if tag else 0):
        header.skip_name()
        dims.append(header.read(header.count))
    header.skip_attributes()
    tag, n = header.read(">i"), header.read(header.count)
    ends, records_vars = [], []
    for _ in range(n if tag else 0):
        header.skip_name()
        ids = [header.read(header.count) for _ in range(header.read(header.count))]
        header.skip_attributes()
        kind, vsize, begin = header.read(">i"), header.read(header.count), header.read(header.offset)
        shape = [dims[i] for i in ids if 0 <= i < len(dims)]
        is_record = bool(shape) and shape[0] == 0  # the record (unlimited) dimension
        # The unpadded size: the least the file must hold (padding after the last value may be cut by a writer).
        size = int(np.prod(shape[1:] if is_record else shape, dtype=np.int64)) * _NC_TYPE_SIZE.get(kind, 1)
        if is_record:
            records_vars.append((begin, vsize, size))
        else:
            ends.append(begin + size)
    if records_vars and records:
        # A record holds every record variable's slab (padded), except that a lone record variable is not padded.
        record_size = records_vars[0][2] if len(records_vars) == 1 else sum(vsize for _, vsize, _ in records_vars)
        ends += [begin + (records - 1) * record_size + size for begin, _, size in records_vars]
    return max(ends, default=None)


def _hdf5_size(stream) -> int | None:
    """The end-of-file address in an HDF5 superblock at offset 0 (netCDF-4 writes it there)."""
    stream.seek(8)
    version = stream.read(1)
    if not version:
        return None
    if version[0] in (0, 1):
        fields = stream.read(7)
        if len(fields) < 7:
            return None
        offset_size = fields[4]
        stream.seek(8 + 16 + (4 if version[0] == 1 else 0))
        base_eof = stream.read(3 * offset_size)
        if len(base_eof) < 3 * offset_size:
            return None
        base = int.from_bytes(base_eof[:offset_size], "little")
        return base + int.from_bytes(base_eof[2 * offset_size:], "little")
    if version[0] in (2, 3):
        offset_size = stream.read(3)[0]
        addresses = stream.read(3 * offset_size)
        if len(addresses) < 3 * offset_size:
            return None
        base = int.from_bytes(addresses[:offset_size], "little")
        return base + int.from_bytes(addresses[2 * offset_size:], "little")
    return None


# TIFF tags holding where each strip or tile of an image lies, and how long it is.
_TIFF_OFFSETS, _TIFF_COUNTS = {273: "strip", 324: "tile"}, {279: "strip", 325: "tile"}
_TIFF_TYPES = {3: "H", 4: "I", 16: "Q"}  # SHORT, LONG, LONG8: the types these tags use


def _tiff_size(stream, head: bytes, path: Path) -> int | None:
    """The end of the last strip or tile of every image (IFD) of a TIFF or BigTIFF file."""
    order = "<" if head[:2] == b"II" else ">"
    big = head[2:4] in (b"+\x00", b"\x00+")
    stream.seek(8 if big else 4)
    raw = stream.read(8 if big else 4)
    if len(raw) < (8 if big else 4):
        return None
    ifd = struct.unpack(order + ("Q" if big else "I"), raw)[0]
    end, seen = 0, set()
    while ifd and ifd not in seen and len(seen) < 1000:
        seen.add(ifd)
        tags, ifd = _tiff_ifd(stream, ifd, order, big, path)
        for kind in ("strip", "tile"):
            offsets = next((v for t, v in tags.items() if _TIFF_OFFSETS.get(t) == kind), None)
            counts = next((v for t, v in tags.items() if _TIFF_COUNTS.get(t) == kind), None)
            if offsets and counts and len(offsets) == len(counts):
                end = max(end, max(o + c for o, c in zip(offsets, counts)))
    return end or None


def _tiff_ifd(stream, at: int, order: str, big: bool, path: Path) -> tuple[dict[int, list[int]], int]:
    """The strip and tile tags of the IFD at ``at``, and the offset of the next IFD."""
    count_fmt, entry_size = ("Q", 20) if big else ("H", 12)
    stream.seek(at)
    raw = stream.read(struct.calcsize(count_fmt))
    if len(raw) < struct.calcsize(count_fmt):
        raise ValueError(f"{path.name} is truncated: its TIFF directory at byte {at:,} lies past the end of the file")
    entries = struct.unpack(order + count_fmt, raw)[0]
    table = stream.read(entries * entry_size)
    link = stream.read(8 if big else 4)
    if len(table) < entries * entry_size or len(link) < (8 if big else 4):
        raise ValueError(f"{path.name} is truncated: its TIFF directory at byte {at:,} ends early")
    tags = {}
    for k in range(entries):
        entry = table[k * entry_size:(k + 1) * entry_size]
        tag, kind = struct.unpack(order + "HH", entry[:4])
        if (tag not in _TIFF_OFFSETS and tag not in _TIFF_COUNTS) or kind not in _TIFF_TYPES:
            continue
        n = struct.unpack(order + ("Q" if big else "I"), entry[4:12] if big else entry[4:8])[0]
        inline = entry[12:20] if big else entry[8:12]
        size = n * struct.calcsize(_TIFF_TYPES[kind])
        if size <= len(inline):
            data = inline[:size]
        else:
            stream.seek(struct.unpack(order + ("Q" if big else "I"), inline)[0])
            data = stream.read(size)
            if len(data) < size:
                raise ValueError(f"{path.name} is truncated: its list of {_TIFF_OFFSETS.get(tag) or _TIFF_COUNTS[tag]} offsets lies past the end")
        tags[tag] = list(struct.unpack(order + _TIFF_TYPES[kind] * n, data))
    return tags, struct.unpack(order + ("Q" if big else "I"), link)[0]


def native_format(path: Path) -> str | None:
    """``"gmt:bf"`` (``bd``, ``bs``, ``bi``, ``bb``) for a GMT native binary grid, ``"surfer:..."``, or None."""
    with path.open("rb") as stream:
        head = stream.read(GMT_NATIVE_HEADER_BYTES)
    if head[:4] in _SURFER:
        return f"surfer:{_SURFER[head[:4]]}"
    header = _gmt_header(head)
    if header is None:
        return None
    nodes = header["nx"] * header["ny"]
    payload = path.stat().st_size - GMT_NATIVE_HEADER_BYTES
    fitting = [code for code, dtype in _GMT_NATIVE.items() if payload == nodes * np.dtype(dtype).itemsize]
    if len(fitting) > 1:
        # =bf and =bi are both 4 bytes a node: the one whose values span the header's z range is the format.
        fitting = [code for code in fitting if _spans_header_range(path, code, header)] or fitting
    return f"gmt:{fitting[0]}" if fitting else None


def _spans_header_range(path: Path, code: str, header: dict) -> bool:
    values = np.fromfile(path, dtype=np.dtype(_GMT_NATIVE[code]).newbyteorder("<"), offset=GMT_NATIVE_HEADER_BYTES)
    values = values.astype(np.float64) * header["scale"] + header["offset"]
    finite = values[np.isfinite(values)]
    return bool(finite.size) and np.allclose([finite.min(), finite.max()], [header["z_min"], header["z_max"]], rtol=1e-5, atol=1e-6)


def _gmt_header(head: bytes) -> dict | None:
    if len(head) < GMT_NATIVE_HEADER_BYTES:
        return None
    nx, ny, registration = struct.unpack("<3i", head[:12])
    w, e, s, n, z_min, z_max, x_inc, y_inc, scale, offset = struct.unpack("<10d", head[12:92])
    sane = (
        0 < nx < 10**7 and 0 < ny < 10**7 and registration in (0, 1) and np.isfinite([w, e, s, n, x_inc, y_inc]).all()
        and x_inc > 0 and y_inc > 0 and e > w and n > s
        and abs((e - w) / x_inc + (1 - registration) - nx) < 1e-3 * nx and abs((n - s) / y_inc + (1 - registration) - ny) < 1e-3 * ny
    )
    if not sane:
        return None
    text = [head[a:b].split(b"\0")[0].decode("latin-1").strip() for a, b in ((92, 172), (172, 252), (252, 332))]
    return dict(nx=nx, ny=ny, registration=registration, w=w, e=e, s=s, n=n, x_inc=x_inc, y_inc=y_inc, z_min=z_min, z_max=z_max,
                scale=scale or 1.0, offset=offset, x_units=text[0], y_units=text[1], z_units=text[2])


def read_gmt_native(path: Path, kind: str):
    """Values (north row first, as stored), x and y node coordinates and the header of a GMT native float grid.

    Raises
    ------
    ValueError
        An integer native grid (nodata not in the file), named with the command that converts it.
    """
    code = kind.split(":")[1]
    if code not in ("bf", "bd"):
        raise ValueError(
            f"{path.name} is a GMT native binary grid of {np.dtype(_GMT_NATIVE[code]).name} (={code}), whose nodata value is not "
            f"stored in the file; convert it to NetCDF naming that value, e.g. gmt grdconvert '{path.name}=${code}+n-32768' "
            f"{path.stem}.nc (with your nodata value), then read the .nc"
        )
    with path.open("rb") as stream:
        header = _gmt_header(stream.read(GMT_NATIVE_HEADER_BYTES))
        values = np.fromfile(stream, dtype=np.dtype(_GMT_NATIVE[code]).newbyteorder("<"))
    assert header is not None  # native_format recognised it
    values = values.astype(np.float64).reshape(header["ny"], header["nx"]) * header["scale"] + header["offset"]
    half = 0.5 * header["registration"]
    xs = header["w"] + (np.arange(header["nx"]) + half) * header["x_inc"]
    ys = header["n"] - (np.arange(header["ny"]) + half) * header["y_inc"]
    return values, xs, ys, header


def check_plausible(values: np.ndarray, name: str, what: str) -> None:
    """Refuse values (as the file stores them, in metres) that no depth or elevation reaches.

    Parameters
    ----------
    values : array
        The file's values, before any sign change: depths or elevations, metres.
    name, what : str
        The file's name and which variable or band, for the message.

    Raises
    ------
    ValueError
        Some value's magnitude exceeds ``DEEPEST_M``; the message says how many, and the likely cause.
    """
    finite = values[np.isfinite(values)]
    bad = finite[np.abs(finite) > DEEPEST_M]
    if not bad.size:
        return
    uniques, counts = np.unique(bad, return_counts=True)
    common = float(uniques[np.argmax(counts)])
    if counts.max() >= 0.5 * bad.size:
        cause = (
            f"{int(counts.max())} of them hold exactly {common:g}, most likely a nodata value the file does not declare "
            f"(GDAL writes -32768 for a hole in a 16-bit GeoTIFF): pass nodata={common:g} (lost run --nodata), "
            "or tag the file (gdal_edit.py -a_nodata VALUE FILE)"
        )
    else:
        cause = "the values may be in centimetres or feet, or scaled: convert them to metres"
    raise ValueError(
        f"{name}: {bad.size} of {finite.size} values of {what} are farther from sea level than any sea floor "
        f"({DEEPEST_M:g} m; they run {float(bad.min()):g} to {float(bad.max()):g}): {cause}"
    )
