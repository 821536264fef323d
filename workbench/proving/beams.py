"""Planar frame numerics of the proving ground: Timoshenko beam and bar elements, assembly, modes, FRFs.

Written apart from `workbench.model` on purpose: the proving ground judges the workbench's methods,
so its data must not come from the same elements (an inverse crime hides every error the two would
share). Only numpy and scipy here.

**Beam element** (local axes: ``u`` along the element, ``w`` across, ``t`` the section's rotation; dofs
``u1, w1, t1, u2, w2, t2``). Axial: linear. Bending: the exact static solution of a Timoshenko beam
without distributed load, in ``xi = x / L``::

    w = b0 + b1 xi + b2 xi^2 + b3 xi^3
    t = (b1 + 2 b2 xi + (3 xi^2 + phi / 2) b3) / L       shear strain  w' - t = -(phi / 2) b3 / L
    phi = 12 EI / (kappa G A L^2)

The four ``b`` follow from the end values; stiffness ``int EI t'^2 + kappa G A (w' - t)^2 dx`` and the
consistent mass ``int mu w^2 + rho I t^2 dx`` (translational and rotary inertia) are integrated by 4-point
Gauss quadrature, exact for these polynomials of degree at most 6. The shear-flexible stiffness comes out
with its ``1 / (1 + phi)`` correction (``K_w1w1 = 12 EI / ((1 + phi) L^3)``, checked in the tests); phi = 0
is the Euler-Bernoulli (cubic Hermite) element. The geometric stiffness of an axial force ``N`` (tension
positive) is ``int N w'^2 dx`` on the same shape functions.

**Bar element**: a pin-ended axial member (a tie rod, a strut): ``EA / L`` along its axis, rigid-rod
consistent mass in both directions, geometric stiffness ``N / L`` across.

**Modes**: ``K phi = omega^2 M phi`` by dense ``scipy.linalg.eigh`` for small systems, else ``eigsh`` in
shift-invert mode with a fixed start vector (same bytes on every call). **FRFs**: modal superposition with
modal damping ratios, plus the residual flexibility of the modes left out (one static solve); with a
non-proportional viscous matrix ``C`` (dashpots), ``(Omega^2 - omega^2 + i omega (2 zeta Omega + Phi^T C Phi))
q = Phi^T f`` is solved directly at every frequency line (time convention exp(+i omega t)).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from threadpoolctl import threadpool_limits

__all__ = ["BeamSet", "BarSet", "System", "Modes", "shear_number", "beam_local", "beam_matrices",
           "beam_geometric", "beam_axial_forces", "beam_misfit_loads", "bar_matrices", "bar_axial_forces",
           "bar_misfit_loads", "assemble", "solve_modes", "frf", "damped_modes", "augmented_modes", "QUANTITIES"]

QUANTITIES = ("receptance", "mobility", "accelerance")
_XI, _WQ = np.polynomial.legendre.leggauss(4)
_XI, _WQ = (_XI + 1.0) / 2.0, _WQ / 2.0  # on [0, 1]
_DENSE_SIZE = 300  # below this many dofs a dense eigen-solve is faster than shift-invert Lanczos
_BENDING, _AXIAL = [1, 2, 4, 5], [0, 3]


@dataclass(frozen=True)
class BeamSet:
    """Beam elements: arrays of shape (e,), SI units.

    Attributes
    ----------
    dofs : (e, 6) global dof numbers of ``ux, uy, rz`` at the start node then the end node.
    length : m. cos, sin : direction of the element's axis in the frame's x-y plane.
    axial_rigidity : EA, N. bending_rigidity : EI, N.m2. shear_rigidity : kappa G A, N (inf: Euler-Bernoulli).
    mass_per_length : kg/m. rotary_per_length : rho I, kg.m (0: no rotary inertia).
    """

    dofs: np.ndarray
    length: np.ndarray
    cos: np.ndarray
    sin: np.ndarray
    axial_rigidity: np.ndarray
    bending_rigidity: np.ndarray
    shear_rigidity: np.ndarray
    mass_per_length: np.ndarray
    rotary_per_length: np.ndarray


@dataclass(frozen=True)
class BarSet:
    """Pin-ended bars: ``dofs`` (e, 4) global ``ux, uy`` of both ends; length (m), cos, sin, EA (N), kg/m."""

    dofs: np.ndarray
    length: np.ndarray
    cos: np.ndarray
    sin: np.ndarray
    axial_rigidity: np.ndarray
    mass_per_length: np.ndarray


@dataclass(frozen=True)
class System:
    """A discretised structure on its free dofs.

    Attributes
    ----------
    stiffness, mass : (n, n) sparse, N/m and kg (rotational dofs in N.m/rad and kg.m2).
    damping : (n, n) sparse viscous matrix of dashpots, N.s/m, or None (modal damping only).
    responses : (n_sensors,) free-dof numbers of the sensors. excitation : free-dof number of the force (-1: none).
    """

    stiffness: sp.csr_matrix
    mass: sp.csr_matrix
    damping: sp.csr_matrix | None
    responses: np.ndarray
    excitation: int

    @property
    def size(self) -> int:
        return int(self.stiffness.shape[0])


@dataclass(frozen=True)
class Modes:
    """Undamped modes: ``frequency_hz`` (m,) increasing, ``shapes`` (n, m) mass-normalised."""

    frequency_hz: np.ndarray
    shapes: np.ndarray

    @property
    def omega(self) -> np.ndarray:
        """(m,) rad/s."""
        return 2.0 * np.pi * self.frequency_hz


def shear_number(length: np.ndarray, bending_rigidity: np.ndarray, shear_rigidity: np.ndarray) -> np.ndarray:
    """``phi = 12 EI / (kappa G A L^2)`` per element (0 where the shear rigidity is infinite)."""
    return 12.0 * bending_rigidity / (shear_rigidity * length**2)


def _coefficients(length: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """(e, 4, 4) ``C`` with ``b = C d``: the shape coefficients from the end values ``d = (w1, t1, w2, t2)``."""
    e = length.size
    a = np.zeros((e, 4, 4))
    inv_l = 1.0 / length
    a[:, 0, 0] = 1.0  # w(0)
    a[:, 1, 1], a[:, 1, 3] = inv_l, 0.5 * phi * inv_l  # t(0)
    a[:, 2, :] = 1.0  # w(1)
    a[:, 3, 1], a[:, 3, 2], a[:, 3, 3] = inv_l, 2.0 * inv_l, (3.0 + 0.5 * phi) * inv_l  # t(1)
    return np.linalg.inv(a)


def beam_local(length: np.ndarray, axial_rigidity: np.ndarray, bending_rigidity: np.ndarray,
               shear_rigidity: np.ndarray, mass_per_length: np.ndarray,
               rotary_per_length: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness and consistent mass of beam elements in local axes (module docstring), each (e, 6, 6).

    Parameters
    ----------
    length : (e,) m. axial_rigidity : EA, N. bending_rigidity : EI, N.m2.
    shear_rigidity : kappa G A, N (``np.inf`` for Euler-Bernoulli). mass_per_length : kg/m.
    rotary_per_length : rho I, kg.m.

    Returns
    -------
    (K, M) : N/m (N/rad, N.m/rad where rotations enter) and kg (kg.m, kg.m2).
    """
    L = np.asarray(length, float)
    phi = shear_number(L, np.asarray(bending_rigidity, float), np.asarray(shear_rigidity, float))
    c = _coefficients(L, phi)
    xi, wq = _XI, _WQ
    zero, one = np.zeros_like(xi), np.ones_like(xi)
    w_rows = np.stack([one, xi, xi**2, xi**3], -1)  # (q, 4): w in b
    dt_rows = np.stack([zero, zero, 2 * one, 6 * xi], -1)  # (q, 4): L^2 dt/dx in b
    t_rows = np.stack([zero, one, 2 * xi, 3 * xi**2], -1)[None] + np.zeros((L.size, 1, 1))
    t_rows[:, :, 3] += 0.5 * phi[:, None]  # (e, q, 4): L t in b
    ei, mu, ri = (np.asarray(v, float)[:, None, None] for v in (bending_rigidity, mass_per_length, rotary_per_length))
    L3 = L[:, None, None]
    # bending energy: int EI t'^2 dx = EI / L^3 int (L^2 t')^2 dxi ; shear: kappa G A (phi/2)^2 / L = 3 EI phi / L^3
    kb = ei / L3**3 * np.einsum("q,qi,qj->ij", wq, dt_rows, dt_rows)[None]
    kb[:, 3, 3] += 3.0 * (ei[:, 0, 0] * phi) / L**3
    mb = mu * L3 * np.einsum("q,qi,qj->ij", wq, w_rows, w_rows)[None]
    mb = mb + ri / L3 * np.einsum("q,eqi,eqj->eij", wq, t_rows, t_rows)
    k, m = np.zeros((L.size, 6, 6)), np.zeros((L.size, 6, 6))
    k[np.ix_(range(L.size), _BENDING, _BENDING)] = np.einsum("eai,eab,ebj->eij", c, kb, c)
    m[np.ix_(range(L.size), _BENDING, _BENDING)] = np.einsum("eai,eab,ebj->eij", c, mb, c)
    ea, rho_a = np.asarray(axial_rigidity, float) / L, np.asarray(mass_per_length, float) * L / 6.0
    k[np.ix_(range(L.size), _AXIAL, _AXIAL)] = ea[:, None, None] * np.array([[1.0, -1.0], [-1.0, 1.0]])
    m[np.ix_(range(L.size), _AXIAL, _AXIAL)] = rho_a[:, None, None] * np.array([[2.0, 1.0], [1.0, 2.0]])
    return k, m


