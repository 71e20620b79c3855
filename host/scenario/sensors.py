"""What the sensors read of the truth: noise, bias, outliers, dropouts; and the ship's USBL."""

from __future__ import annotations

import math

import numpy as np

from .spec import Scenario, SensorSpec

__all__ = ["read", "usbl_profile", "usbl_pings"]


def read(rng: np.random.Generator, truth: np.ndarray, spec: SensorSpec) -> np.ndarray:
    """One sensor's readings of a true series: noise, bias, outliers, dropouts.

    For a 2-D series (rows of components) an outlier or a dropout hits a whole row.
    """
    truth = np.asarray(truth, float)
    reading = truth + np.asarray(spec.bias, float) + rng.normal(0.0, 1.0, truth.shape) * spec.noise
    outliers = rng.random(truth.shape[0]) < spec.outlier_rate
    reading[outliers] += rng.uniform(-spec.outlier, spec.outlier, reading[outliers].shape)
    reading[rng.random(truth.shape[0]) < spec.dropout_rate] = np.nan
    return reading


def usbl_profile(scenario: Scenario):
    """The sound-speed profile of the scenario's ``[sensors.usbl]`` cast, or None when it has no USBL."""
    spec = scenario.sensors["usbl"]
    if not spec.enabled:
        return None
    from ..usbl.scenario import shipped_cast_path
    from ..usbl.sound import SoundSpeedProfile, read_cast

    path = scenario.base_dir / spec.cast if spec.cast.endswith(".csv") else shipped_cast_path(spec.cast)
    # The layers keep every sample within 5 cm/s of the cast: what lost.host.usbl's own simulator uses.
    return SoundSpeedProfile.from_cast(read_cast(path), tolerance_m_s=0.05)


def _usbl_array(scenario: Scenario):
    from ..usbl.fix import UsblArray

    spec, sensors = scenario.sensors["usbl"], scenario.sensors
    # The fix's covariance takes the recorded inputs' noise; UsblArray needs it positive, a millimetre is none.
    return UsblArray(frequency_hz=spec.frequency_hz, baseline_m=spec.baseline_m, lever_arm_m=(0.0, 0.0, spec.transducer_depth_m),
                     antenna_height_m=0.0, phase_noise_rad=spec.phase_noise_rad, travel_time_noise_s=spec.travel_time_noise_s,
                     tilt_noise_rad=math.radians(spec.tilt_noise_deg), heading_noise_rad=math.radians(sensors["heading"].noise),
                     gnss_noise_m=max(sensors["gps"].noise, 1e-3), depth_noise_m=max(sensors["depth"].noise, 1e-3),
                     noise_growth_per_km=spec.noise_growth_per_km)


def usbl_pings(scenario: Scenario, ship: np.ndarray, heading_deg: np.ndarray, truth: np.ndarray, depth: np.ndarray,
                recorded: dict) -> dict[str, np.ndarray]:
    """The ``[sensors.usbl]`` series of NavRecords (empty without a USBL): travel times and fixes (see UsblSpec)."""
    spec = scenario.sensors["usbl"]
    if not spec.enabled:
        return {}
    from ..usbl.fix import reply_from_geometry, usbl_fix

    profile, array = usbl_profile(scenario), _usbl_array(scenario)
    if depth.max() > profile.bottom_m or depth.min() <= spec.transducer_depth_m:
        raise ValueError(f"sensors.usbl.cast {spec.cast!r} spans {profile.depth_m[0]:g}-{profile.bottom_m:g} m but the vehicle goes from "
                         f"{depth.min():.0f} to {depth.max():.0f} m (the transducer at {spec.transducer_depth_m:g} m): use a deeper cast")
    rng = np.random.default_rng([scenario.seed, 14])  # its own stream: the other sensors' draws do not change
    n = truth.shape[0]
    out = {name: np.full(n, np.nan) for name in ("usbl_travel_time_s", "usbl_x_m", "usbl_y_m", "usbl_sxx", "usbl_syy", "usbl_sxy")}
    every = max(int(round(spec.interval_s * scenario.rate_hz)), 1)
    tilt = math.radians(spec.tilt_noise_deg)
    for k in range(0, n, every):
        slant_km = math.hypot(math.hypot(*(truth[k] - ship[k])), depth[k] - spec.transducer_depth_m) / 1000.0
        if rng.random() < spec.dropout_rate + spec.dropout_rate_per_km * slant_km:
            continue
        travel, phase_x, phase_y = reply_from_geometry(profile, array, roll_rad=0.0, pitch_rad=0.0, heading_rad=math.radians(heading_deg[k]),
                                                       antenna_north_m=ship[k, 1], antenna_east_m=ship[k, 0], target_north_m=truth[k, 1],
                                                       target_east_m=truth[k, 0], target_depth_m=depth[k])
        noise = array.phase_noise_at(slant_km * 1000.0)
        travel += rng.normal(0.0, spec.travel_time_noise_s) + (rng.uniform(0.0, spec.outlier_delay_s) if rng.random() < spec.outlier_rate else 0.0)
        phase_x, phase_y = phase_x + rng.normal(0.0, noise), phase_y + rng.normal(0.0, noise)
        roll, pitch = rng.normal(0.0, tilt, 2)
        out["usbl_travel_time_s"][k] = travel
        inputs = (recorded["ship"][k, 0], recorded["ship"][k, 1], recorded["heading_deg"][k], recorded["depth_m"][k])
        if not np.all(np.isfinite(inputs)):
            continue
        try:
            fix = usbl_fix(profile, array, travel_time_s=travel, roll_rad=roll, pitch_rad=pitch, heading_rad=math.radians(inputs[2]),
                           antenna_north_m=inputs[1], antenna_east_m=inputs[0], target_depth_m=inputs[3], phase_x_rad=phase_x, phase_y_rad=phase_y)
        except ValueError:  # a reply the depth cannot explain (a late multipath one, say) gives no fix, as on a real USBL
            continue
        (syy, sxy), (_, sxx) = fix.covariance_ne  # (north, east) to (east, north)
        out["usbl_x_m"][k], out["usbl_y_m"][k] = fix.east_m, fix.north_m
        out["usbl_sxx"][k], out["usbl_syy"][k], out["usbl_sxy"][k] = sxx, syy, sxy
    return out
