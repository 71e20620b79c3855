"""Contact tracking with an active sonar: detections in, the paper's particle filter, tracks out."""

from .detections import DetectionReport, Ping, read_detections, write_detections
from .geometry import Sonar, polar_to_world, world_to_polar

__all__ = ["DetectionReport", "Ping", "Sonar", "polar_to_world", "read_detections", "world_to_polar", "write_detections"]