def _rotation(cos: np.ndarray, sin: np.ndarray, nodes: int = 2, rotations: bool = True) -> np.ndarray:
    """(e, n, n) ``T`` with ``local = T @ global`` (n = 6 for beams, 4 for bars)."""
    per = 3 if rotations else 2
    t = np.zeros((cos.size, per * nodes, per * nodes))
    for n in range(nodes):
        o = per * n
        t[:, o, o], t[:, o, o + 1], t[:, o + 1, o], t[:, o + 1, o + 1] = cos, sin, -sin, cos
        if rotations:
            t[:, o + 2, o + 2] = 1.0
    return t


def _to_global(local: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.einsum("eai,eab,ebj->eij", t, local, t)


def beam_matrices(beams: BeamSet) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness and mass of every beam in global axes, (e, 6, 6) each (`beam_local`, rotated)."""
    k, m = beam_local(beams.length, beams.axial_rigidity, beams.bending_rigidity, beams.shear_rigidity,
                      beams.mass_per_length, beams.rotary_per_length)
    t = _rotation(beams.cos, beams.sin)
    return _to_global(k, t), _to_global(m, t)


def beam_geometric(beams: BeamSet, axial_force: np.ndarray) -> np.ndarray:
    """Geometric stiffness ``int N w'^2 dx`` of axial forces ``N`` (e,) N, tension positive; global (e, 6, 6)."""
    L = beams.length
    phi = shear_number(L, beams.bending_rigidity, beams.shear_rigidity)
    c = _coefficients(L, phi)
    xi = _XI
    dw_rows = np.stack([np.zeros_like(xi), np.ones_like(xi), 2 * xi, 3 * xi**2], -1)  # L dw/dx in b
    kg_b = (np.asarray(axial_force, float) / L)[:, None, None] * np.einsum("q,qi,qj->ij", _WQ, dw_rows, dw_rows)
    kg = np.zeros((L.size, 6, 6))
    kg[np.ix_(range(L.size), _BENDING, _BENDING)] = np.einsum("eai,eab,ebj->eij", c, kg_b, c)
    return _to_global(kg, _rotation(beams.cos, beams.sin))


def _axial_stretch(dofs: np.ndarray, cos: np.ndarray, sin: np.ndarray, u: np.ndarray, per: int) -> np.ndarray:
    """Elongation of each element along its axis, m, from the global displacement vector ``u``."""
    ue = u[dofs]
    return (ue[:, per] - ue[:, 0]) * cos + (ue[:, per + 1] - ue[:, 1]) * sin


def beam_axial_forces(beams: BeamSet, u: np.ndarray, strain: np.ndarray | None = None) -> np.ndarray:
    """(e,) axial force, N (tension positive): ``EA (elongation / L - strain)``; ``strain`` the stress-free strain."""
    eps0 = np.zeros_like(beams.length) if strain is None else strain
    return beams.axial_rigidity * (_axial_stretch(beams.dofs, beams.cos, beams.sin, u, 3) / beams.length - eps0)


def beam_misfit_loads(beams: BeamSet, strain: np.ndarray) -> np.ndarray:
    """(e, 6) global nodal loads, N, of a stress-free strain (a member too long by ``strain * L``)."""
    f = beams.axial_rigidity * strain
    loads = np.zeros((beams.length.size, 6))
    loads[:, 0], loads[:, 1], loads[:, 3], loads[:, 4] = -f * beams.cos, -f * beams.sin, f * beams.cos, f * beams.sin
    return loads


def bar_matrices(bars: BarSet, axial_force: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stiffness, mass and geometric stiffness of pin-ended bars, global (e, 4, 4) each."""
    L = bars.length
    n = np.zeros_like(L) if axial_force is None else np.asarray(axial_force, float)
    k, m, kg = np.zeros((L.size, 4, 4)), np.zeros((L.size, 4, 4)), np.zeros((L.size, 4, 4))
    pair = np.array([[1.0, -1.0], [-1.0, 1.0]])
    k[np.ix_(range(L.size), [0, 2], [0, 2])] = (bars.axial_rigidity / L)[:, None, None] * pair
    kg[np.ix_(range(L.size), [1, 3], [1, 3])] = (n / L)[:, None, None] * pair
    # a pin-ended rod moves as a rigid rod across its axis too: the same consistent mass both ways
    rod = (bars.mass_per_length * L / 6.0)[:, None, None] * np.array([[2.0, 1.0], [1.0, 2.0]])
    m[np.ix_(range(L.size), [0, 2], [0, 2])] = rod
    m[np.ix_(range(L.size), [1, 3], [1, 3])] = rod
    t = _rotation(bars.cos, bars.sin, rotations=False)
    return _to_global(k, t), _to_global(m, t), _to_global(kg, t)


def bar_axial_forces(bars: BarSet, u: np.ndarray, strain: np.ndarray | None = None) -> np.ndarray:
    """(e,) axial force of each bar, N (tension positive); ``strain`` its stress-free strain."""
    eps0 = np.zeros_like(bars.length) if strain is None else strain
    return bars.axial_rigidity * (_axial_stretch(bars.dofs, bars.cos, bars.sin, u, 2) / bars.length - eps0)


def bar_misfit_loads(bars: BarSet, strain: np.ndarray) -> np.ndarray:
    """(e, 4) global nodal loads, N, of a stress-free strain of each bar."""
    f = bars.axial_rigidity * strain
    return np.stack([-f * bars.cos, -f * bars.sin, f * bars.cos, f * bars.sin], -1)


def assemble(blocks: np.ndarray, dofs: np.ndarray, size: int) -> sp.csr_matrix:
    """Sum element blocks (e, n, n) on the global dofs (e, n) into a (size, size) sparse matrix."""
    n = dofs.shape[1]
    rows = np.repeat(dofs, n, axis=1).ravel()
    cols = np.tile(dofs, (1, n)).ravel()
    out = sp.csr_matrix((blocks.ravel(), (rows, cols)), shape=(size, size))
    out.sum_duplicates()
    return out


def _mass_normalise(shapes: np.ndarray, mass: sp.csr_matrix) -> np.ndarray:
    """Mass-normalised shapes, each with its largest component positive (the same sign on every call)."""
    norms = np.sqrt(np.einsum("ij,ij->j", shapes, mass @ shapes))
    shapes = shapes / norms
    signs = np.sign(shapes[np.argmax(np.abs(shapes), axis=0), np.arange(shapes.shape[1])])
    return shapes * np.where(signs == 0, 1.0, signs)


def solve_modes(stiffness: sp.csr_matrix, mass: sp.csr_matrix, count: int = 10,
                max_hz: float | None = None) -> Modes:
    """The lowest modes of ``K phi = omega^2 M phi``: ``count`` of them, and more until one is above ``max_hz``.

    Parameters
    ----------
    stiffness, mass : (n, n) sparse symmetric; K positive semi-definite, M positive definite.
    count : the fewest modes returned.
    max_hz : Hz; when given, modes are added until the highest exceeds it (or every mode is found).

    Returns
    -------
    Modes
        Mass-normalised, frequencies increasing.
    """
    # one BLAS thread: the matrices are small, and threads only add contention (10x slower on a busy
    # two-core machine) and round-off that depends on the thread count (the same seed must give the same bytes)
    with threadpool_limits(1):
        return _solve_modes(stiffness, mass, count, max_hz)


def _solve_modes(stiffness: sp.csr_matrix, mass: sp.csr_matrix, count: int, max_hz: float | None) -> Modes:
    n = stiffness.shape[0]
    k = min(count, n - 1)
    while True:
        if n <= _DENSE_SIZE:
            values, vectors = la.eigh(stiffness.toarray(), mass.toarray(), subset_by_index=[0, k - 1])
        else:
            # shift below zero: K - sigma M stays positive definite, also with rigid-body modes
            v0 = np.random.default_rng(20200).standard_normal(n)  # fixed: the same bytes on every call
            values, vectors = spla.eigsh(stiffness.tocsc(), k=k, M=mass.tocsc(), sigma=-1.0e2, which="LM", v0=v0)
            order = np.argsort(values)
            values, vectors = values[order], vectors[:, order]
        freq = np.sqrt(np.clip(values, 0.0, None)) / (2.0 * np.pi)
        if max_hz is None or freq[-1] > max_hz or k >= n - 1:
            return Modes(freq, _mass_normalise(vectors, mass))
        k = min(2 * k, n - 1)


def _static_residual(system: System, modes: Modes) -> np.ndarray:
    """(n_sensors,) residual receptance of the modes left out, m/N: ``K^-1 f - sum phi phi^T f / omega^2``."""
    load = np.zeros(system.size)
    load[system.excitation] = 1.0
    static = spla.spsolve(system.stiffness.tocsc(), load)[system.responses]
    omega2 = np.maximum(modes.omega**2, 1e-300)
    return static - modes.shapes[system.responses] @ (modes.shapes[system.excitation] / omega2)


def augmented_modes(system: System, modes: Modes) -> Modes:
    """``modes`` plus Ritz vectors of the static shapes ``K^-1 f`` (the force) and ``K^-1 C`` (the dashpots).

    A dashpot across a 2 cm joint zone deforms it locally: projected on the modes alone the FRF converges
    slowly (0.3 % off at 550 Hz with 160 modes on the bundled two-bolt frame); with the static shapes in the
    basis (modal truncation augmentation) it is exact at 0 Hz and close below the modes left out. The added
    vectors, M-orthogonal to ``modes``, are K-orthogonal to them too (``modes`` are exact eigenvectors), so the
    original modes come back unchanged and the new ones are pseudo-modes above them.
    """
    columns = [np.eye(1, system.size, system.excitation).ravel()]
    if system.damping is not None:
        damping = system.damping.tocsc()
        columns += [damping[:, j].toarray().ravel() for j in np.unique(damping.nonzero()[1])]
    static = spla.splu(system.stiffness.tocsc()).solve(np.column_stack(columns))
    static = static - modes.shapes @ (modes.shapes.T @ (system.mass @ static))
    # drop what the modes already span (or the static shapes repeat): an orthonormal basis of the rest
    q, r = np.linalg.qr(static)
    keep = np.abs(np.diag(r)) > 1e-10 * np.abs(np.diag(r)).max()
    extra = q[:, keep]
    values, vectors = la.eigh(extra.T @ (system.stiffness @ extra), extra.T @ (system.mass @ extra))
    shapes = _mass_normalise(extra @ vectors, system.mass)
    return Modes(np.concatenate([modes.frequency_hz, np.sqrt(np.clip(values, 0, None)) / (2 * np.pi)]),
                 np.column_stack([modes.shapes, shapes]))


def _ratios(damping_ratio: np.ndarray | Callable[[np.ndarray], np.ndarray], frequency_hz: np.ndarray) -> np.ndarray:
    """Damping ratios of modes at ``frequency_hz``: a law, or given values with the last one repeated."""
    if callable(damping_ratio):
        return np.asarray(damping_ratio(frequency_hz), float)
    zeta = np.asarray(damping_ratio, float)
    return np.concatenate([zeta, np.full(frequency_hz.size - zeta.size, zeta[-1])])[:frequency_hz.size]


def _to_quantity(receptance: np.ndarray, omega: np.ndarray, quantity: str) -> np.ndarray:
    if quantity == "mobility":
        return receptance * (1j * omega)
    if quantity == "accelerance":
        return receptance * (-(omega**2))
    return receptance


def frf(system: System, modes: Modes, frequency_hz: np.ndarray,
        damping_ratio: np.ndarray | Callable[[np.ndarray], np.ndarray], quantity: str = "accelerance",
        residual: bool = True, chunk: int = 512) -> np.ndarray:
    """FRFs at the sensors for a unit force at the excitation (module docstring).

    Parameters
    ----------
    modes : the modes summed (or the basis of the direct solve when ``system.damping`` is set).
    frequency_hz : (n_freq,) Hz.
    damping_ratio : (m,) modal viscous damping ratios of ``modes`` (the last repeats on pseudo-modes), or a
        law ``zeta(f_hz)``.
    quantity : receptance (m/N), mobility (m/s/N) or accelerance (m/s2/N).
    residual : add the static response of what the modes leave out (residual flexibility; with dashpots, the
        static shapes in the basis: `augmented_modes`).

    Returns
    -------
    (n_sensors, n_freq) complex.
    """
    if quantity not in QUANTITIES:
        raise ValueError(f"quantity: {quantity!r} is not one of {', '.join(QUANTITIES)}")
    with threadpool_limits(1):  # as in `solve_modes`
        return _frf(system, modes, frequency_hz, damping_ratio, quantity, residual, chunk)


def _frf(system: System, modes: Modes, frequency_hz: np.ndarray,
         damping_ratio: np.ndarray | Callable[[np.ndarray], np.ndarray], quantity: str, residual: bool,
         chunk: int) -> np.ndarray:
    omega = 2.0 * np.pi * np.asarray(frequency_hz, float)
    if system.damping is None:
        wr, zeta = modes.omega, _ratios(damping_ratio, modes.frequency_hz)
        phi_s, phi_e = modes.shapes[system.responses], modes.shapes[system.excitation]
        denominator = wr[:, None] ** 2 - omega[None, :] ** 2 + 2j * (zeta * wr)[:, None] * omega[None, :]
        h = (phi_s * phi_e) @ (1.0 / denominator)
        if residual:
            h = h + _static_residual(system, modes)[:, None]
        return _to_quantity(h, omega, quantity)
    # dashpots couple the modes: one small complex solve per line on the (augmented) modal basis
    basis = augmented_modes(system, modes) if residual else modes
    wr, zeta = basis.omega, _ratios(damping_ratio, basis.frequency_hz)
    phi_s, phi_e = basis.shapes[system.responses], basis.shapes[system.excitation]
    modal = np.diag(2.0 * zeta * wr) + basis.shapes.T @ (system.damping @ basis.shapes)
    h = np.empty((phi_s.shape[0], omega.size), complex)
    eye = np.eye(wr.size)
    for start in range(0, omega.size, chunk):
        w = omega[start:start + chunk]
        z = np.diag(wr**2)[None] - (w**2)[:, None, None] * eye[None] + 1j * w[:, None, None] * modal[None]
        q = np.linalg.solve(z, np.broadcast_to(phi_e[None, :, None], (w.size, wr.size, 1)))[..., 0]
        h[:, start:start + chunk] = phi_s @ q.T
    return _to_quantity(h, omega, quantity)


def damped_modes(system: System, modes: Modes,
                 damping_ratio: np.ndarray | Callable[[np.ndarray], np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Natural frequencies (Hz) and damping ratios of the damped system on the (augmented) modal basis, increasing.

    The first-order form of ``q'' + (2 zeta Omega + Phi^T C Phi) q' + Omega^2 q = 0``: with dashpots the modes
    are complex and each ratio is ``-Re(lambda) / |lambda|``; without, the modal ratios come back unchanged.
    """
    if system.damping is not None:
        modes = augmented_modes(system, modes)
    wr, zeta = modes.omega, _ratios(damping_ratio, modes.frequency_hz)
    modal = np.diag(2.0 * zeta * wr)
    if system.damping is not None:
        modal = modal + modes.shapes.T @ (system.damping @ modes.shapes)
    m = wr.size
    state = np.block([[np.zeros((m, m)), np.eye(m)], [-np.diag(wr**2), -modal]])
    lam = la.eigvals(state)
    lam = lam[lam.imag > 0]
    order = np.argsort(np.abs(lam))
    lam = lam[order]
    return np.abs(lam) / (2.0 * np.pi), -lam.real / np.abs(lam)
