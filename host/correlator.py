"""One entry point to every correlator backend.

A navigator calls :func:`correlate` and never learns whether its surface came from NumPy, the C
kernel, a simulated RTL core or a board: every backend returns the golden model's integers.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from lost import model

from .software import software_surface

__all__ = ["BACKENDS", "correlate"]

SurfaceFn = Callable[[np.ndarray, np.ndarray, np.ndarray, bool], np.ndarray]


def _model_surface(terrain: np.ndarray, patch: np.ndarray, mask: np.ndarray, mean_compensation: bool) -> np.ndarray:
    return model.correlate(terrain, patch, mask=mask, mean_compensation=mean_compensation)


def _rtl_surface(terrain: np.ndarray, patch: np.ndarray, mask: np.ndarray, mean_compensation: bool) -> np.ndarray:
    # Lazily: only this backend needs Amaranth, cocotb and Verilator.
    from lost.sim.rtl import rtl_surface

    return rtl_surface(terrain, patch, mask, mean_compensation)


#: Backend name to a function of validated (terrain, patch, mask, mean_compensation).
BACKENDS: dict[str, SurfaceFn] = {
    "software": software_surface,
    "model": _model_surface,
    "rtl": _rtl_surface,
}


def correlate(
    terrain: np.ndarray,
    patch: np.ndarray,
    *,
    mask: np.ndarray | None = None,
    mean_compensation: bool = True,
    backend: str = "software",
) -> np.ndarray:
    """Correlate a sonar patch against a terrain map; the definition is :func:`lost.model.correlate`.

    Parameters
    ----------
    terrain, patch, mask, mean_compensation
        As for :func:`lost.model.correlate`.
    backend : str
        ``"software"`` (default): the fast SIMD kernel. ``"model"``: the golden model, plain NumPy.
        ``"rtl"``: the correlator's generated Verilog on Verilator (:mod:`lost.sim.rtl`; a build per
        shape, for checking the gateware on real data, not for speed).

    Returns
    -------
    (H - h + 1, W - w + 1) int64 array, identical for every backend.

    Raises
    ------
    ValueError
        Bad inputs (see :func:`lost.model.check_inputs`) or an unknown backend.
    """
    try:
        surface = BACKENDS[backend]
    except (KeyError, TypeError):
        raise ValueError(f"unknown correlator backend {backend!r}; choose one of {sorted(BACKENDS)}") from None
    terrain, patch, mask = model.check_inputs(terrain, patch, mask, mean_compensation)
    return surface(terrain, patch, mask, bool(mean_compensation))
