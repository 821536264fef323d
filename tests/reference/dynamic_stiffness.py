"""Exact natural frequencies of planar Euler-Bernoulli frames.

Independent reference solver used only by the tests.  It implements the
dynamic stiffness method (exact member stiffness for axial + Euler-Bernoulli
bending, no shear deformation, no rotary inertia of the cross-section) and
the Wittrick-Williams algorithm

    J(omega) = J0(omega) + s{K(omega)},

where ``J`` is the number of natural frequencies strictly below ``omega``,
``J0`` the sum of clamped-clamped member frequencies below ``omega`` and
``s{K}`` the number of negative eigenvalues of the assembled dynamic
stiffness matrix of the free dofs.  Frequencies are located by bisection on
``J``, so multiplicities are returned exactly and no mode can be missed.

The hyperbolic functions are written in a form scaled by ``1/cosh(nu)``
(``tanh`` and ``sech`` only), hence there is no overflow for any ``nu``; for
``nu < 1`` exact Taylor series avoid the cancellation in ``1 - cos cosh``.
Only numpy and scipy are used; nothing is imported from ``workbench``.

Limitations: ``J(0) = 0`` is assumed (stable frame, non-negative springs and
masses); a mechanism yields frequencies of ~0 Hz (within ``tol_hz``).  The
count uses a dense ``eigvalsh`` per bisection step, i.e. about
``count * 45`` evaluations of cost O(n_dof^3).
"""

from fractions import Fraction
from math import factorial

import numpy as np

__all__ = ["natural_frequencies_hz", "member_dynamic_stiffness",
           "wittrick_williams_count", "portal_frame_reference"]


