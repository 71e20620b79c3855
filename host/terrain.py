"""Seeded synthetic sea floors, generated in code, for the demo, the tests and the scenarios."""

from __future__ import annotations

import numpy as np

__all__ = ["synthetic_terrain"]


def _fractal(shape: tuple[int, int], rng: np.random.Generator, hurst: float, *, corner_nodes: float | None = None,
             aspect: float = 1.0, azimuth_deg: float = 0.0) -> np.ndarray:
    """Unit-variance random surface by spectral synthesis.

    Without ``corner_nodes``: a pure power law, power ~ k**-(2 * hurst + 2). With it: the anisotropic
    von Karman spectrum of Goff and Jordan (1988), the standard statistical model of sea-floor
    morphology, power ~ (1 + (k / k0)**2)**-(hurst + 1) with k0 = 1 / corner_nodes: flat beyond the
    corner wavelength, the same power law below it. ``aspect`` > 1 stretches the features along
    ``azimuth_deg`` (clockwise from north, i.e. from the row axis), as abyssal hills are elongated.
    """
    ky = np.fft.fftfreq(shape[0])[:, None]
    kx = np.fft.rfftfreq(shape[1])[None, :]
    if aspect != 1.0:
        a = np.radians(azimuth_deg)
        along = ky * np.cos(a) + kx * np.sin(a)
        across = -ky * np.sin(a) + kx * np.cos(a)
        ky, kx = along * aspect, across
    k = np.hypot(ky, kx)
    if corner_nodes is None:
        k[0, 0] = np.inf  # no mean
        amplitude = k ** (-(hurst + 1.0))
    else:
        amplitude = (1.0 + (k * corner_nodes) ** 2) ** (-(hurst + 1.0) / 2.0)
        amplitude[0, 0] = 0.0
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
    corner_nodes: float | None = None,
    aspect: float = 1.0,
    azimuth_deg: float = 0.0,
    repeat_nodes: tuple[int, int] | None = None,
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
    corner_nodes, aspect, azimuth_deg : float
        With ``corner_nodes``, the roughness follows the von Karman spectrum of Goff and Jordan (corner
        wavelength in nodes, elongation and its direction; see ``_fractal``) instead of a pure power law.
    repeat_nodes : (rows, cols), optional
        Build a tile of this many nodes and repeat it over the floor: terrain that looks alike every
        tile, on which a terrain navigator must not claim a fix it cannot tell apart.

    Raises
    ------
    ValueError
        A non-2-D shape, or a smooth fraction outside [0, 1].
    """
    if len(shape) != 2 or min(shape) < 2:
        raise ValueError(f"shape must be two sides of at least 2 nodes, got {shape!r}")
    if not 0.0 <= smooth_fraction <= 1.0:
        raise ValueError(f"smooth_fraction must lie in [0, 1], got {smooth_fraction!r}")
    if aspect <= 0 or (corner_nodes is not None and corner_nodes <= 0):
        raise ValueError(f"aspect and corner_nodes must be positive, got {aspect!r} and {corner_nodes!r}")
    if repeat_nodes is not None:
        tile = tuple(int(n) for n in repeat_nodes)
        if len(tile) != 2 or min(tile) < 2:
            raise ValueError(f"repeat_nodes must be two sides of at least 2 nodes, got {repeat_nodes!r}")
        floor = synthetic_terrain(tile, seed=seed, mean_depth_m=mean_depth_m, relief_m=relief_m, roughness_m=roughness_m,
                                  hurst=hurst, corner_nodes=corner_nodes, aspect=aspect, azimuth_deg=azimuth_deg)
        reps = (-(-shape[0] // tile[0]), -(-shape[1] // tile[1]))
        return np.tile(floor, reps)[: shape[0], : shape[1]]
    rng = np.random.default_rng(seed)
    relief = _fractal(shape, rng, hurst=1.5)
    rough = _fractal(shape, rng, hurst=hurst, corner_nodes=corner_nodes, aspect=aspect, azimuth_deg=azimuth_deg)
    cols = np.arange(shape[1]) / max(shape[1] - 1, 1)
    # A smooth ramp between the rough and the smooth region, so the roughness has no seam.
    edge = 1.0 - smooth_fraction
    envelope = np.clip((edge - cols) / 0.1 + 0.5, 0.0, 1.0) if smooth_fraction > 0 else np.ones_like(cols)
    return mean_depth_m + relief_m * relief + roughness_m * rough * envelope[None, :]
