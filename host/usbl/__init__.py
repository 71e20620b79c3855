"""INS + USBL positioning of a towfish (Du et al. 2018): sound speed from CTD casts, ray tracing through
constant-gradient layers, USBL fixes, INS dead reckoning and strapdown, and the INS+USBL Kalman filter."""

from .rays import RaySolution, slant_range_from_travel_time, solve_ray, trace_for_time, trace_to_depth
from .sound import Cast, SoundSpeedProfile, read_cast, sound_speed_teos10

__all__ = ["Cast", "RaySolution", "SoundSpeedProfile", "read_cast", "slant_range_from_travel_time", "solve_ray",
           "sound_speed_teos10", "trace_for_time", "trace_to_depth"]
