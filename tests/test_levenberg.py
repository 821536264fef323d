"""`workbench.extraction.levenberg.lm` is ``scipy.optimize.least_squares(method="lm")`` without its wrapper:
the same MINPACK iterations, so the same solution, cost and Jacobian, on well-conditioned fits of the kinds
the circle fits solve (a circle, an exponential decay; 1e-14 relative, last-bit rounding of the memory
layout aside), and the same errors.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from workbench.extraction.levenberg import lm

RNG = np.random.default_rng(7)
T = np.linspace(0.0, 4.0, 60)
DECAY = 2.5 * np.exp(-1.3 * T) + 0.4 + 0.01 * RNG.standard_normal(T.size)
ANGLE = np.linspace(0.0, 5.0, 40)
POINTS = (1.0 + 2.0j) + 3.0 * np.exp(1j * ANGLE) + 0.02 * (RNG.standard_normal(40) + 1j * RNG.standard_normal(40))


def _decay(p: np.ndarray) -> np.ndarray:
    return p[0] * np.exp(-p[1] * T) + p[2] - DECAY


def _decay_jac(p: np.ndarray) -> np.ndarray:
    e = np.exp(-p[1] * T)
    return np.column_stack([e, -p[0] * T * e, np.ones_like(T)])


def _circle(p: np.ndarray) -> np.ndarray:
    return np.hypot(POINTS.real - p[0], POINTS.imag - p[1]) - p[2]


def _circle_jac(p: np.ndarray) -> np.ndarray:
    d = np.hypot(POINTS.real - p[0], POINTS.imag - p[1])
    return np.column_stack([-(POINTS.real - p[0]) / d, -(POINTS.imag - p[1]) / d, -np.ones_like(d)])


@pytest.mark.parametrize("fun, jac, x0, tolerances", [
    (_decay, _decay_jac, [1.0, 1.0, 0.0], {}),
    (_decay, _decay_jac, [1.0, 1.0, 0.0], {"xtol": 1e-15, "ftol": 1e-15, "gtol": 1e-15}),
    (_circle, _circle_jac, [0.0, 0.0, 1.0], {"xtol": 1e-14, "ftol": 1e-14}),
])
def test_lm_gives_least_squares_answer(fun, jac, x0, tolerances):
    want = least_squares(fun, x0, jac=jac, method="lm", **tolerances)
    got = lm(fun, x0, jac, **tolerances)
    np.testing.assert_allclose(got.x, want.x, rtol=1e-14, atol=0.0)
    np.testing.assert_allclose(got.cost, want.cost, rtol=1e-14)
    np.testing.assert_allclose(got.jac, want.jac, rtol=1e-14, atol=1e-300)


def test_lm_evaluates_no_point_twice():
    seen: list[bytes] = []

    def counted(p: np.ndarray) -> np.ndarray:
        seen.append(np.asarray(p, float).tobytes())
        return _decay(p)

    lm(counted, [1.0, 1.0, 0.0], _decay_jac)
    assert len(seen) == len(set(seen))


def test_lm_refuses_what_least_squares_refuses():
    with pytest.raises(ValueError, match="not finite"):
        lm(lambda p: np.full(3, np.nan), [1.0], lambda p: np.ones((3, 1)))
    with pytest.raises(ValueError, match="number of residuals"):
        lm(lambda p: np.zeros(1), [1.0, 2.0], lambda p: np.ones((1, 2)))
