"""A grid's per-node uncertainty layer: which variable of a file holds it, and whether it is one.

The navigation's map error model takes a grid's standard deviation per node (``Grid.sigma_m``) when the
grid carries one. :func:`read_grid` looks for it beside the depth:

NetCDF
    The variable the depth variable names in its CF ``ancillary_variables`` attribute when that one is a
    standard deviation (below); else the first 2-D variable whose name is one of :data:`SIGMA_NAMES`
    (``depth_std``, what ``lost grid`` writes, first); else the first whose CF ``standard_name`` ends in
    ``standard_error`` (CF's modifier: ``sea_floor_depth_below_sea_surface standard_error``) or whose
    ``long_name`` says ``standard deviation`` or ``uncertainty``. A variable named so but holding
    something else (``units`` that are not metres) is refused by name, not read as metres.
BAG
    Its ``uncertainty`` layer (GDAL's BAG driver's band of that name).

Values are metres, one standard deviation. A hole of the layer (NaN or the file's fill value) is NaN in
``Grid.sigma_m``: a node of one sounding has no spread (``lost grid`` writes NaN there), and the
navigation's own per-node model stands in for it. A layer of another shape than the depth, negative or
infinite values are named errors (:class:`~lost.host.io.errors.UncertaintyLayerError`).
"""

from __future__ import annotations

import numpy as np

from .errors import UncertaintyLayerError

__all__ = ["SIGMA_NAMES", "sigma_variable", "check_sigma_layer", "check_units", "fill_sigma_gaps"]

#: Variable names read as the depth's standard deviation, in order (``lost grid``'s first), compared without case.
SIGMA_NAMES = ("depth_std", "elevation_std", "z_std", "std", "stdev", "stddev", "standard_deviation", "sd", "uncertainty",
               "depth_uncertainty", "z_uncertainty")
_METRE_UNITS = ("", "m", "metre", "metres", "meter", "meters")


def _is_sigma_by_attributes(attrs: dict) -> bool:
    standard = str(attrs.get("standard_name", "")).strip().lower()
    long_name = str(attrs.get("long_name", "")).lower()
    return standard.endswith("standard_error") or "standard deviation" in long_name or "uncertainty" in long_name


def sigma_variable(ds, depth_variable: str) -> str | None:
    """The name of ``ds``'s variable holding the standard deviation of ``depth_variable``, or None (see the module)."""
    two_d = [str(name) for name, v in ds.data_vars.items() if v.ndim == 2 and name != depth_variable]
    ancillary = str(ds[depth_variable].attrs.get("ancillary_variables", "")).split()
    for name in ancillary:
        if name in ds.data_vars and (_is_sigma_by_attributes(ds[name].attrs) or name.lower() in SIGMA_NAMES):
            return name
    by_name = {name.lower(): name for name in two_d}
    for candidate in SIGMA_NAMES:
        if candidate in by_name:
            return by_name[candidate]
    return next((name for name in two_d if _is_sigma_by_attributes(ds[name].attrs)), None)


def check_units(attrs: dict, file_name: str, variable: str) -> None:
    """Refuse a standard deviation layer whose ``units`` are not metres."""
    units = str(attrs.get("units", "")).strip().lower()
    if units not in _METRE_UNITS:
        raise UncertaintyLayerError(f"{file_name}: the uncertainty layer {variable!r} is in {units!r}; LOST reads it in metres (units 'm')")


def check_sigma_layer(sigma: np.ndarray, depth: np.ndarray, file_name: str, variable: str) -> np.ndarray:
    """The layer as float64 metres, NaN on the depth's holes; a named error for another shape, a negative or infinite value."""
    sigma = np.asarray(sigma, dtype=np.float64)
    if sigma.shape != depth.shape:
        raise UncertaintyLayerError(f"{file_name}: the uncertainty layer {variable!r} is {' x '.join(map(str, sigma.shape)) or 'a scalar'} "
                                    f"nodes but the depth {' x '.join(map(str, depth.shape))}; a layer must match its depth node for node")
    negative = sigma < 0
    if negative.any():
        r, c = (int(v[0]) for v in np.nonzero(negative))
        raise UncertaintyLayerError(f"{file_name}: the uncertainty layer {variable!r} has {int(negative.sum())} negative standard "
                                    f"deviation(s) (first {float(sigma[r, c])!r} m at row {r}, column {c} of the file)")
    infinite = np.isinf(sigma)
    if infinite.any():
        raise UncertaintyLayerError(f"{file_name}: the uncertainty layer {variable!r} has {int(infinite.sum())} infinite value(s)")
    return np.where(np.isfinite(depth), sigma, np.nan)


def fill_sigma_gaps(grid, fallback_m: float):
    """The grid with its uncertainty layer's gaps on depth nodes (one sounding, no spread) set to ``fallback_m``, and a report.

    The navigation's map error model (``lost.host.nav.maperror.check_node_sigma``) refuses a NaN sigma on a node
    with a depth; ``fallback_m`` is its own stand-in for an unknown survey error (``NavParameters.survey_sigma_m``).
    The report (a dict for a run's summary) says where the map's survey error came from, node by node.
    """
    from dataclasses import replace

    has_depth = np.isfinite(grid.depth_m)
    if grid.sigma_m is None:
        return grid, {"source": "survey_sigma_m (the grid carries no uncertainty layer)", "survey_sigma_m": float(fallback_m),
                      "nodes_from_layer": 0, "nodes_from_survey_sigma_m": int(has_depth.sum())}
    gaps = has_depth & ~np.isfinite(grid.sigma_m)
    from_layer = has_depth & ~gaps
    report = {"source": "the grid file's uncertainty layer", "survey_sigma_m": float(fallback_m),
              "nodes_from_layer": int(from_layer.sum()), "nodes_from_survey_sigma_m": int(gaps.sum()),
              "layer_median_m": round(float(np.median(grid.sigma_m[from_layer])), 4) if from_layer.any() else None}
    if gaps.any():
        grid = replace(grid, sigma_m=np.where(gaps, float(fallback_m), grid.sigma_m))
    return grid, report
