"""INS + USBL positioning of a towfish (Du et al. 2018): sound speed from CTD casts, ray tracing through
constant-gradient layers, USBL fixes, INS dead reckoning and strapdown, and the INS+USBL Kalman filter."""

from .filter import FusionResult, ImuNoise, InsUsblFilter, fuse
from .fix import UsblArray, UsblFix, reply_from_geometry, usbl_fix
from .frames import LocalFrame
from .ins import EarthModel, ImuSamples, NavState, dead_reckon, strapdown
from .pipeline import UsblConfig, UsblRun, process, read_imu, read_log
from .rays import RaySolution, slant_range_from_travel_time, solve_ray, trace_for_time, trace_to_depth
from .sound import Cast, SoundSpeedProfile, read_cast, sound_speed_teos10

__all__ = ["Cast", "EarthModel", "FusionResult", "ImuNoise", "ImuSamples", "InsUsblFilter", "LocalFrame", "NavState", "RaySolution",
           "SoundSpeedProfile", "UsblArray", "UsblConfig", "UsblFix", "UsblRun", "dead_reckon", "fuse", "process", "read_cast", "read_imu",
           "read_log", "reply_from_geometry", "slant_range_from_travel_time", "solve_ray", "sound_speed_teos10", "strapdown", "trace_for_time",
           "trace_to_depth", "usbl_fix"]
