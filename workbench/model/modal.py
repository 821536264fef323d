"""Modal analysis: eigen-solutions of ``K phi = lambda M phi``, MAC, and FRF synthesis.

Eigenvectors are mass-normalised (``Phi^T M Phi = I``) and signed so that their largest component
is positive, which keeps mode tracking and eigenvector derivatives deterministic. FRFs follow the
contract's exp(+i omega t) convention: a receptance is ``1 / (k - omega^2 m + i omega c)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from threadpoolctl import threadpool_limits

from workbench.model.assembly import Model, strain_energy

__all__ = [
    "RIGID_HZ",
    "DENSE_LIMIT",
    "QUANTITIES",
    "Modes",
    "FRFSet",
    "solve_modes",
    "ldl_pivots",
    "count_below",
    "model_modes",
    "mac",
    "dominant_real",
    "DEGENERATE_GAP",
    "shared_eigenvalues",
    "modal_superposition",
    "modal_magnitude",
    "modal_frf",
    "add_noise",
]

RIGID_HZ = 0.5  # modes below this are rigid-body modes of a free structure: never measured, never compared

# dofs; above it sparse shift-invert Lanczos is faster for the first tens of modes (measured: 7 ms
# against 14 ms at 318 dofs, 6 ms against 28 ms at 489, single-threaded BLAS).
DENSE_LIMIT = 200
DENSE_THREAD_LIMIT = 4000  # dofs; above it dense LAPACK runs single-threaded (see solve_modes)
# Shift of the shift-invert solver, (rad/s)^2: below zero so that K - sigma M is definite for
# free-free structures, and small (0.1 Hz) because Lanczos converges fastest, and most accurately,
# when the shift sits just under the wanted eigenvalues.
SHIFT = -((2.0 * np.pi * 0.1) ** 2)
QUANTITIES = ("receptance", "mobility", "accelerance")


@dataclass(frozen=True)
class Modes:
    """The first modes of a structure.

    Attributes
    ----------
    eigenvalues : (n,) ``omega^2`` in (rad/s)^2, increasing.
    shapes : (n_dof, n) mass-normalised eigenvectors on the model's free dofs.
    """

    eigenvalues: np.ndarray
    shapes: np.ndarray

    def __post_init__(self) -> None:
        if self.shapes.ndim != 2 or self.shapes.shape[1] != self.eigenvalues.shape[0]:
            raise ValueError(f"Modes: shapes {self.shapes.shape} do not match "
                             f"{self.eigenvalues.shape[0]} eigenvalues")

    @property
    def count(self) -> int:
        return int(self.eigenvalues.size)

    @property
    def omega(self) -> np.ndarray:
        """Natural circular frequencies, rad/s (rigid-body modes give 0)."""
        return np.sqrt(np.clip(self.eigenvalues, 0.0, None))

    @property
    def frequency_hz(self) -> np.ndarray:
        return self.omega / (2.0 * np.pi)


@dataclass(frozen=True)
class FRFSet:
    """FRFs of several responses to one excitation.

    Attributes
    ----------
    frequency_hz : (n_freq,) frequency lines, Hz.
    values : (n_response, n_freq) complex FRF, in the unit of ``quantity``
        (receptance m/N, mobility m/s/N, accelerance m/s^2/N).
    responses : names of the responses (sensor names).
    quantity : one of `QUANTITIES`.
    """

    frequency_hz: np.ndarray
    values: np.ndarray
    responses: tuple[str, ...]
    quantity: str

    def __post_init__(self) -> None:
        if self.quantity not in QUANTITIES:
            raise ValueError(f"FRFSet: quantity {self.quantity!r} is not one of {QUANTITIES}")
        if self.values.shape != (len(self.responses), self.frequency_hz.size):
            raise ValueError(f"FRFSet: values {self.values.shape} do not match "
                             f"{len(self.responses)} responses x {self.frequency_hz.size} lines")


def _normalise(vectors: np.ndarray, mass: sp.spmatrix | np.ndarray) -> np.ndarray:
    norms = np.sqrt(np.einsum("ik,ik->k", vectors, mass @ vectors))
    vectors = vectors / norms
    peak = vectors[np.abs(vectors).argmax(axis=0), np.arange(vectors.shape[1])]
    return vectors * np.sign(peak)


def ldl_pivots(a: sp.spmatrix) -> tuple[np.ndarray, np.ndarray] | None:
    """Pivots of ``P^T A P = L D L^T`` and the row each belongs to, or None when no such factorisation exists.

    SuperLU with diagonal pivoting preferred (threshold 0) and a symmetric ordering factors a symmetric
    matrix as ``L (D L^T)``: the diagonal of U holds D, whose signs are the matrix's inertia (Sylvester).
    When it had to take an off-diagonal pivot (a zero on the diagonal), or the matrix is exactly singular,
    the matrix is not definite. Its cost is that of the sparse factorisation the modal solve does anyway.
    """
    try:
        lu = spla.splu(sp.csc_matrix(a), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True, "Equil": False})
    except RuntimeError:  # SuperLU: "Factor is exactly singular"
        return None
    if not np.array_equal(lu.perm_r, lu.perm_c):
        return None
    return lu.U.diagonal(), np.argsort(lu.perm_c)


def count_below(stiffness: sp.spmatrix, mass: sp.spmatrix, value: float) -> int | None:
    """How many eigenvalues of ``K phi = lambda M phi`` lie below ``value``: a Sturm sequence check.

    By Sylvester's law of inertia, the negative pivots of ``K - value M = L D L^T`` count them. None
    when the factorisation needed an off-diagonal pivot (or ``value`` is an eigenvalue): no count then.
    """
    factors = ldl_pivots(sp.csc_matrix(stiffness - value * mass))
    return None if factors is None else int(np.sum(factors[0] < 0))


def solve_modes(stiffness: sp.spmatrix | np.ndarray, mass: sp.spmatrix | np.ndarray, count: int,
                method: str = "auto") -> Modes:
    """First ``count`` modes of ``K phi = lambda M phi``, mass-normalised.

    Parameters
    ----------
    stiffness, mass : (n, n) symmetric matrices, K positive semi-definite, M positive definite.
    count : number of modes, the lowest first.
    method : ``"dense"`` (LAPACK, all of K and M in memory, then one Rayleigh-Ritz refinement),
        ``"sparse"`` (ARPACK shift-invert Lanczos about a small negative shift, so free-free
        structures work too) or ``"auto"``: dense up to `DENSE_LIMIT` dofs.

    Returns
    -------
    Modes

    Raises
    ------
    ValueError
        A bad count or method, or a singular model (a mechanism, or a mass matrix that is not
        positive definite).
    """
    n = stiffness.shape[0]
    if not 1 <= count <= n:
        raise ValueError(f"count: asked for {count} modes of a model with {n} dofs")
    if method == "auto":
        method = "dense" if n <= DENSE_LIMIT or count >= n - 1 else "sparse"
    sigma = SHIFT
    if method == "dense":
        k = cast(sp.spmatrix, stiffness).toarray() if sp.issparse(stiffness) else np.asarray(stiffness)
        m = cast(sp.spmatrix, mass).toarray() if sp.issparse(mass) else np.asarray(mass)
        guard = min(n, max(2 * count, count + 8))
        # OpenBLAS 0.3.31's threaded sygvx segfaulted at 20 000 dofs here; single-threaded it
        # completes (19 min), so large dense solves run on one thread.
        try:
            with threadpool_limits(limits=1 if n > DENSE_THREAD_LIMIT else None):
                values, vectors = sla.eigh(k, m, subset_by_index=[0, guard - 1])
                # LAPACK's error is absolute (about eps * ||K||): 1e-7 relative on the low modes
                # of a 400-dof frame with stiff axial dofs, 5e-5 at 20 000 dofs. Two steps of
                # inverse subspace iteration on guard vectors, each followed by Rayleigh-Ritz,
                # shrink the vector errors by (lambda_k / lambda_guard)^2.
                factor = sla.cho_factor(k - sigma * m, check_finite=False)
                for _ in range(2):
                    vectors = sla.cho_solve(factor, m @ vectors)
                    values, ritz = sla.eigh(vectors.T @ k @ vectors, vectors.T @ m @ vectors)
                    vectors = vectors @ ritz
                del factor
            values, vectors = values[:count], vectors[:, :count]
        except np.linalg.LinAlgError as exc:
            raise ValueError(f"singular model: the mass matrix is not positive definite ({exc})") from None
    elif method == "sparse":
        if count >= n - 1:
            raise ValueError(f"count: the sparse solver finds at most {n - 2} modes of {n} dofs")
        k, m = sp.csc_matrix(stiffness), sp.csc_matrix(mass)
        try:
            # A fixed, generic start vector: ARPACK's default one depends on the history of
            # earlier calls, and results must not depend on what ran before.
            start = np.random.default_rng(12345).standard_normal(n)
            values, vectors = spla.eigsh(k, k=count, M=m, sigma=sigma, which="LM", tol=0.0, v0=start)
        except (RuntimeError, spla.ArpackError) as exc:
            raise ValueError(f"singular model: the shift-invert factorisation failed ({exc})") from None
        order = np.argsort(values)
        values, vectors = values[order], vectors[:, order]
    else:
        raise ValueError(f"method: {method!r} is not one of auto, dense, sparse")
    if np.any(values < -_roundoff(stiffness, mass, values[-1])):
        raise ValueError("singular model: negative eigenvalues (an axial force above buckling, "
                         "or a stiffness that is not positive)")
    return Modes(values, _normalise(vectors, mass))


def _roundoff(stiffness: np.ndarray | sp.spmatrix, mass: np.ndarray | sp.spmatrix, highest: float) -> float:
    """How far below zero a rigid-body eigenvalue may come out by rounding alone.

    A solver's absolute eigenvalue error is about eps times the largest eigenvalue of the whole
    pencil, estimated by ``max(K_ii / M_ii)``, not of the few modes asked for: a free-free beam whose
    joint is stiffened to 1e12 Pa gives rigid modes at -1e-2 (rad/s)^2, far below 1e-8 of its
    first bending mode's eigenvalue, yet no instability.
    """
    k = np.asarray(stiffness.diagonal() if sp.issparse(stiffness) else np.diagonal(stiffness), float)
    m = np.asarray(mass.diagonal() if sp.issparse(mass) else np.diagonal(mass), float)
    ratio = np.divide(k, m, out=np.zeros_like(k), where=m > 0)
    return max(1e-8 * max(abs(highest), 1.0), 1e3 * np.finfo(float).eps * float(ratio.max(initial=0.0)))


def model_modes(model: Model, count: int = 10, gamma: np.ndarray | None = None, method: str = "auto") -> Modes:
    """First ``count`` modes of an assembled `Model` with joint moduli ``gamma`` (default: nominal).

    The eigenvalues are the Rayleigh quotients of the eigenvectors with the strain energy summed
    element by element (`workbench.model.assembly.strain_energy`): stationary, so accurate to the
    square of the eigenvector error, and free of the cancellation that limits ``phi^T K phi`` on
    the assembled matrix to about 1e-7. Dense and sparse solutions then agree to about 1e-11.
    """
    modes = solve_modes(model.stiffness(gamma), model.mass, count, method)
    values = strain_energy(model, modes.shapes, gamma)
    order = np.argsort(values, kind="stable")
    return Modes(values[order], modes.shapes[:, order])


# Relative eigenvalue gap under which two modes are one repeated eigenvalue. Symmetry-degenerate
# pairs come out of the eigensolver 1e-12 apart; the closest distinct pairs of the bundled frames
# sit 1e-2 apart, and at 1e-6 Nelson's derivatives (which scale as 1 / gap) are already meaningless.
DEGENERATE_GAP = 1e-6


def shared_eigenvalues(modes: Modes, count: int) -> list[np.ndarray]:
    """Groups of two or more modes, among those touching the first ``count``, that share one eigenvalue.

    Returns
    -------
    list of increasing 0-based mode indices; a group may run past ``count`` into the extra modes.
    """
    lam = modes.eigenvalues
    scale = max(float(np.max(np.abs(lam))), np.finfo(float).tiny)
    groups: list[np.ndarray] = []
    k = 0
    while k < min(count, lam.size):
        end = k + 1
        while end < lam.size and lam[end] - lam[end - 1] <= DEGENERATE_GAP * max(abs(lam[end]), 1e-12 * scale):
            end += 1
        if end - k > 1:
            groups.append(np.arange(k, end))
        k = end
    return groups


def mac(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Modal assurance criterion between the columns of ``a`` (n, p) and ``b`` (n, q), shape (p, q).

    ``MAC_ij = |a_i^H b_j|^2 / ((a_i^H a_i)(b_j^H b_j))``: 1 for collinear shapes, 0 for orthogonal.
    """
    a, b = np.atleast_2d(a.T).T, np.atleast_2d(b.T).T
    cross = np.abs(a.conj().T @ b) ** 2
    return cross / np.outer(np.einsum("ij,ij->j", a.conj(), a).real, np.einsum("ij,ij->j", b.conj(), b).real)


