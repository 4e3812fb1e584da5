"""Euler–Bernoulli beam model of TUDOR's elastic links (sections 4.2–4.5, 5.1).

Each elastic link is a uniform spring-steel blade clamped to its joint hub
(rigid clamping, ``K_r -> inf``) with a load mass ``m_L`` and load inertia
``I_L`` at the tip (the distal actuator, links and payload, the inertia taken
about the tip bending axis with the parallel-axis theorem).

Link frame conventions
----------------------
``x`` runs along the undeflected neutral fibre from the hub (``x = 0``) to the
tip (``x = L``). The deflection ``w(x)`` is measured along the link's ``y``
axis, which lies in the arm's vertical plane and points in the direction of
increasing joint angle (upward when the link is horizontal at zero
configuration). The slope is ``w'`` (radians, positive = rotated like a
positive joint angle) and the curvature ``w''`` (1/m).

Surface strain is reported on the top surface (the ``+y`` face, where the
gauges of a horizontal link face up), positive in tension::

    eps(x) = -(h / 2) * w''(x)

so a horizontal link sagging under gravity reads positive strain near the hub.

Static loads are given per unit of the link ``y`` direction: ``q`` is a
distributed force per length (N/m), ``tip_force`` a force at ``x = L`` (N)
and ``tip_moment`` a moment at ``x = L`` (N m, positive turning ``+x`` toward
``+y``). Gravity on a horizontal link gives negative ``q`` and ``tip_force``.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from .._checks import TudorVisionError
from ..robot.params import LinkParams

__all__ = [
    "cantilever_static", "surface_strain", "characteristic_tip_load",
    "tip_load_roots", "spring_hinged_roots", "characteristic_spring_hinged", "ModalBasis", "modal_basis", "link_rho", "link_rigidity",
]


def cantilever_static(x, length_m: float, flexural_rigidity_Nm2: float, *, q_N_m: float = 0.0,
                      tip_force_N: float = 0.0, tip_moment_Nm: float = 0.0):
    """Static deflection of a clamped–free Euler–Bernoulli beam (superposition).

    Own weight (uniform ``q``), a transverse tip force and a tip moment::

        w  = q x^2 (6L^2 - 4Lx + x^2) / (24 EI) + P x^2 (3L - x) / (6 EI) + M x^2 / (2 EI)
        w' = q x (3L^2 - 3Lx + x^2) / (6 EI)    + P x (2L - x) / (2 EI)    + M x / EI
        w''= q (L - x)^2 / (2 EI)                + P (L - x) / EI           + M / EI

    Parameters
    ----------
    x : array_like
        Positions along the link, metres, ``0 <= x <= L``.
    length_m, flexural_rigidity_Nm2 : float
        Beam length ``L`` and stiffness ``E I_z``.
    q_N_m, tip_force_N, tip_moment_Nm : float
        Loads along the link ``y`` direction (see the module notes).

    Returns
    -------
    w, slope, curvature : ndarray
        Deflection (m), slope (rad) and curvature (1/m) at ``x``.

    Examples
    --------
    >>> w, s, k = cantilever_static(1.0, 1.0, 3.0, tip_force_N=-1.0)
    >>> round(float(w), 6)   # -P L^3 / (3 EI)
    -0.111111
    """
    x = np.asarray(x, dtype=np.float64)
    L, EI = float(length_m), float(flexural_rigidity_Nm2)
    q, P, M = float(q_N_m), float(tip_force_N), float(tip_moment_Nm)
    w = (q * x**2 * (6 * L**2 - 4 * L * x + x**2) / 24.0 + P * x**2 * (3 * L - x) / 6.0
         + M * x**2 / 2.0) / EI
    slope = (q * x * (3 * L**2 - 3 * L * x + x**2) / 6.0 + P * x * (2 * L - x) / 2.0 + M * x) / EI
    curv = (q * (L - x) ** 2 / 2.0 + P * (L - x) + M) / EI
    return w, slope, curv


def surface_strain(curvature, height_m: float) -> np.ndarray:
    """Top-surface strain ``-(h/2) w''`` (dimensionless, m/m; tension positive).

    Examples
    --------
    >>> float(surface_strain(-0.1, 0.004))
    0.0002
    """
    return -0.5 * float(height_m) * np.asarray(curvature, dtype=np.float64)


def characteristic_tip_load(beta, mass_ratio: float, inertia_ratio: float):
    """Characteristic function (4.4.6) of a clamped beam with tip mass and inertia.

    With ``beta = k_w L``, ``mu = m_L / (rho_b L)`` and ``iota = I_L / (rho_b L^3)``
    the seed's equation reads::

        1 + cosh b cos b + mu b (cos b sinh b - cosh b sin b)
          - iota b^3 (cos b sinh b + cosh b sin b) + mu iota b^4 (1 - cos b cosh b) = 0

    The value returned is divided by ``cosh(beta)`` so it stays bounded; the
    roots are unchanged.

    Parameters
    ----------
    beta : array_like
        Dimensionless wave numbers ``k_w L``.
    mass_ratio, inertia_ratio : float
        ``m_L / (rho_b L)`` and ``I_L / (rho_b L^3)``, both >= 0.

    Examples
    --------
    >>> abs(float(characteristic_tip_load(1.875104, 0.0, 0.0))) < 1e-6
    True
    """
    b = np.asarray(beta, dtype=np.float64)
    mu, io = float(mass_ratio), float(inertia_ratio)
    c, s = np.cos(b), np.sin(b)
    t = np.tanh(b)                     # sinh / cosh
    sech = 1.0 / np.cosh(b)
    return (sech + c + mu * b * (c * t - s) - io * b**3 * (c * t + s)
            + mu * io * b**4 * (sech - c))


def tip_load_roots(n_roots: int, mass_ratio: float, inertia_ratio: float) -> np.ndarray:
    """First ``n_roots`` positive roots ``beta_r`` of (4.4.6), by bracketing and Brent's method.

    Parameters
    ----------
    n_roots : int
        Number of roots wanted (>= 1).
    mass_ratio, inertia_ratio : float
        ``m_L / (rho_b L)`` and ``I_L / (rho_b L^3)``.

    Returns
    -------
    beta : ndarray, shape (n_roots,)
        Increasing roots; ``omega_r = beta_r^2 sqrt(EI / (rho_b L^4))`` (4.4.7).

    Raises
    ------
    ValueError
        If a ratio is negative or ``n_roots < 1``.

    Examples
    --------
    >>> np.round(tip_load_roots(2, 0.0, 0.0), 4)   # clamped-free cantilever
    array([1.8751, 4.6941])
    """
    if n_roots < 1:
        raise ValueError(f"n_roots: expected >= 1, got {n_roots}")
    if mass_ratio < 0 or inertia_ratio < 0:
        raise ValueError(f"mass_ratio, inertia_ratio: expected >= 0, got {mass_ratio}, {inertia_ratio}")
    f = functools.partial(characteristic_tip_load, mass_ratio=mass_ratio, inertia_ratio=inertia_ratio)
    roots: list[float] = []
    lo, step = 1e-4, 0.02
    while len(roots) < n_roots:
        grid = lo + step * np.arange(1, 501)
        vals = f(np.concatenate([[lo], grid]))
        pts = np.concatenate([[lo], grid])
        idx = np.nonzero(np.sign(vals[:-1]) * np.sign(vals[1:]) < 0)[0]
        for i in idx:
            roots.append(brentq(f, pts[i], pts[i + 1], xtol=1e-13, rtol=1e-13))
            if len(roots) == n_roots:
                break
        lo = pts[-1]
    return np.asarray(roots[:n_roots])


@dataclass(frozen=True, kw_only=True)
class ModalBasis:
    """Mass-normalised bending modes of one link with its current tip load.

    A mode shape is ``Phi_r(x) = a_r (sinh k x - sin k x) + b_r (cosh k x - cos k x)
    + c_r (sinh k x + sin k x)`` with ``c_r = b_r k EI / K_r`` (the rotary
    spring support of (4.4.2): ``Phi'(0) = (EI / K_r) Phi''(0)``; ``c_r = 0``
    for rigid clamping, ``K_r -> inf``), normalised so that
    ``int rho Phi_r^2 dx + m_L Phi_r(L)^2 + I_L Phi_r'(L)^2 = 1`` (4.4.9).
    The modal stiffness is then ``omega_r^2 = int EI Phi_r''^2 dx + K_r Phi_r'(0)^2``.

    Attributes
    ----------
    length_m, rho_kg_m, flexural_rigidity_Nm2, height_m : float
        Beam data.
    tip_mass_kg, tip_inertia_kg_m2 : float
        Load at the tip (inertia about the tip bending axis).
    beta : ndarray, shape (n,)
        Roots of (4.4.6).
    omega_rad_s : ndarray, shape (n,)
        Natural frequencies (4.4.7), rad/s.
    coef : ndarray, shape (n, 3)
        ``(a_r, b_r, c_r)`` of each normalised shape.
    hub_stiffness_Nm_rad : float
        Rotary clamping stiffness ``K_r`` at the hub, N m/rad (``inf``: rigid clamping).
    rotation_participation : ndarray, shape (n,)
        ``Gamma_r = int rho x Phi_r + m_L L Phi_r(L) + I_L Phi_r'(L)``: modal
        force per unit hub angular acceleration is ``-Gamma_r``.
    translation_participation : ndarray, shape (n,)
        ``Pi_r = int rho Phi_r + m_L Phi_r(L)``: modal force per unit hub
        acceleration along the link ``y`` axis is ``-Pi_r``.
    """

    length_m: float
    rho_kg_m: float
    flexural_rigidity_Nm2: float
    height_m: float
    tip_mass_kg: float
    tip_inertia_kg_m2: float
    beta: np.ndarray
    omega_rad_s: np.ndarray
    coef: np.ndarray
    rotation_participation: np.ndarray
    translation_participation: np.ndarray
    hub_stiffness_Nm_rad: float = float("inf")

    @property
    def n_modes(self) -> int:
        return len(self.beta)

    @property
    def frequency_hz(self) -> np.ndarray:
        """Natural frequencies in Hz."""
        return self.omega_rad_s / (2 * np.pi)

    def shape(self, x, derivative: int = 0) -> np.ndarray:
        """Mode shapes or their spatial derivatives at positions ``x``.

        Parameters
        ----------
        x : array_like, shape (K,)
            Positions along the link, metres.
        derivative : {0, 1, 2, 3}
            Order of the spatial derivative.

        Returns
        -------
        ndarray, shape (n_modes, K)
            ``d^j Phi_r / dx^j`` at ``x``; units m/sqrt(kg) per m^j.
        """
        return _shape(self.beta / self.length_m, self.coef, np.atleast_1d(np.asarray(x, float)),
                      derivative)

    def shape_at(self, x: float) -> np.ndarray:
        """``shape([x])[:, 0]``, remembered per position (read-only), shape (n_modes,).

        The arm evaluates its probes at a few fixed points at 2 kHz; the values are those of
        :meth:`shape`, bit for bit.

        Examples
        --------
        >>> from tudorvision.robot.params import load_robot_params
        >>> b = modal_basis(load_robot_params().link3, 0.0, 0.0)
        >>> bool((b.shape_at(0.3) == b.shape([0.3])[:, 0]).all())
        True
        """
        cache = self.__dict__.setdefault("_shape_at", {})
        key = float(x)
        row = cache.get(key)
        if row is None:
            row = self.shape([key])[:, 0]
            row.setflags(write=False)
            cache[key] = row
        return row

    def static_coordinates(self, q_N_m: float, tip_force_N: float, tip_moment_Nm: float,
                           hub_moment_Nm: float = 0.0) -> np.ndarray:
        """Modal coordinates of the static deflection under the given loads.

        For exact eigenfunctions the mass-weighted projection of the static
        shape equals the generalised force over ``omega_r^2``::

            eta_r = (q int Phi_r dx + P Phi_r(L) + M Phi_r'(L) + M_hub Phi_r'(0)) / omega_r^2

        ``hub_moment_Nm`` is a moment on the link at its root (turning it like
        a positive joint angle), e.g. the backlash correction of
        :mod:`tudorvision.sim.joint_compliance`; it only matters for a finite ``K_r``.
        """
        return (q_N_m * self._int_phi + tip_force_N * self._phi_tip + tip_moment_Nm * self._dphi_tip
                + hub_moment_Nm * self.hub_slope) / self.omega_rad_s**2

    def static_hub_angle(self, q_N_m: float, tip_force_N: float, tip_moment_Nm: float,
                         hub_moment_Nm: float = 0.0) -> float:
        """Rotation of the link root on its spring under static loads, rad (0 for rigid clamping).

        The spring carries the root moment of the loads,
        ``q L^2 / 2 + P L + M`` plus ``hub_moment_Nm``, so the root turns by that over ``K_r``.
        """
        if not np.isfinite(self.hub_stiffness_Nm_rad):
            return 0.0
        L = self.length_m
        return float((q_N_m * L * L / 2.0 + tip_force_N * L + tip_moment_Nm + hub_moment_Nm)
                     / self.hub_stiffness_Nm_rad)

    @functools.cached_property
    def hub_slope(self) -> np.ndarray:
        """``Phi_r'(0)`` per mode, 1/sqrt(kg) (zero for rigid clamping), shape (n,)."""
        return self.shape([0.0], 1)[:, 0]

    @functools.cached_property
    def _phi_tip(self) -> np.ndarray:
        return self.shape([self.length_m])[:, 0]

    @functools.cached_property
    def _dphi_tip(self) -> np.ndarray:
        return self.shape([self.length_m], 1)[:, 0]

    @functools.cached_property
    def _int_phi(self) -> np.ndarray:
        xg, wg = gauss_points(self.length_m)
        return self.shape(xg) @ wg


