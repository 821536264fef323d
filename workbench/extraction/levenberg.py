"""Levenberg-Marquardt on small dense problems: MINPACK's ``lmder`` without `scipy.optimize.least_squares`'s
per-evaluation bookkeeping.

The circle fits solve thousands of least-squares problems of 3 to 12 parameters (a 12-test campaign: about
6000, 150 000 residual and Jacobian evaluations). ``least_squares(method="lm")`` runs MINPACK's ``lmder``,
but wraps every evaluation in a ``VectorFunction`` (copies and comparisons of ``x`` and of the values) that
cost a third of the evaluations themselves. `lm` calls the same ``lmder`` through the public
`scipy.optimize.leastsq` with the settings ``least_squares`` gives it (``factor=100``, ``diag=None``, i.e.
``x_scale="jac"``, ``maxfev = 100 n``): the same iterations, solution, cost and Jacobian at the solution
(``tests/test_levenberg.py``). Bit for bit but for ``lmder``'s own last-bit rounding, which depends on where
its work arrays fall in memory: on an ill-conditioned fit (a weak or edge-of-band mode) that is amplified,
and ``least_squares`` itself then differs from one call to the next.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import leastsq

__all__ = ["LMResult", "LastCall", "lm"]


@dataclass(frozen=True)
class LMResult:
    """The fields of `scipy.optimize.OptimizeResult` the fits read.

    Attributes
    ----------
    x : (n,) solution.
    cost : half the residual sum of squares at ``x``.
    jac : (m, n) Jacobian at ``x``.
    """

    x: np.ndarray
    cost: float
    jac: np.ndarray


class LastCall:
    """A function remembering its last argument and value: `scipy.optimize.leastsq` checks the residual and
    the Jacobian at ``x0`` before ``lmder`` asks for them again, and ``least_squares`` reads the Jacobian at
    the solution, which ``lmder`` has most often just computed (`lm`); a residual and its Jacobian share work
    at the same point (`workbench.extraction.multimode.pole_fit`'s basis).
    """

    def __init__(self, fun: Callable[[np.ndarray], np.ndarray]) -> None:
        self.fun = fun
        self.key = b""
        self.value = np.zeros(0)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        # the argument's bytes: 20 times quicker than np.array_equal, and a point is the same point only
        # when every bit is (-0.0 is not 0.0 here)
        key = np.asarray(x, dtype=float).tobytes()
        if key != self.key:
            self.value = np.atleast_1d(self.fun(x))
            self.key = key
        return self.value


def lm(fun: Callable[[np.ndarray], np.ndarray], x0, jac: Callable[[np.ndarray], np.ndarray], *,
       ftol: float = 1e-8, xtol: float = 1e-8, gtol: float = 1e-8) -> LMResult:
    """``scipy.optimize.least_squares(fun, x0, jac=jac, method="lm", ftol=ftol, xtol=xtol, gtol=gtol)``.

    Parameters
    ----------
    fun : residuals (m,) of the parameters (n,), ``m >= n``.
    x0 : (n,) start.
    jac : (m, n) Jacobian of ``fun``.
    ftol, xtol, gtol : MINPACK's tolerances, with ``least_squares``'s defaults.

    Returns
    -------
    LMResult with the solution, its cost and the Jacobian there.

    Raises
    ------
    ValueError
        The residuals are not finite at ``x0``, or fewer than the parameters (as ``least_squares``).
    """
    x0 = np.atleast_1d(np.asarray(x0, dtype=float))
    residual, jacobian = LastCall(fun), LastCall(jac)
    f0 = residual(x0)
    if not np.all(np.isfinite(f0)):
        raise ValueError("Residuals are not finite in the initial point.")
    if f0.size < x0.size:
        raise ValueError("Method 'lm' doesn't work when the number of residuals is less than the number of "
                         "variables.")
    x, _, info, _, _ = leastsq(residual, x0, Dfun=jacobian, full_output=True, ftol=ftol, xtol=xtol, gtol=gtol,
                               maxfev=100 * x0.size, factor=100.0, diag=None)
    f = info["fvec"]
    return LMResult(x=x, cost=0.5 * float(np.dot(f, f)), jac=jacobian(x))