def _bending_series(n_terms=12):
    """Exact Taylor series of the bending stiffness functions.

    Returns polynomials in ``x = nu**4`` (highest power first) of
    (sC+cS)/nu, sS/nu^2, (s+S)/nu, (C-c)/nu^2, (sC-cS)/nu^3, (S-s)/nu^3 and
    (1-cC)/nu^4, where s, c, S, C are sin, cos, sinh, cosh of nu.
    """
    deg = 4 * n_terms + 8
    z = [Fraction(0)] * deg
    s, c, S, C = list(z), list(z), list(z), list(z)
    for k in range(deg):
        f = Fraction(1, factorial(k))
        if k % 2:
            S[k], s[k] = f, f * (-1) ** (k // 2)
        else:
            C[k], c[k] = f, f * (-1) ** (k // 2)

    def mul(a, b):
        return [sum(a[i] * b[k - i] for i in range(k + 1)) for k in range(deg)]

    def add(a, b, sign=1):
        return [p + sign * q for p, q in zip(a, b)]

    one = [Fraction(1)] + z[1:]
    funcs = [(add(mul(s, C), mul(c, S)), 1), (mul(s, S), 2), (add(s, S), 1),
             (add(C, c, -1), 2), (add(mul(s, C), mul(c, S), -1), 3),
             (add(S, s, -1), 3), (add(one, mul(c, C), -1), 4)]
    out = []
    for coef, shift in funcs:
        sh = coef[shift:]
        # only powers nu^(4m) survive after the shift
        assert all(v == 0 for k, v in enumerate(sh) if k % 4)
        out.append(np.array([float(sh[4 * m]) for m in range(n_terms)])[::-1])
    return out


_SERIES = _bending_series()


def _axial_bending_parts(omega, L, E, A, I, rho):
    """Return (k_a L, nu) of a member at circular frequency ``omega``."""
    ka_l = omega * L * np.sqrt(rho / E)
    nu = L * (rho * A * omega ** 2 / (E * I)) ** 0.25
    return ka_l, nu


def member_dynamic_stiffness(omega, L, E, A, I, rho):
    """Exact local dynamic stiffness of a uniform planar frame member.

    Parameters
    ----------
    omega : float
        Circular frequency (rad/s), ``omega >= 0``.
    L, E, A, I, rho : float
        Length (m), Young's modulus (Pa), area (m2), second moment of
        area (m4) and density (kg/m3).

    Returns
    -------
    numpy.ndarray
        (6, 6) matrix for local dofs (u1, v1, theta1, u2, v2, theta2);
        it reduces to the static stiffness matrix at ``omega = 0``.
    """
    ka_l, nu = _axial_bending_parts(omega, L, E, A, I, rho)
    k = np.zeros((6, 6))
    # axial bar: EA k / sin(kL) [[cos, -1], [-1, cos]]
    if ka_l < 1e-4:  # series, relative error < 1e-16
        d, o = 1.0 - ka_l ** 2 / 3.0, -(1.0 + ka_l ** 2 / 6.0)
    else:
        d, o = ka_l * np.cos(ka_l) / np.sin(ka_l), -ka_l / np.sin(ka_l)
    k[np.ix_([0, 3], [0, 3])] = E * A / L * np.array([[d, o], [o, d]])
    # bending: Howson-Williams closed form.  Small nu: exact Taylor series
    # (no cancellation in 1 - cos cosh); otherwise numerator and denominator
    # are divided by cosh(nu) so that only tanh and sech appear.
    if nu < 1.0:
        x = nu ** 4
        f = np.array([np.polyval(p, x) for p in _SERIES[:6]]) / np.polyval(
            _SERIES[6], x)
    else:
        s, c = np.sin(nu), np.cos(nu)
        t, h = np.tanh(nu), 2.0 * np.exp(-nu) / (1.0 + np.exp(-2.0 * nu))
        delta = h - c  # (1 - cos cosh) / cosh
        f = np.array([nu ** 3 * (s + c * t), nu ** 2 * s * t,
                      nu ** 3 * (s * h + t), nu ** 2 * (1.0 - c * h),
                      nu * (s - c * t), nu * (t - s * h)]) / delta
    f1, f2, f3, f4, f5, f6 = f
    kb = E * I / L ** 3 * np.array([
        [f1, f2 * L, -f3, f4 * L],
        [f2 * L, f5 * L ** 2, -f4 * L, f6 * L ** 2],
        [-f3, -f4 * L, f1, -f2 * L],
        [f4 * L, f6 * L ** 2, -f2 * L, f5 * L ** 2]])
    k[np.ix_([1, 2, 4, 5], [1, 2, 4, 5])] = kb
    return k


def _clamped_member_count(omega, L, E, A, I, rho):
    """Number of clamped-clamped member frequencies below ``omega`` (J0)."""
    ka_l, nu = _axial_bending_parts(omega, L, E, A, I, rho)
    j_axial = int(np.floor(ka_l / np.pi))
    i = int(np.floor(nu / np.pi))
    h = 2.0 * np.exp(-nu) / (1.0 + np.exp(-2.0 * nu))
    # sign(1 - cosh(nu) cos(nu)); it is +1 for nu < 4.73 (no cancellation)
    sgn = 1.0 if nu < 1.0 else np.sign(h - np.cos(nu))
    j_bending = i - (1 - (-1) ** i * sgn) / 2
    return j_axial + int(j_bending)


def _rotation(cos_a, sin_a):
    """6x6 transformation from global to local member dofs."""
    r = np.array([[cos_a, sin_a, 0.0], [-sin_a, cos_a, 0.0], [0.0, 0.0, 1.0]])
    t = np.zeros((6, 6))
    t[:3, :3] = r
    t[3:, 3:] = r
    return t


def _prepare(node_xy, members):
    """Precompute lengths, transformations and dof maps of the members."""
    xy = np.asarray(node_xy, dtype=float)
    out = []
    for m in members:
        a, b = int(m["start"]), int(m["end"])
        dx, dy = xy[b] - xy[a]
        L = float(np.hypot(dx, dy))
        if L <= 0.0:
            raise ValueError(f"zero-length member {a}-{b}")
        props = (L, float(m["E"]), float(m["A"]), float(m["I"]), float(m["rho"]))
        dofs = np.array([3 * a, 3 * a + 1, 3 * a + 2, 3 * b, 3 * b + 1, 3 * b + 2])
        out.append((props, _rotation(dx / L, dy / L), dofs))
    return out


def wittrick_williams_count(omega, node_xy, members, fixed_dofs,
                            node_masses=None, grounded_springs=None,
                            _prepared=None):
    """Number of natural frequencies strictly below ``omega`` (rad/s).

    Parameters are those of :func:`natural_frequencies_hz`, except ``omega``
    (circular frequency, rad/s).

    Returns
    -------
    int
        ``J0(omega) + s{K(omega)}``.
    """
    prepared = _prepare(node_xy, members) if _prepared is None else _prepared
    n_dof = 3 * len(node_xy)
    K = np.zeros((n_dof, n_dof))
    j0 = 0
    for props, t, dofs in prepared:
        K[np.ix_(dofs, dofs)] += t.T @ member_dynamic_stiffness(omega, *props) @ t
        j0 += _clamped_member_count(omega, *props)
    for node, (mass, inertia) in (node_masses or {}).items():
        d = 3 * int(node)
        K[[d, d + 1, d + 2], [d, d + 1, d + 2]] -= omega ** 2 * np.array(
            [mass, mass, inertia], dtype=float)
    for dof, stiffness in (grounded_springs or {}).items():
        K[int(dof), int(dof)] += stiffness
    free = np.setdiff1d(np.arange(n_dof), np.fromiter(fixed_dofs, dtype=int))
    if free.size == 0:
        return j0
    Kf = K[np.ix_(free, free)]
    # symmetric scaling keeps the inertia (Sylvester) and balances units
    d = np.abs(np.diag(Kf))
    scale = 1.0 / np.sqrt(np.where(d > 0.0, d, 1.0))
    eig = np.linalg.eigvalsh(Kf * scale[:, None] * scale[None, :])
    return j0 + int(np.count_nonzero(eig < 0.0))


def natural_frequencies_hz(node_xy, members, fixed_dofs, count,
                           node_masses=None, grounded_springs=None,
                           tol_hz=1e-9):
    """First ``count`` exact natural frequencies of a planar frame.

    Parameters
    ----------
    node_xy : array_like, shape (n_nodes, 2)
        Node coordinates (m); node ``i`` has dofs 3i, 3i+1, 3i+2 for
        (ux, uy, rz) in global axes.
    members : sequence of dict
        Keys ``start``, ``end``, ``E``, ``A``, ``I``, ``rho``; rigid joints.
    fixed_dofs : iterable of int
        Clamped global dofs.
    count : int
        Number of frequencies wanted.
    node_masses : dict, optional
        ``node -> (mass, rotary_inertia)`` lumped at nodes.
    grounded_springs : dict, optional
        ``global dof -> stiffness`` added to the diagonal.
    tol_hz : float, optional
        Bisection tolerance in Hz (raised to a few ulps if smaller).

    Returns
    -------
    numpy.ndarray
        Frequencies (Hz), ascending, repeated according to multiplicity.
    """
    fixed = [int(d) for d in fixed_dofs]
    prepared = _prepare(node_xy, members)

    def J(omega):
        return wittrick_williams_count(omega, node_xy, members, fixed,
                                       node_masses, grounded_springs, prepared)

    samples = {0.0: 0}  # omega -> J(omega); J(0) = 0 for a stable frame
    hi = 2.0 * np.pi
    while True:
        samples[hi] = J(hi)
        if samples[hi] >= count:
            break
        hi *= 2.0
        if hi > 1e12:
            raise RuntimeError(f"fewer than {count} frequencies below 1.6e11 Hz")
    tol = 2.0 * np.pi * tol_hz
    result = []
    for k in range(1, count + 1):
        lo = max(w for w, n in samples.items() if n < k)
        up = min(w for w, n in samples.items() if n >= k)
        for _ in range(200):
            if up - lo <= max(tol, 8.0 * np.finfo(float).eps * up):
                break
            mid = 0.5 * (lo + up)
            samples[mid] = J(mid)
            if samples[mid] >= k:
                up = mid
            else:
                lo = mid
        result.append(0.5 * (lo + up) / (2.0 * np.pi))
    return np.array(result)


def portal_frame_reference(count=6):
    """Documented clamped-base aluminium portal frame and its frequencies.

    Columns 0.5 m high, beam 0.6 m long, rigid knees, both bases clamped.
    Flat bar 30 mm x 8 mm bending about its thin direction in the frame
    plane: A = 0.03*0.008, I = 0.03*0.008**3/12; E = 70 GPa,
    rho = 2700 kg/m3.  Nodes: 0 (0, 0), 1 (0, 0.5), 2 (0.6, 0.5),
    3 (0.6, 0); members 0-1, 1-2, 2-3.

    Returns
    -------
    dict
        ``node_xy``, ``members``, ``fixed_dofs`` and ``frequencies_hz``
        (first ``count`` exact frequencies, ascending).
    """
    sec = dict(E=70e9, A=0.03 * 0.008, I=0.03 * 0.008 ** 3 / 12.0, rho=2700.0)
    node_xy = np.array([[0.0, 0.0], [0.0, 0.5], [0.6, 0.5], [0.6, 0.0]])
    members = [dict(start=0, end=1, **sec), dict(start=1, end=2, **sec),
               dict(start=2, end=3, **sec)]
    fixed_dofs = [0, 1, 2, 9, 10, 11]
    freqs = natural_frequencies_hz(node_xy, members, fixed_dofs, count)
    return dict(node_xy=node_xy, members=members, fixed_dofs=fixed_dofs,
                frequencies_hz=freqs)


if __name__ == "__main__":
    ref = portal_frame_reference()
    for n, f in enumerate(ref["frequencies_hz"], 1):
        print(f"mode {n}: {f:.9f} Hz")
