"""Frames: the ship's and the vehicle's body frame (x forward, y starboard, z down), the local navigation frame
(north, east, down, in metres on a local tangent plane), and the Earth (WGS 84 geographic and UTM, through pyproj).

The local plane is pyproj's azimuthal equidistant projection about a chosen origin: its scale is 1 at the
origin and within 1e-6 over 10 km, so an INS integrating true metres and a fix projected into it agree; UTM's
scale (0.9996 at the central meridian) would not.
"""

from __future__ import annotations

import numpy as np
from pyproj import CRS, Transformer
from pyproj.aoi import AreaOfInterest
from pyproj.database import query_utm_crs_info
from scipy.spatial.transform import Rotation

__all__ = ["LocalFrame", "body_to_ned", "euler_from_matrix", "skew", "rotation_from_vector"]


def body_to_ned(roll_rad, pitch_rad, heading_rad) -> np.ndarray:
    """Rotation matrices (..., 3, 3) taking body vectors (forward, starboard, down) to north, east, down."""
    angles = np.stack(np.broadcast_arrays(heading_rad, pitch_rad, roll_rad), axis=-1)
    return Rotation.from_euler("ZYX", angles.reshape(-1, 3)).as_matrix().reshape(angles.shape[:-1] + (3, 3))


def euler_from_matrix(matrix: np.ndarray) -> np.ndarray:
    """Roll, pitch, heading (rad) of body-to-NED rotation matrices (..., 3, 3); heading in [-pi, pi)."""
    matrix = np.asarray(matrix)
    heading, pitch, roll = Rotation.from_matrix(matrix.reshape(-1, 3, 3)).as_euler("ZYX").T
    return np.stack([roll, pitch, heading], axis=-1).reshape(matrix.shape[:-2] + (3,))


def skew(vector: np.ndarray) -> np.ndarray:
    """The cross-product matrix ``[v x]``."""
    x, y, z = vector
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def rotation_from_vector(vector: np.ndarray) -> np.ndarray:
    """Rodrigues: the rotation matrix of a rotation vector (axis times angle, rad)."""
    angle = float(np.linalg.norm(vector))
    k = skew(vector)
    if angle < 1e-8:
        return np.eye(3) + k + k @ k / 2.0
    return np.eye(3) + np.sin(angle) / angle * k + (1.0 - np.cos(angle)) / angle**2 * (k @ k)


class LocalFrame:
    """A local tangent plane about ``(latitude0_deg, longitude0_deg)``, with WGS 84 and UTM conversions.

    Parameters
    ----------
    latitude0_deg, longitude0_deg : float
        The origin (e.g. the first ship position of a run).
    """

    def __init__(self, latitude0_deg: float, longitude0_deg: float) -> None:
        if not (-90.0 < latitude0_deg < 90.0 and -180.0 <= longitude0_deg <= 180.0):
            raise ValueError(f"local frame origin latitude {latitude0_deg}, longitude {longitude0_deg} is out of range")
        self.latitude0_deg = float(latitude0_deg)
        self.longitude0_deg = float(longitude0_deg)
        local = CRS.from_proj4(f"+proj=aeqd +lat_0={latitude0_deg} +lon_0={longitude0_deg} +datum=WGS84 +units=m +no_defs")
        utm_info = query_utm_crs_info(datum_name="WGS 84", area_of_interest=AreaOfInterest(longitude0_deg, latitude0_deg, longitude0_deg, latitude0_deg))
        self.utm_crs = CRS.from_epsg(utm_info[0].code)
        self._to_local = Transformer.from_crs("EPSG:4326", local, always_xy=True)
        self._to_utm = Transformer.from_crs(local, self.utm_crs, always_xy=True)

    def to_local(self, latitude_deg, longitude_deg) -> tuple[np.ndarray, np.ndarray]:
        """North and east (m) on the local plane of geographic positions."""
        east, north = self._to_local.transform(np.asarray(longitude_deg, dtype=float), np.asarray(latitude_deg, dtype=float))
        return np.asarray(north), np.asarray(east)

    def to_geographic(self, north_m, east_m) -> tuple[np.ndarray, np.ndarray]:
        """Latitude and longitude (deg) of local positions."""
        lon, lat = self._to_local.transform(np.asarray(east_m, dtype=float), np.asarray(north_m, dtype=float), direction="INVERSE")
        return np.asarray(lat), np.asarray(lon)

    def to_utm(self, north_m, east_m) -> tuple[np.ndarray, np.ndarray]:
        """UTM easting and northing (m, in ``self.utm_crs``) of local positions."""
        easting, northing = self._to_utm.transform(np.asarray(east_m, dtype=float), np.asarray(north_m, dtype=float))
        return np.asarray(easting), np.asarray(northing)
