"""Seeded synthetic sea floors, generated in code, for the demo, the tests and the scenarios."""

from __future__ import annotations

import numpy as np

__all__ = ["synthetic_terrain"]


def _fractal(shape: tuple[int, int], rng: np.random.Generator, hurst: float) -> np.ndarray:
    """Unit-variance fractal surface by spectral synthesis: power ~ k**-(2 * hurst + 2)."""
    ky = np.fft.fftfreq(shape[0])[:, None]
    kx = np.fft.rfftfreq(shape[1])[None, :]
    k = np.hypot(ky, kx)
    k[0, 0] = np.inf  # no mean
    amplitude = k ** (-(hurst + 1.0))
    phase = rng.uniform(0.0, 2.0 * np.pi, amplitude.shape)
    surface = np.fft.irfft2(amplitude * np.exp(1j * phase), s=shape)
    return surface / surface.std()


def synthetic_terrain(
    shape: tuple[int, int] = (501, 501),
    *,
    seed: int = 0,
    mean_depth_m: float = 1000.0,
    relief_m: float = 60.0,
    roughness_m: float = 8.0,
    smooth_fraction: float = 0.0,
    hurst: float = 0.8,
) -> np.ndarray:
    """A sea floor in metres (positive down), one value per map node.

    Parameters
    ----------
    shape : (rows, cols)
        Map nodes; the node spacing is the caller's (10 m in the paper).
    seed : int
        The same seed gives the same floor on every machine.
    mean_depth_m : float
        Mean depth.
    relief_m : float
        Standard deviation of the long-wavelength relief (hills and basins).
    roughness_m : float
        Standard deviation of the short-wavelength roughness where the floor is rough.
    smooth_fraction : float
        Fraction of the columns, from the east edge, where the roughness fades to nothing: terrain
        on which a correlator has little to hold on to.
    hurst : float
        Hurst exponent of the roughness; lower is rougher at the smallest scales.

    Raises
    ------
    ValueError
        A non-2-D shape, or a smooth fraction outside [0, 1].
    """
    if len(shape) != 2 or min(shape) < 2:
        raise ValueError(f"shape must be two sides of at least 2 nodes, got {shape!r}")
    if not 0.0 <= smooth_fraction <= 1.0:
        raise ValueError(f"smooth_fraction must lie in [0, 1], got {smooth_fraction!r}")
    rng = np.random.default_rng(seed)
    relief = _fractal(shape, rng, hurst=1.5)
    rough = _fractal(shape, rng, hurst=hurst)
    cols = np.arange(shape[1]) / max(shape[1] - 1, 1)
    # A smooth ramp between the rough and the smooth region, so the roughness has no seam.
    edge = 1.0 - smooth_fraction
    envelope = np.clip((edge - cols) / 0.1 + 0.5, 0.0, 1.0) if smooth_fraction > 0 else np.ones_like(cols)
    return mean_depth_m + relief_m * relief + roughness_m * rough * envelope[None, :]
