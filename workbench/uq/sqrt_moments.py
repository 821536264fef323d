"""``E[sqrt X]`` and ``Std[sqrt X]`` for ``X`` a constant plus a weighted sum of Gamma variables.

The one-dimensional integral behind SMR1 (eq. 5): an eigenfrequency is the square root of an
eigenvalue that is linear in the joints' Gamma-distributed moduli (eq. 8-9), so its moments are
those of ``sqrt(X)``. Exact for any number of joints, by one integral over the Gamma Laplace
transform (`sqrt_moments`), evaluated for many modes at once on a fixed rule.
"""

from __future__ import annotations

import numpy as np

__all__ = ["sqrt_moments"]


_SERIES = np.array([(-1.0) ** n / n for n in range(2, 12)])[::-1]  # x^2 (1/2 - x/3 + x^2/4 - ...), Horner order


def _x_minus_log1p(x: np.ndarray) -> np.ndarray:
    """``x - log(1 + x)`` without cancellation for small x.

    Below |x| = 0.01 the series to x^11 (truncation under 1e-20 relative); above, the direct
    difference loses at most log10(2 / 0.01) = 2.3 of 16 digits. The quadrature of `sqrt_moments`
    calls this thousands of times per mode, on every joint: a short series keeps SMR1 cheap with
    hundreds of joints.
    """
    x = np.asarray(x, float)
    out = x - np.log1p(x)
    small = np.abs(x) < 0.01
    if np.any(small):
        xs = x[small]
        acc = np.full_like(xs, _SERIES[0])
        for c in _SERIES[1:]:
            acc = acc * xs + c
        out[small] = acc * xs * xs
    return out


def _sqrt_rule(points: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """Nodes and weights in s for ``int_0^inf f(s) ds`` of `sqrt_moments`' integrand.

    Gauss-Legendre on [0, 1], [1, 10] and [10, 60] in ``u = sqrt(s)`` (the integrand goes as
    ``s^(1/2)`` at 0, smooth in u), and on [60, inf) in ``t = sqrt(60 / s)`` (a polynomial tail when all
    the stiffness is in the joints). 4 x 48 points agree with adaptive quadrature at epsrel 1e-12 to
    2e-15 over random cases of 1-300 joints, CoVs 0.01-0.45, with and without rest stiffness
    (`tests/test_propagation.py`), at a fourteenth of its cost.
    """
    x, w = np.polynomial.legendre.leggauss(points)
    t, wt = (x + 1.0) / 2.0, w / 2.0
    nodes, weights = [], []
    for a, b in ((0.0, 1.0), (1.0, 10.0), (10.0, 60.0)):
        u = np.sqrt(a) + (np.sqrt(b) - np.sqrt(a)) * t
        nodes.append(u * u)
        weights.append(wt * (np.sqrt(b) - np.sqrt(a)) * 2.0 * u)
    nodes.append(60.0 / t**2)
    weights.append(wt * 120.0 / t**3)
    return np.concatenate(nodes), np.concatenate(weights)


_RULE = _sqrt_rule()
_RULE_BYTES = 50e6  # the (modes, nodes, joints) array is built this many bytes at a time


def sqrt_moments(constant, weights, shape: np.ndarray, scale: np.ndarray) -> tuple:
    """Mean and standard deviation of ``sqrt(X)``, ``X = constant + sum_i weights_i gamma_i``.

    ``gamma_i ~ Gamma(shape_i, scale_i)`` independent, ``shape_i * scale_i = 1``. Exact, for any
    number of gammas: with ``mu = E[X]`` and ``r(s) = sum_i shape_i (x_i - log(1 + x_i))``,
    ``x_i = s weights_i scale_i / mu``,

        E[sqrt X] - sqrt(mu) = -sqrt(mu) / (2 sqrt(pi)) int_0^inf e^-s expm1(r(s)) s^(-3/2) ds,

    from ``sqrt(x) = (2 sqrt(pi))^-1 int_0^inf (1 - e^(-t x)) t^(-3/2) dt`` and the Gamma Laplace
    transform, integrated by a fixed rule (`_sqrt_rule`). The variance ``mu - E[sqrt X]^2`` is
    formed from the difference, so no cancellation spoils the small CoVs of eigenfrequencies
    (Table 3: 1e-4).

    Parameters
    ----------
    constant : scalar, or (n,) for n sums at once.
    weights : (n_gammas,), or (n, n_gammas) with a (n,) ``constant``.
    shape, scale : (n_gammas,) Gamma parameters.

    Returns
    -------
    (mean, std) : floats, or (n,) arrays when ``constant`` is an array.
    """
    single = np.ndim(constant) == 0
    c = np.atleast_1d(np.asarray(constant, float))
    w = np.atleast_2d(np.asarray(weights, float))
    shape, scale = np.asarray(shape, float), np.asarray(scale, float)
    mu = c + w.sum(axis=1)  # E[gamma_i] = 1
    if np.any(mu <= 0):
        raise ValueError(f"sqrt_moments: E[X] = {mu[mu <= 0][0]} must be positive")
    nodes, rule = _RULE
    total = np.zeros(mu.size)
    rate = w * scale / mu[:, None]
    step = max(1, int(_RULE_BYTES // (8 * nodes.size * max(w.shape[1], 1))))
    for lo in range(0, mu.size, step):
        r = np.einsum("j,mnj->mn", shape, _x_minus_log1p(nodes[None, :, None] * rate[lo:lo + step, None, :]))
        # e^-s expm1(r): expm1 keeps small r exact; for large r (no rest stiffness) it would
        # overflow where the product itself is tiny.
        small = r < 1.0
        value = np.where(small, np.exp(-nodes) * np.expm1(np.where(small, r, 0.0)),
                         np.exp(np.where(small, 0.0, r) - nodes) - np.exp(-nodes))
        total[lo:lo + step] = (value * nodes**-1.5) @ rule
    delta = -np.sqrt(mu) / (2.0 * np.sqrt(np.pi)) * total
    mean = np.sqrt(mu) + delta
    std = np.sqrt(np.maximum(-2.0 * np.sqrt(mu) * delta - delta * delta, 0.0))
    std[~np.any(w, axis=1)] = 0.0
    if single:
        return float(mean[0]), float(std[0])
    return mean, std