def dominant_real(vectors: np.ndarray) -> np.ndarray:
    """Real parts of complex vectors turned to their dominant phase.

    Parameters
    ----------
    vectors : (..., n) complex.

    Returns
    -------
    (..., n) real: ``Re(v exp(-i theta))`` with ``theta = arg(sum v^2) / 2``, the angle that puts
    the most of the vector's energy on the real axis; a real vector is returned as it is (up to sign).
    NaN entries stay NaN and are left out of the sum.
    """
    v = np.asarray(vectors, complex)
    theta = 0.5 * np.angle(np.nansum(v * v, axis=-1, keepdims=True))
    return np.real(v * np.exp(-1j * theta))


def _receptance_parts(frequency_hz, natural_hz, damping_ratios, constants, dtype) -> tuple[np.ndarray, np.ndarray]:
    """Real and imaginary parts of ``sum_r A_r / (omega_r^2 - omega^2 + 2 i zeta_r omega_r omega)``.

    In real arithmetic, ``A (a - i b) / (a^2 + b^2)`` with ``a = omega_r^2 - omega^2`` and ``b = 2 zeta_r
    omega_r omega``: a complex division costs four times as much, and the batched magnitudes of a
    10 000-draw FRF band are float32 (`modal_magnitude`).
    """
    omega = (2.0 * np.pi * np.asarray(frequency_hz, float)).astype(dtype)
    wr = 2.0 * np.pi * np.asarray(natural_hz, float)
    zeta = np.asarray(damping_ratios, float)
    if zeta.shape not in (wr.shape, wr.shape[-1:]):
        raise ValueError(f"damping_ratios: expected {wr.shape[-1]} values, got shape {zeta.shape}")
    a = (wr**2).astype(dtype)[..., :, None] - omega**2
    b = (2.0 * zeta * wr).astype(dtype)[..., :, None] * omega
    d = a * a + b * b
    c = np.atleast_2d(np.asarray(constants)).astype(dtype)
    return c @ (a / d), -(c @ (b / d))


