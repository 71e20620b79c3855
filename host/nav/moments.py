"""Moments of a weighted point set and the closed-form algebra of 2 x 2 symmetric matrices the filters ask for at every
update (NumPy's general routines cost tens of microseconds a call)."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["eigenvalues_2x2", "largest_sigma", "moments", "quadratic_form_2x2"]


def eigenvalues_2x2(covariance: np.ndarray) -> tuple[float, float]:
    """The smaller and the larger eigenvalue of a symmetric 2 x 2 matrix, in closed form.

    ``np.linalg.eigvalsh`` costs some 30 microseconds a call, and the filters ask several times a record.
    """
    a, b, c = float(covariance[0, 0]), float(covariance[0, 1]), float(covariance[1, 1])
    centre, half = 0.5 * (a + c), math.hypot(0.5 * (a - c), b)
    return centre - half, centre + half


def largest_sigma(covariance: np.ndarray) -> float:
    """The 1-sigma of a 2 x 2 covariance's widest axis."""
    return math.sqrt(max(eigenvalues_2x2(covariance)[1], 0.0))


def moments(weights: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of points weighted by normalized ``weights``."""
    mx, my = float(np.sum(weights * x)), float(np.sum(weights * y))
    dx, dy = x - mx, y - my
    sxy = float(np.sum(weights * dx * dy))
    cov = np.array([[float(np.sum(weights * dx * dx)), sxy], [sxy, float(np.sum(weights * dy * dy))]])
    return np.array([mx, my]), cov


def quadratic_form_2x2(d: np.ndarray, matrix: np.ndarray) -> float:
    """``d' matrix^-1 d`` for a symmetric 2 x 2 matrix, in closed form (inf where it is singular): ``np.linalg.solve``
    costs some 20 microseconds a call, and every update asks."""
    a, b, c = float(matrix[0, 0]), float(matrix[0, 1]), float(matrix[1, 1])
    x, y = float(d[0]), float(d[1])
    det = a * c - b * b
    return (c * x * x - 2.0 * b * x * y + a * y * y) / det if det != 0.0 else float("inf")
