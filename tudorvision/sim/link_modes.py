"""One elastic link's modal model as the plant integrates it: constants, modal forces, exact modal steps."""
from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from .beam import ModalBasis, cantilever_static, gauss_points

__all__ = ["LinkModes", "coupled_mass_matrix"]


class LinkModes:
    """Modal constants of one elastic link for the plant's scalar 2 kHz loop (rebuilt when the payload changes).

    Parameters
    ----------
    basis : ModalBasis
        Clamped-blade modes with the distal bodies as tip mass and inertia.
    gauges : sequence of float
        Strain-gauge positions along the link, m from the hub.
    zeta : sequence of float
        Modal damping ratios (the last one repeats for higher modes).
    dt : float
        Plant step, s (the exact zero-order-hold transition matrices use it).
    """

    def __init__(self, basis: ModalBasis, gauges, zeta, dt: float):
        self.basis = basis
        self.L, self.EI, self.h = basis.length_m, basis.flexural_rigidity_Nm2, basis.height_m
        self.gauges = [float(x) for x in gauges]
        n = basis.n_modes
        om = basis.omega_rad_s
        self.om2 = [float(w * w) for w in om]
        self.gamma = [float(x) for x in basis.rotation_participation]
        self.pi = [float(x) for x in basis.translation_participation]
        self.phiL = [float(x) for x in basis.shape([self.L])[:, 0]]
        self.dphiL = [float(x) for x in basis.shape([self.L], 1)[:, 0]]
        self.iphi = [float(x) for x in basis.static_coordinates(1.0, 0.0, 0.0) * om**2]
        self.dphi0 = [float(x) for x in basis.hub_slope]     # Phi_r'(0): hub rotation per mode
        K = float(basis.hub_stiffness_Nm_rad)
        self.kinv = 0.0 if not np.isfinite(K) else 1.0 / K
        d2 = basis.shape(self.gauges, 2)
        self.ddphi_g = [[float(d2[r, k]) for r in range(n)] for k in range(len(self.gauges))]
        self.zoh = []
        self.cdamp = []
        for r in range(n):
            z = float(zeta[min(r, len(zeta) - 1)])
            self.cdamp.append(2.0 * z * float(om[r]))
            A = expm(np.array([[0.0, 1.0], [-om[r] ** 2, -2.0 * z * om[r]]]) * dt)
            self.zoh.append(tuple(float(v) for v in A.ravel()))
        self.n = n

    def generalised_force(self, q: float, P: float, M: float, Mh: float = 0.0) -> list:
        """Modal forces of a distributed load ``q`` (N/m), tip force ``P`` (N), tip moment ``M`` and root moment ``Mh`` (N m)."""
        return [self.iphi[r] * q + self.phiL[r] * P + self.dphiL[r] * M + self.dphi0[r] * Mh for r in range(self.n)]

    def static_hub_angle(self, q: float, P: float, M: float, Mh: float = 0.0) -> float:
        """Rotation of the root on the hub spring under static loads, rad (0 for rigid clamping)."""
        L = self.L
        return (q * L * L / 2.0 + P * L + M + Mh) * self.kinv

    def zoh_step(self, r: int, eta: list, deta: list, u: float, dt: float) -> float:
        """Exact step of ``eta'' + c eta' + w^2 eta = u`` for mode ``r`` (in place); returns the mean acceleration."""
        xs = u / self.om2[r]
        A11, A12, A21, A22 = self.zoh[r]
        x, v = eta[r] - xs, deta[r]
        v_new = A21 * x + A22 * v
        eta[r] = xs + A11 * x + A12 * v
        deta[r] = v_new
        return (v_new - v) / dt

    def shape_on_grid(self, eta, deta, loads):
        """The link's deflection on a quadrature grid for modal state ``(eta, deta)`` under ``loads``.

        Returns
        -------
        tuple
            ``(x, weights, w, dw, w_tip, slope_tip, v_tip, slope_rate_tip)``: grid (m), quadrature
            weights, deflection and its rate on the grid, tip deflection, slope and their rates.
        """
        B = self.basis
        xg, wg = gauss_points(B.length_m)
        ws, ss, _ = cantilever_static(xg, B.length_m, B.flexural_rigidity_Nm2, q_N_m=loads[0],
                                      tip_force_N=loads[1], tip_moment_Nm=loads[2])
        wsL, ssL, _ = cantilever_static(B.length_m, B.length_m, B.flexural_rigidity_Nm2, q_N_m=loads[0],
                                        tip_force_N=loads[1], tip_moment_Nm=loads[2])
        ph = self.static_hub_angle(*loads)          # rigid rotation on the hub spring
        ws, wsL, ssL = ws + xg * ph, wsL + B.length_m * ph, ssL + ph
        nu = np.asarray(eta) - B.static_coordinates(*loads)
        phi = B.shape(xg)
        w = ws + nu @ phi
        dw = np.asarray(deta) @ phi
        wL = float(wsL) + float(nu @ np.asarray(self.phiL))
        sL = float(ssL) + float(nu @ np.asarray(self.dphiL))
        vL = float(np.asarray(deta) @ np.asarray(self.phiL))
        svL = float(np.asarray(deta) @ np.asarray(self.dphiL))
        return xg, wg, w, dw, wL, sL, vL, svL


def coupled_mass_matrix(m22, m23, m33, coupling, bodies: ArmBodies, link2, link3, c3: float) -> np.ndarray:
    """Assumed-modes mass matrix of the two-way model over (theta2, theta3, eta2, eta3).

    Parameters
    ----------
    m22, m23, m33 : float
        Rigid joint-2/3 block of the mass matrix, kg m^2.
    coupling : tuple
        ``(c2_t2, c2_t3, c3_t2, c3_t3, E)`` mode/joint couplings at the current elbow angle.
    bodies : ArmBodies
        Lumped bodies (uses ``s3``, the first moment of the distal body, and ``l2``).
    link2, link3 : LinkModes
        Modes of the elastic links (``n``, tip values ``phiL`` and slopes ``dphiL``).
    c3 : float
        cos(theta3).

    Returns
    -------
    ndarray, shape (2 + n2 + n3, 2 + n2 + n3)
        Symmetric mass matrix.
    """
    b, k2, k3 = bodies, link2, link3
    n2, n3 = k2.n, k3.n
    c2_t2, c2_t3, c3_t2, c3_t3, E = coupling
    sc = b.s3 * c3
    N = 2 + n2 + n3
    M = np.zeros((N, N))
    M[0, 0], M[0, 1], M[1, 0], M[1, 1] = m22, m23, m23, m33
    for r in range(n2):
        M[0, 2 + r] = M[2 + r, 0] = c2_t2[r] + sc * (b.l2 * k2.dphiL[r] + k2.phiL[r])
        M[1, 2 + r] = M[2 + r, 1] = c2_t3[r]
        for q in range(n2):
            M[2 + r, 2 + q] = (1.0 if r == q else 0.0) + sc * (k2.phiL[r] * k2.dphiL[q]
                                                               + k2.dphiL[r] * k2.phiL[q])
        for q in range(n3):
            M[2 + r, 2 + n2 + q] = M[2 + n2 + q, 2 + r] = E[r][q]
    for q in range(n3):
        M[0, 2 + n2 + q] = M[2 + n2 + q, 0] = c3_t2[q]
        M[1, 2 + n2 + q] = M[2 + n2 + q, 1] = c3_t3[q]
        M[2 + n2 + q, 2 + n2 + q] = 1.0
    return M