def link_rho(link: LinkParams) -> float:
    """Mass per unit length ``rho_b`` of a blade, kg/m."""
    return float(link.density_kg_m3) * float(link.width_m) * float(link.height_m)


def link_rigidity(link: LinkParams) -> float:
    """Flexural rigidity ``E I_z = E b h^3 / 12`` of a blade, N m^2.

    (Converts through ``float`` so a YAML value such as ``200.0e9``, which
    YAML 1.1 reads as a string, still works.)
    """
    return float(link.youngs_modulus_Pa) * float(link.width_m) * float(link.height_m) ** 3 / 12.0


def _shape(k: np.ndarray, coef: np.ndarray, x: np.ndarray, derivative: int) -> np.ndarray:
    kx = k[:, None] * x[None, :]
    sh, ch, s, c = np.sinh(kx), np.cosh(kx), np.sin(kx), np.cos(kx)
    # derivatives of (sinh - sin) and (cosh - cos), divided by k^j
    table = {
        0: (sh - s, ch - c, sh + s),
        1: (ch - c, sh + s, ch + c),
        2: (sh + s, ch + c, sh - s),
        3: (ch + c, sh - s, ch - c),
    }
    if derivative not in table:
        raise ValueError(f"derivative: expected 0..3, got {derivative}")
    f1, f2, f3 = table[derivative]
    out = coef[:, :1] * f1 + coef[:, 1:2] * f2
    if coef.shape[1] > 2:
        out = out + coef[:, 2:3] * f3
    return (k[:, None] ** derivative) * out


