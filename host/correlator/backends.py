"""The correlator backends: the golden model, the fast software kernel, and the device behind a driver.

Every backend answers :meth:`Backend.run` for validated inputs and an in-map search area. The hardware
backends (``rtl``: the device co-simulated on Verilator; ``fpga``: the board on a serial port) are one
class, :class:`DeviceBackend`, holding a :class:`~lost.host.correlator.driver.CorrelatorDriver` over
the transport it opens on first use.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from lost import model

from .result import Area, Outcome

__all__ = ["Backend", "DeviceBackend", "FunctionBackend", "crop"]


def crop(terrain: np.ndarray, patch_shape: tuple[int, int], area: Area) -> np.ndarray:
    """The map window an in-map ``area`` of placements reads."""
    (h, w), (i0, j0, rows, cols) = patch_shape, area
    return terrain[i0 : i0 + rows + h - 1, j0 : j0 + cols + w - 1]


class Backend:
    """A correlator backend; :meth:`run` is all a caller needs."""

    name: str = "?"

    def run(self, terrain: np.ndarray, patch: np.ndarray, mask: np.ndarray, mean_compensation: bool, area: Area,
            exclusion_radius: int, *, map_key: object | None = None) -> Outcome:
        """V over the in-map ``area`` of validated inputs, and the hardware's best fit if it has one.

        ``map_key``: a caller holding the map unchanged between calls names it, so that a device need not
        fingerprint the map to know its tile is still resident.
        """
        raise NotImplementedError

    def close(self) -> None:
        """Release what the backend holds (a serial port, a simulator); it opens again when used."""


class FunctionBackend(Backend):
    """A backend that is a function of (terrain window, patch, mask, mode) to the surface."""

    def __init__(self, name: str, surface: Callable[[np.ndarray, np.ndarray, np.ndarray, bool], np.ndarray]):
        self.name = name
        self._surface = surface

    def run(self, terrain, patch, mask, mean_compensation, area, exclusion_radius, *, map_key=None) -> Outcome:
        return Outcome(self._surface(crop(terrain, patch.shape, area), patch, mask, mean_compensation))

    def __call__(self, terrain, patch, mask, mean_compensation) -> np.ndarray:
        return self._surface(terrain, patch, mask, mean_compensation)


def model_surface(terrain: np.ndarray, patch: np.ndarray, mask: np.ndarray, mean_compensation: bool) -> np.ndarray:
    return model.correlate(terrain, patch, mask=mask, mean_compensation=mean_compensation)


def software_surface(terrain: np.ndarray, patch: np.ndarray, mask: np.ndarray, mean_compensation: bool) -> np.ndarray:
    # Lazily: the C kernel loads on first use, after OMP_WAIT_POLICY is set (see software.py).
    from .software import software_surface as kernel

    return kernel(terrain, patch, mask, mean_compensation)


class DeviceBackend(Backend):
    """The device behind a :class:`~lost.host.correlator.driver.CorrelatorDriver`.

    Parameters
    ----------
    name : str
        ``"rtl"`` or ``"fpga"``.
    open_transport : callable returning a Transport
        Called on first use (and after :meth:`close`); the device stays open between calls, so its
        map tile stays resident.
    """

    def __init__(self, name: str, open_transport: Callable[[], object]):
        self.name = name
        self._open_transport = open_transport
        self._driver = None

    @property
    def driver(self):
        if self._driver is None:
            from .driver import CorrelatorDriver

            self._driver = CorrelatorDriver(self._open_transport())
        return self._driver

    def run(self, terrain, patch, mask, mean_compensation, area, exclusion_radius, *, map_key=None) -> Outcome:
        return self.driver.correlate(terrain, patch, mask, mean_compensation, area=area, exclusion_radius=exclusion_radius,
                                     map_key=map_key)

    def __call__(self, terrain, patch, mask, mean_compensation) -> np.ndarray:
        (H, W), (h, w) = terrain.shape, patch.shape
        return self.run(terrain, patch, mask, mean_compensation, (0, 0, H - h + 1, W - w + 1), 1).surface

    def close(self) -> None:
        if self._driver is not None:
            self._driver.close()
            self._driver = None