def modal_superposition(frequency_hz: np.ndarray, natural_hz: np.ndarray, damping_ratios: np.ndarray,
                        constants: np.ndarray, quantity: str = "receptance") -> np.ndarray:
    """FRFs from modal parameters: ``sum_r A_r / (omega_r^2 - omega^2 + 2 i zeta_r omega_r omega)``.

    Parameters
    ----------
    frequency_hz : (n_freq,) Hz.
    natural_hz : (n_modes,) natural frequencies, Hz, or (n_samples, n_modes) for a batch of samples.
    damping_ratios : (n_modes,) modal damping ratios (the same for every sample of a batch), or the
        shape of ``natural_hz``.
    constants : (n_curves, n_modes) real receptance modal constants ``A_r = phi_jr phi_kr`` (1/kg for
        mass-normalised shapes), or (n_samples, n_curves, n_modes) for a batch; complex constants
        (fitted ones) are taken as they are.
    quantity : receptance (m/N), or times ``i omega`` for mobility, ``-omega^2`` for accelerance.

    Returns
    -------
    (n_curves, n_freq) complex array, or (n_samples, n_curves, n_freq) for a batch.
    """
    if quantity not in QUANTITIES:
        raise ValueError(f"quantity: {quantity!r} is not one of {', '.join(QUANTITIES)}")
    if np.iscomplexobj(constants):  # a complex A: both parts through the real form
        re_re, re_im = _receptance_parts(frequency_hz, natural_hz, damping_ratios, np.real(constants), float)
        im_re, im_im = _receptance_parts(frequency_hz, natural_hz, damping_ratios, np.imag(constants), float)
        h = (re_re - im_im) + 1j * (re_im + im_re)
    else:
        real, imag = _receptance_parts(frequency_hz, natural_hz, damping_ratios, constants, float)
        h = real + 1j * imag
    omega = 2.0 * np.pi * np.asarray(frequency_hz, float)
    if quantity == "mobility":
        return h * (1j * omega)
    if quantity == "accelerance":
        return h * (-(omega**2))
    return h