def gauss_points(length: float, n: int = 64):
    xg, wg = np.polynomial.legendre.leggauss(n)
    return 0.5 * length * (xg + 1.0), 0.5 * length * wg


def _tip_rows(beta, mass_ratio, inertia_ratio, compliance):
    """Tip conditions (4.4.3), (4.4.4) on ``(a, b)`` for the spring-supported shape (L = rho = 1), / cosh."""
    b = np.asarray(beta, dtype=np.float64)
    t, sech = np.tanh(b), 1.0 / np.cosh(b)
    s, c = np.sin(b) * sech, np.cos(b) * sech
    # sinh, cosh divided by cosh
    sh, ch = t, np.ones_like(b)
    kap = compliance * b              # c = kap * b_coef (k EI / K_r with L = 1)
    g = b**3 * inertia_ratio
    e = b * mass_ratio
    S1 = (sh - s, ch - c, sh + s, ch + c)
    S2 = tuple(u + kap * v for u, v in zip((ch - c, sh + s, ch + c, sh - s), (sh + s, ch + c, sh - s, ch - c)))
    m1, m2 = S1[2] - g * S1[1], S2[2] - g * S2[1]
    f1, f2 = S1[3] + e * S1[0], S2[3] + e * S2[0]
    return m1, m2, f1, f2


