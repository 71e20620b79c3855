"""Contact tracking with an active sonar: detections in, the paper's particle filter, several tracks out.

One concept per module: ``geometry`` (the sector and its frames), ``detections`` (the CSV layout),
``particle`` (Guilmain & Sharma's filter, exactly), ``cluster`` (EM over the cloud), ``kalman`` (one
contact's EKF and its PDA update), ``association`` (joint integrated PDA: association and existence),
``tracker`` (birth, confirmation and deletion by existence, classes), ``simulate`` (divers in
clutter, TOML scenarios), ``evaluate`` and ``baseline`` (Stone Soup's metrics, its GM-PHD and JPDA), ``run``,
``output``, ``plots`` and ``cli`` (the ``lost track`` command). See docs/track.md.
"""

from .detections import DetectionReport, Ping, read_detections, write_detections
from .geometry import Sonar, polar_to_world, world_to_polar
from .particle import DiverParticleFilter, PaperParameters, clutter_floor
from .run import TrackerRun, run_tracker
from .simulate import Simulation, TrackScenario, builtin_scenario_path, load_scenario, simulate
from .tracker import MultiTargetTracker, TrackerParameters, TrackReport

__all__ = [
    "DetectionReport", "DiverParticleFilter", "MultiTargetTracker", "PaperParameters", "Ping", "Simulation", "Sonar",
    "TrackReport", "TrackScenario", "TrackerParameters", "TrackerRun", "builtin_scenario_path", "clutter_floor",
    "load_scenario", "polar_to_world", "read_detections", "run_tracker", "simulate", "world_to_polar", "write_detections",
]