def modal_magnitude(frequency_hz: np.ndarray, natural_hz: np.ndarray, damping_ratios: np.ndarray,
                    constants: np.ndarray, quantity: str = "receptance") -> np.ndarray:
    """``|H|`` of `modal_superposition` for a batch of real modal constants, in float32.

    The shapes are `modal_superposition`'s; float32 keeps 7 significant digits, far below the
    sampling error of a band of draws, at half the memory traffic.
    """
    if quantity not in QUANTITIES:
        raise ValueError(f"quantity: {quantity!r} is not one of {', '.join(QUANTITIES)}")
    real, imag = _receptance_parts(frequency_hz, natural_hz, damping_ratios, constants, np.float32)
    magnitude = np.hypot(real, imag, out=real)
    omega = (2.0 * np.pi * np.asarray(frequency_hz, float)).astype(np.float32)
    if quantity == "mobility":
        magnitude *= omega
    elif quantity == "accelerance":
        magnitude *= omega * omega
    return magnitude


def modal_frf(modes: Modes, frequency_hz: np.ndarray, response_dofs: np.ndarray, excitation_dof: int,
              damping_ratios: np.ndarray, quantity: str = "receptance") -> np.ndarray:
    """FRFs by modal superposition with modal damping (`modal_superposition` of the modes' shapes).

    Parameters
    ----------
    modes : mass-normalised modes; only these are summed (no residual terms).
    frequency_hz : (n_freq,) frequency lines, Hz.
    response_dofs : (n_resp,) indices of the response dofs in the model's free-dof system.
    excitation_dof : index of the excited dof.
    damping_ratios : (modes.count,) modal damping ratios.
    quantity : receptance, mobility or accelerance.

    Returns
    -------
    (n_resp, n_freq) complex array.
    """
    zeta = np.asarray(damping_ratios, float)
    if zeta.shape != (modes.count,):
        raise ValueError(f"damping_ratios: expected {modes.count} values, got shape {zeta.shape}")
    constants = modes.shapes[np.asarray(response_dofs)] * modes.shapes[excitation_dof]  # (n_resp, n_modes)
    return modal_superposition(frequency_hz, modes.frequency_hz, zeta, constants, quantity)


def add_noise(values: np.ndarray, snr_db: float | None, rng: np.random.Generator) -> np.ndarray:
    """Measurement noise: circular complex Gaussian, per curve (last axis = frequency).

    ``SNR_dB = 20 log10(RMS_f |H| / sigma)`` with ``sigma^2 = E|noise|^2``, split evenly between the
    real and imaginary parts. ``snr_db = None`` returns a noise-free copy.
    """
    values = np.asarray(values, complex)
    if snr_db is None:
        return values.copy()
    sigma = np.sqrt(np.mean(np.abs(values) ** 2, axis=-1, keepdims=True)) * 10.0 ** (-snr_db / 20.0)
    noise = rng.standard_normal(values.shape) + 1j * rng.standard_normal(values.shape)
    return values + sigma * noise / np.sqrt(2.0)