def characteristic_spring_hinged(beta, mass_ratio: float, inertia_ratio: float, compliance: float):
    """Characteristic function (4.4.5) of a beam on a rotary spring with tip mass and inertia.

    Written as the determinant of the two tip conditions on the shapes that
    satisfy the hub conditions (4.4.1), (4.4.2); its roots are those of (4.4.5).

    Parameters
    ----------
    beta : array_like
        Dimensionless wave numbers ``k_w L``.
    mass_ratio, inertia_ratio : float
        ``m_L / (rho_b L)`` and ``I_L / (rho_b L^3)``, both >= 0.
    compliance : float
        ``EI / (K_r L)`` (0: rigid clamping, then the roots are those of (4.4.6)).

    Returns
    -------
    ndarray
        Same shape as ``beta``; bounded (divided by ``cosh^2 beta``).
    """
    m1, m2, f1, f2 = _tip_rows(beta, mass_ratio, inertia_ratio, compliance)
    return m1 * f2 - m2 * f1


def spring_hinged_roots(n_roots: int, mass_ratio: float, inertia_ratio: float, compliance: float) -> np.ndarray:
    """First ``n_roots`` positive roots ``beta_r`` of (4.4.5) by bracketing and Brent's method.

    Parameters
    ----------
    n_roots : int
        Number of roots wanted (>= 1).
    mass_ratio, inertia_ratio : float
        ``m_L / (rho_b L)`` and ``I_L / (rho_b L^3)``.
    compliance : float
        ``EI / (K_r L)`` >= 0 (the seed's ``EI_z / K_r`` over the length).

    Returns
    -------
    beta : ndarray, shape (n_roots,)
        Increasing roots; ``omega_r = beta_r^2 sqrt(EI / (rho_b L^4))`` (4.4.7).

    Raises
    ------
    ValueError
        If a ratio or the compliance is negative or ``n_roots < 1``.

    Examples
    --------
    >>> bool(np.allclose(spring_hinged_roots(2, 0.5, 0.1, 0.0), tip_load_roots(2, 0.5, 0.1)))
    True
    """
    if n_roots < 1:
        raise ValueError(f"n_roots: expected >= 1, got {n_roots}")
    if mass_ratio < 0 or inertia_ratio < 0 or compliance < 0:
        raise ValueError(f"mass_ratio, inertia_ratio, compliance: expected >= 0, got "
                         f"{mass_ratio}, {inertia_ratio}, {compliance}")
    f = functools.partial(characteristic_spring_hinged, mass_ratio=mass_ratio, inertia_ratio=inertia_ratio,
                          compliance=compliance)
    roots: list[float] = []
    lo, step = 1e-4, 0.005
    while len(roots) < n_roots:
        pts = lo + step * np.arange(0, 2001)
        vals = f(pts)
        idx = np.nonzero(np.sign(vals[:-1]) * np.sign(vals[1:]) < 0)[0]
        for i in idx:
            roots.append(brentq(f, pts[i], pts[i + 1], xtol=1e-13, rtol=1e-13))
            if len(roots) == n_roots:
                break
        lo = pts[-1]
    return np.asarray(roots[:n_roots])


