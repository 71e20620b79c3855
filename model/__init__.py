"""The specification, executable: the exact correlator, its bit widths and fixed-point conversion.

Imports numpy only, so that the gateware, the simulators and the host all stand on the same
definition.
"""

from .correlator import DEPTH_MAX, DEPTH_MIN, BestFit, Placement, best_fit, check_inputs, correlate
from .fixed import dequantize, quantize
from .widths import Bound, CorrelatorWidths, bits_for, correlator_widths, placement_widths

__all__ = [
    "DEPTH_MAX",
    "DEPTH_MIN",
    "BestFit",
    "Bound",
    "CorrelatorWidths",
    "Placement",
    "best_fit",
    "bits_for",
    "check_inputs",
    "correlate",
    "correlator_widths",
    "dequantize",
    "placement_widths",
    "quantize",
]
