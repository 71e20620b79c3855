"""A simulated tow as multibeam pings: the scenario's vehicle sounding its true floor with a swath, as :class:`Ping` values.

:func:`simulated_pings` turns a scenario (:mod:`lost.host.scenario`) into the ping stream a multibeam on the
towed vehicle would have recorded, so that :func:`~lost.host.io.kongsberg_all.write_all_pings` writes it as a
Kongsberg ``.all`` file and ``lost run --survey`` navigates it like any recorded survey:

- one ping per record of the tow (``rate_hz``), at the vehicle's true position (``simulate``'s truth), its
  heading the direction of its true motion (north when at rest), its transducer at its measured depth;
- ``beams`` beams across the heading, evenly over ``swath_width_m`` (the scenario's ``[sensors.sonar]``
  values: ``beams``, and ``swath_width_m`` or the patch's larger side), each sounding the true floor
  (:func:`lost.host.scenario.floor.floor_depth`: bilinear in the scenario's fine floor) with the sonar's bias,
  noise and outliers; a beam without a return (``missing_beam_rate``) or off the floor is flagged invalid;
- a scenario whose sonar is a ``"swath"``: its own soundings, the very depths its records' patches were gridded
  from (:func:`lost.host.scenario.tow.simulate_with_swath`), so that the file's pings are the patches' pings;
  :func:`swath_dead_reckoning_error` gives the dead reckoning that placed them. Another sonar (``"gridded"``: a
  patch of map nodes, no pings): soundings drawn from their own random stream (the scenario's seed plus
  :data:`PING_SEED_OFFSET`), the same sonar model as a swath's;
- positions as WGS 84 latitude/longitude: a scenario's local frame (no CRS) is placed by
  :data:`LOCAL_FRAME_CRS`, a transverse Mercator whose origin is 0 N 0 E (grid and true north agree there to
  0.0001 degree over a 10 km tow); a scenario with a projected CRS keeps its own;
- times from :data:`EPOCH_S` (2026-01-01 00:00 UTC) plus the tow's seconds; no attitude (roll, pitch and
  heave NaN: the beams are placed already); sound speed NaN.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator

import numpy as np

from .survey import Ping

__all__ = ["simulated_pings", "swath_dead_reckoning_error", "LOCAL_FRAME_CRS", "EPOCH_S", "PING_SEED_OFFSET"]

#: Where a scenario's local metric frame is placed on the Earth to give its pings a latitude and longitude.
LOCAL_FRAME_CRS = "+proj=tmerc +lat_0=0 +lon_0=0 +k=1 +x_0=0 +y_0=0 +datum=WGS84 +units=m +no_defs +type=crs"
#: The simulated tow's time zero, POSIX seconds (2026-01-01T00:00:00Z).
EPOCH_S = 1_767_225_600.0
#: The pings' random stream: the scenario's seed plus this, apart from the scenario's own streams.
PING_SEED_OFFSET = 29_029
#: The sonar head (serial number) the pings carry.
SIMULATED_HEAD = 1


def simulated_pings(scenario, *, head: int = SIMULATED_HEAD) -> tuple[object, str, Iterator[Ping]]:
    """The scenario's map, the CRS its pings are projected with, and its pings (a generator; see the module).

    Returns
    -------
    (grid, crs, pings)
        ``grid`` the scenario's navigation map (``simulate``'s), its ``crs`` set to the frame the pings were
        placed in, so a survey read back with that CRS lies on it; ``pings`` one :class:`Ping` per record.
    """
    from dataclasses import replace

    from ..scenario import scenario_floor
    from ..scenario.floor import floor_depth
    from ..scenario.tow import simulate_with_swath
    from .crs import transformer

    grid, records, swath = simulate_with_swath(scenario)
    if not records.has_truth:
        raise ValueError(f"scenario {scenario.name!r} has no true track to place pings on")
    crs = grid.crs or LOCAL_FRAME_CRS
    floor = scenario_floor(scenario)
    spec = scenario.sensors["sonar"]
    h, w = spec.shape
    width = spec.swath_width_m if spec.swath_width_m is not None else max(h, w) * grid.node_m
    across = np.linspace(-width / 2, width / 2, spec.beams) if swath is None else swath.across_m
    truth = np.column_stack([records.truth_x_m, records.truth_y_m])
    dt = 1.0 / scenario.rate_hz
    velocity = np.gradient(truth, dt, axis=0) if len(truth) > 1 else np.zeros_like(truth)
    heading = np.where(np.hypot(velocity[:, 0], velocity[:, 1]) > 1e-6, np.degrees(np.arctan2(velocity[:, 0], velocity[:, 1])), 0.0)
    depth = _filled(records.vehicle_depth_m)
    to_lonlat = transformer(crs, "EPSG:4326")
    lon, lat = to_lonlat.transform(truth[:, 0], truth[:, 1])
    # True north's grid bearing at each ping (the meridian convergence), so that the heading the file gives is true.
    east, north = transformer("EPSG:4326", crs).transform(np.concatenate([lon, lon]), np.concatenate([lat, np.minimum(lat + 1e-5, 90.0)]))
    n = len(truth)
    convergence = np.degrees(np.arctan2(east[n:] - east[:n], north[n:] - north[:n]))
    rng = np.random.default_rng(scenario.seed + PING_SEED_OFFSET)

    def drawn(k: int) -> tuple[np.ndarray, np.ndarray]:
        """Ping k's soundings and which of them have a return, drawn from the pings' own stream."""
        g = math.radians(heading[k])
        spots_e = truth[k, 0] + across * math.cos(g)
        spots_n = truth[k, 1] - across * math.sin(g)
        sounded = floor_depth(floor, spots_e, spots_n) + spec.bias + rng.normal(0.0, spec.noise, across.size)
        outliers = rng.random(across.size) < spec.outlier_rate
        sounded[outliers] += rng.uniform(-spec.outlier, spec.outlier, int(outliers.sum()))
        return sounded, np.isfinite(sounded) & ~(rng.random(across.size) < spec.missing_beam_rate)

    def pings() -> Iterator[Ping]:
        for k in range(n):
            if swath is None:
                sounded, valid = drawn(k)
            else:
                sounded = swath.depth_m[k]
                valid = np.isfinite(sounded)
            yield Ping(time_s=EPOCH_S + float(records.t_s[k]), lat_deg=float(lat[k]), lon_deg=float(lon[k]),
                       heading_deg=float((heading[k] - convergence[k]) % 360.0), roll_deg=math.nan, pitch_deg=math.nan, heave_m=math.nan,
                       sound_speed_mps=math.nan, along_m=np.zeros(across.size), across_m=across.copy(),
                       depth_m=np.where(np.isfinite(sounded), sounded, depth[k]), valid=valid, head=head, origin_depth_m=float(depth[k]))

    return replace(grid, crs=crs), crs, pings()


def swath_dead_reckoning_error(records, swath) -> Callable[[float], np.ndarray]:
    """The dead reckoning a ``"swath"`` scenario placed its pings by, as
    :class:`~lost.host.io.survey_records.SurveyRecorder`'s ``dead_reckoning_error``: ``t`` seconds after the first ping
    to the reckoned position less the true one (east, north), linear between pings.

    ``records`` and ``swath`` are :func:`~lost.host.scenario.tow.simulate_with_swath`'s. The reckoning starts at the true
    first position: only its changes place a beam.
    """
    truth = np.column_stack([records.truth_x_m, records.truth_y_m])
    error = swath.reckoned_m - (truth - truth[0])
    t = np.asarray(records.t_s, dtype=np.float64) - float(records.t_s[0])
    return lambda at: np.array([np.interp(at, t, error[:, 0]), np.interp(at, t, error[:, 1])])


def _filled(series: np.ndarray) -> np.ndarray:
    """A reading with its dropouts (NaN) filled from the nearest reading before (or after, at the start)."""
    values = np.asarray(series, dtype=np.float64).copy()
    finite = np.isfinite(values)
    if not finite.any():
        return np.zeros_like(values)
    index = np.where(finite, np.arange(values.size), -1)
    np.maximum.accumulate(index, out=index)
    first = int(np.flatnonzero(finite)[0])
    index[index < 0] = first
    return values[index]