def modal_basis(link: LinkParams, tip_mass_kg: float, tip_inertia_kg_m2: float,
                n_modes: int = 2, hub_stiffness_Nm_rad: float = float("inf")) -> ModalBasis:
    """Solve the boundary-value problem (4.4.6), or (4.4.5) with a hub spring, for one link and build its modes.

    Parameters
    ----------
    link : LinkParams
        Blade geometry and material.
    tip_mass_kg, tip_inertia_kg_m2 : float
        Aggregated load at the tip; the inertia is about the tip bending axis.
    n_modes : int
        Number of modes (>= 1).
    hub_stiffness_Nm_rad : float, optional
        Rotary clamping stiffness ``K_r`` at the hub, N m/rad; ``inf`` (default) is
        the rigid clamping of (4.4.6).

    Returns
    -------
    ModalBasis

    Raises
    ------
    ValueError
        If the tip load is negative, ``n_modes < 1`` or ``hub_stiffness_Nm_rad`` is not positive.

    Examples
    --------
    >>> from tudorvision.robot import load_robot_params
    >>> b = modal_basis(load_robot_params().link3, 0.0, 0.0)
    >>> np.round(b.frequency_hz, 1)   # bare blade: clamped-free cantilever
    array([ 19.5, 122. ])
    """
    if tip_mass_kg < 0 or tip_inertia_kg_m2 < 0:
        raise ValueError(f"tip load: expected mass and inertia >= 0, got {tip_mass_kg}, {tip_inertia_kg_m2}")
    if not hub_stiffness_Nm_rad > 0:
        raise ValueError(f"hub_stiffness_Nm_rad: expected > 0 (inf for rigid clamping), got {hub_stiffness_Nm_rad}")
    return _modal_basis_cached(float(link.length_m), link_rho(link), link_rigidity(link),
                               float(link.height_m), float(tip_mass_kg), float(tip_inertia_kg_m2),
                               int(n_modes), float(hub_stiffness_Nm_rad))


