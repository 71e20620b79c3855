"""The closed-form 2 x 2 algebra the filters use at every update, against NumPy's general routines."""

import math

import numpy as np

from lost.host.nav.moments import eigenvalues_2x2, largest_sigma, moments, quadratic_form_2x2


def test_the_closed_forms_match_numpys_on_random_symmetric_matrices():
    rng = np.random.default_rng(3)
    for _ in range(500):
        root = rng.normal(size=(2, 2)) * 10.0 ** rng.uniform(-3, 3)
        matrix = root @ root.T + 1e-9 * np.eye(2)
        d = rng.normal(size=2) * 10.0 ** rng.uniform(-2, 2)
        want = float(d @ np.linalg.solve(matrix, d))
        assert math.isclose(quadratic_form_2x2(d, matrix), want, rel_tol=1e-6 * np.linalg.cond(matrix))
        np.testing.assert_allclose(eigenvalues_2x2(matrix), np.linalg.eigvalsh(matrix), rtol=1e-9, atol=1e-9 * np.abs(matrix).max())
        assert math.isclose(largest_sigma(matrix), math.sqrt(np.linalg.eigvalsh(matrix)[1]), rel_tol=1e-9)


def test_a_singular_matrix_gives_an_infinite_quadratic_form():
    assert quadratic_form_2x2(np.array([1.0, 2.0]), np.array([[1.0, 2.0], [2.0, 4.0]])) == math.inf
    assert quadratic_form_2x2(np.array([1.0, 0.0]), np.zeros((2, 2))) == math.inf


def test_weighted_moments_are_the_weighted_mean_and_covariance():
    rng = np.random.default_rng(4)
    x, y, w = rng.normal(size=300), rng.normal(size=300) * 2 + 0.5 * rng.normal(size=300), rng.random(300)
    w /= w.sum()
    mean, cov = moments(w, x, y)
    np.testing.assert_allclose(mean, [np.average(x, weights=w), np.average(y, weights=w)], rtol=1e-12)
    np.testing.assert_allclose(cov, np.cov(np.vstack([x, y]), aweights=w, bias=True), rtol=1e-10)
