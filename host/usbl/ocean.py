"""The simulator's sea: a finer, time-varying truth than the cast the processing is given.

The truth starts from the logged cast's temperature and salinity, interpolated every ``fine_step_m`` (the processing
thins the cast to layers within 0.05 m/s), continued below the cast by :func:`lost.host.usbl.sound.extend_cast` where the
tow goes deeper, and changed over the tow in two ways the cast cannot know:

- a surface layer that warms: ``surface_warming_c_per_h`` times the cast's age (``cast_age_h`` at the tow's start, plus
  the time since), fading with depth as ``exp(-z / warm_layer_m)``;
- internal waves: the water column heaves by ``internal_wave_m * sin(pi z / H) * sin(2 pi t / internal_wave_period_s)``
  (the first mode over the cast's depth H), so temperature and salinity are read ``eta`` higher or lower.

The speed at every depth follows by TEOS-10 (``gsw``) at each ping; the ray of a reply is traced through that profile.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import gsw
import numpy as np

from .scenario import OceanSpec
from .sound import Cast, SoundSpeedProfile, extend_cast, sound_speed_teos10

__all__ = ["TruthOcean"]


@dataclass(frozen=True)
class TruthOcean:
    """The truth's sound-speed profile at any time of the tow (seconds from its start)."""

    cast: Cast
    spec: OceanSpec
    depth_m: np.ndarray
    pressure_dbar: np.ndarray

    @classmethod
    def build(cls, cast: Cast, spec: OceanSpec, deepest_m: float) -> TruthOcean:
        """The truth for a tow reaching ``deepest_m`` (the cast is extended below its last sample if it stops above).

        Raises
        ------
        ValueError
            The ocean changes over the tow but the cast has no temperature and salinity (a sound-velocity probe's).
        """
        if spec.changes() and not np.all(np.isfinite(cast.temperature_c)):
            raise ValueError(f"cast {cast.source}: a changing truth ocean ([ocean] warming or internal waves) needs the cast's temperature "
                             "and salinity, and this cast gives sound speed only")
        cast = extend_cast(cast, deepest_m + 100.0)
        depth = np.arange(0.0, cast.depth_m[-1], spec.fine_step_m)
        depth = np.append(depth, cast.depth_m[-1])
        return cls(cast, spec, depth, np.asarray(gsw.p_from_z(-depth, cast.latitude_deg), dtype=float))

    @functools.cached_property
    def _still(self) -> SoundSpeedProfile:
        return self._profile(0.0)

    def profile_at(self, time_s: float) -> SoundSpeedProfile:
        """The truth's profile ``time_s`` seconds after the tow's start."""
        return self._profile(time_s) if self.spec.changes() else self._still

    def _profile(self, time_s: float) -> SoundSpeedProfile:
        spec, cast, z = self.spec, self.cast, self.depth_m
        if not np.all(np.isfinite(cast.temperature_c)):  # a sound-velocity probe's cast, unchanged (build refuses changes)
            return SoundSpeedProfile(z, np.interp(z, cast.depth_m, cast.sound_speed_m_s))
        heave = spec.internal_wave_m * np.sin(np.pi * z / cast.depth_m[-1]) * np.sin(2.0 * np.pi * time_s / spec.internal_wave_period_s)
        source = np.clip(z - heave, 0.0, cast.depth_m[-1])
        age_h = spec.cast_age_h + time_s / 3600.0
        temperature = np.interp(source, cast.depth_m, cast.temperature_c) + spec.surface_warming_c_per_h * age_h * np.exp(-z / spec.warm_layer_m)
        salinity = np.interp(source, cast.depth_m, cast.salinity_psu)
        speed = sound_speed_teos10(self.pressure_dbar, temperature, salinity, cast.latitude_deg, cast.longitude_deg)
        return SoundSpeedProfile(z, speed)