@functools.lru_cache(maxsize=256)
def _modal_basis_cached(L, rho, EI, h, mL, IL, n_modes, Kr=float("inf")) -> ModalBasis:
    rigid = not np.isfinite(Kr)
    comp = 0.0 if rigid else EI / (Kr * L)
    if rigid:
        beta = tip_load_roots(n_modes, mL / (rho * L), IL / (rho * L**3))
    else:
        beta = spring_hinged_roots(n_modes, mL / (rho * L), IL / (rho * L**3), comp)
    k = beta / L
    omega = beta**2 * np.sqrt(EI / (rho * L**4))
    coef = np.zeros((n_modes, 3))
    for r, kr in enumerate(k):
        m1, m2, f1, f2 = (float(v) for v in _tip_rows(kr * L, mL / (rho * L), IL / (rho * L**3), comp))
        # pick the better-conditioned row to fix the ratio a : b
        if abs(m1) + abs(m2) >= abs(f1) + abs(f2):
            a, b = m2, -m1
        else:
            a, b = f2, -f1
        coef[r] = (a, b, b * kr * EI / Kr if not rigid else 0.0)
    if not np.all(np.isfinite(coef)):
        raise TudorVisionError("modal_basis: mode shape computation failed (non-finite coefficients)")
    xg, wg = gauss_points(L)
    phi = _shape(k, coef, xg, 0)
    phiL = _shape(k, coef, np.array([L]), 0)[:, 0]
    dphiL = _shape(k, coef, np.array([L]), 1)[:, 0]
    norm = np.sqrt(rho * (phi**2) @ wg + mL * phiL**2 + IL * dphiL**2)
    coef = coef / norm[:, None]
    phi, phiL, dphiL = phi / norm[:, None], phiL / norm, dphiL / norm
    # sign convention: positive tip deflection for every mode
    sign = np.where(phiL < 0, -1.0, 1.0)
    coef, phi, phiL, dphiL = coef * sign[:, None], phi * sign[:, None], phiL * sign, dphiL * sign
    gamma = rho * (phi * xg) @ wg + mL * L * phiL + IL * dphiL
    pi_ = rho * phi @ wg + mL * phiL
    for arr in (beta, omega, coef, gamma, pi_):
        arr.setflags(write=False)
    return ModalBasis(length_m=L, rho_kg_m=rho, flexural_rigidity_Nm2=EI, height_m=h,
                      tip_mass_kg=mL, tip_inertia_kg_m2=IL, beta=beta, omega_rad_s=omega, coef=coef,
                      rotation_participation=gamma, translation_participation=pi_, hub_stiffness_Nm_rad=Kr)
