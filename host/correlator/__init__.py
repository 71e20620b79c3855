"""The correlator, as a navigator sees it: one entry point, one result type, every backend.

:func:`correlation` returns a :class:`Correlation` (surface, valid placements, best fit, runner-up)
from any backend; :func:`correlate` returns the bare surface, as before. A navigator never learns
whether its surface came from NumPy, the C kernel, the co-simulated device or a board: every backend
returns the golden model's integers.

Backends (:data:`BACKENDS`): ``software`` (default, the SIMD kernel), ``model`` (the golden model),
``rtl`` (the device top-level co-simulated on Verilator, through :class:`CorrelatorDriver`), ``fpga``
(the board on a serial port; :func:`configure_backend` ``("fpga", port=...)`` first).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lost import model

from .backends import Backend, DeviceBackend, FunctionBackend, model_surface, software_surface
from .result import Area, Correlation, Outcome, choose_fit, placed, valid_placements

__all__ = ["BACKENDS", "Backend", "Correlation", "Outcome", "configure_backend", "correlate", "correlation", "valid_placements"]


def _rtl_transport(variant: str | None = None):
    from .transports import CosimTransport

    return CosimTransport(variant=variant)


def _fpga_unconfigured():
    raise ValueError("the fpga backend needs a serial port: lost ... --backend fpga --port /dev/ttyUSB0, "
                     "or lost.host.correlator.configure_backend('fpga', port=...)")


#: Backend name to backend; each is also callable as ``backend(terrain, patch, mask, mean_compensation)``.
BACKENDS: dict[str, Backend] = {
    "software": FunctionBackend("software", software_surface),
    "model": FunctionBackend("model", model_surface),
    "rtl": DeviceBackend("rtl", _rtl_transport),
    "fpga": DeviceBackend("fpga", _fpga_unconfigured),
}


def configure_backend(name: str, **options: Any) -> Backend:
    """Set up a hardware backend: ``("rtl", variant=...)`` or ``("fpga", port=..., baud=...)``.

    The backend so configured serves every later call by that name (the command line does this once
    for ``--backend fpga --port``). Returns it.
    """
    from .transports import CosimTransport, SerialTransport

    if name == "rtl":
        backend = DeviceBackend("rtl", lambda: CosimTransport(**options))
    elif name == "fpga":
        if not options.get("port"):
            _fpga_unconfigured()
        backend = DeviceBackend("fpga", lambda: SerialTransport(**options))
    else:
        raise ValueError(f"only the hardware backends (rtl, fpga) take options, got {name!r}")
    BACKENDS[name].close()
    BACKENDS[name] = backend
    return backend


def _backend(backend: str | Backend) -> Backend:
    if isinstance(backend, Backend):
        return backend
    try:
        return BACKENDS[backend]
    except (KeyError, TypeError):
        raise ValueError(f"unknown correlator backend {backend!r}; choose one of {sorted(BACKENDS)}") from None


def correlate(
    terrain: np.ndarray,
    patch: np.ndarray,
    *,
    mask: np.ndarray | None = None,
    mean_compensation: bool = True,
    backend: str | Backend = "software",
) -> np.ndarray:
    """The surface of a sonar patch over a terrain map; the definition is :func:`lost.model.correlate`.

    Returns
    -------
    (H - h + 1, W - w + 1) int64 array, identical for every backend. :func:`correlation` gives the
    valid placements and the best fit with it.

    Raises
    ------
    ValueError
        Bad inputs (see :func:`lost.model.check_inputs`) or an unknown backend.
    """
    chosen = _backend(backend)
    terrain, patch, mask = model.check_inputs(terrain, patch, mask, mean_compensation)
    (H, W), (h, w) = terrain.shape, patch.shape
    return chosen.run(terrain, patch, mask, bool(mean_compensation), (0, 0, H - h + 1, W - w + 1), 1).surface


def _check_area(area: Any, surface_shape: tuple[int, int]) -> Area:
    if area is None:
        return (0, 0, *surface_shape)
    if (not isinstance(area, (tuple, list)) or len(area) != 4
            or not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in area)):
        raise ValueError(f"area must be (i0, j0, rows, cols) integers, got {area!r}")
    i0, j0, rows, cols = (int(v) for v in area)
    if rows < 1 or cols < 1:
        raise ValueError(f"area must have at least one placement, got rows={rows}, cols={cols}")
    return i0, j0, rows, cols


def correlation(
    terrain: np.ndarray,
    patch: np.ndarray,
    *,
    mask: np.ndarray | None = None,
    mean_compensation: bool = True,
    backend: str | Backend = "software",
    holes: np.ndarray | None = None,
    area: Area | None = None,
    exclusion_radius: int | None = None,
) -> Correlation:
    """Correlate a patch over a search area of a map; return the surface, valid placements and best fit.

    Parameters
    ----------
    terrain, patch, mask, mean_compensation
        As for :func:`lost.model.correlate`; ``terrain`` is the whole map (a hardware backend keeps a
        tile of it resident between calls).
    backend : str or Backend
        A name of :data:`BACKENDS` or a backend object.
    holes : (H, W) bool array, optional
        Map nodes without a measured depth: a placement where a valid node of the patch falls on one is
        not valid (a hole under a node the mask leaves out does not count: see :func:`valid_placements`).
    area : (i0, j0, rows, cols), optional
        The placements to search; may reach past the map's edges (those placements are not valid).
        Default: every placement of the map.
    exclusion_radius : int, optional
        Chebyshev radius around the best fit outside which the runner-up is sought; default half the
        patch's larger side.

    Raises
    ------
    ValueError
        Bad inputs, an unknown backend, an area without placements.
    """
    chosen = _backend(backend)
    terrain, patch, mask = model.check_inputs(terrain, patch, mask, mean_compensation)
    (H, W), (h, w) = terrain.shape, patch.shape
    radius = max(h, w) // 2 if exclusion_radius is None else int(exclusion_radius)
    if radius < 0:
        raise ValueError(f"exclusion_radius must be non-negative, got {exclusion_radius}")
    i0, j0, rows, cols = _check_area(area, (H - h + 1, W - w + 1))
    valid = valid_placements((H, W), (h, w), (i0, j0, rows, cols), holes, mask)
    # The in-map part of the area is what a backend computes.
    a0, a1 = max(i0, 0), min(i0 + rows, H - h + 1)
    b0, b1 = max(j0, 0), min(j0 + cols, W - w + 1)
    fit, cycles, best_from = None, None, "host"
    surface = None
    if a0 < a1 and b0 < b1:
        outcome = chosen.run(terrain, patch, mask, bool(mean_compensation), (a0, b0, a1 - a0, b1 - b0), radius)
        if (a0, b0, a1 - a0, b1 - b0) == (i0, j0, rows, cols):
            surface = outcome.surface  # the whole area is on the map: no second surface-sized copy
        else:
            surface = np.zeros((rows, cols), dtype=np.int64)
            surface[a0 - i0 : a1 - i0, b0 - j0 : b1 - j0] = outcome.surface
        cycles = outcome.cycles
        if outcome.fit is not None and valid.all():
            fit, best_from = outcome.fit, "hardware"  # the device searched exactly these placements
    if surface is None:
        surface = np.zeros((rows, cols), dtype=np.int64)
    if fit is None:
        fit = choose_fit(surface, valid, radius)
    best, runner_up = placed(fit, (i0, j0))
    return Correlation(surface, valid, best, runner_up, radius, (i0, j0), chosen.name, best_from, cycles)
