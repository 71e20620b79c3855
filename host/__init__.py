"""Everything a navigator runs: correlator backends, and (in later issues) grid and log I/O, the
LOST pipeline, filters, fusion, the tracker and the command line."""

from .correlator import BACKENDS, correlate

__all__ = ["BACKENDS", "correlate"]
