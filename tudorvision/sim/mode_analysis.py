"""Linearised modes of the simulated arm with the joints held: frequencies, decay rates, shapes.

The two-way assumed-modes model (:func:`tudorvision.sim.model.coupled_mass_matrix`)
restricted to the link modes (gear outputs held), with the modal stiffness
``diag(omega_r^2)`` (hub springs engaged, :mod:`tudorvision.sim.joint_compliance`)
and the damping ``diag(2 zeta_r omega_r) + sum_j c_r,j phi'_j(0) phi'_j(0)^T``
(modal damping plus the hub dampers, engaged). The backlash is not linear:
inside its gap the ring-down of :mod:`tudorvision.lab.plant_modes` is the reference.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.linalg import eig

from .model import coupled_mass_matrix

__all__ = ["held_joint_matrices", "held_joint_modes"]


def held_joint_matrices(arm, coupled: bool = True):
    """Mass, damping and stiffness of the link modes of ``arm`` with its joints held, at its pose.

    Parameters
    ----------
    arm : ElasticArm
        The plant (its bodies, link modes, hub compliance and current ``theta``).
    coupled : bool, optional
        ``False``: the one-way model's view, each link on its own BVP (identity mass matrix).

    Returns
    -------
    M, C, K : ndarray, shape (n2 + n3, n2 + n3)
        Modal mass (dimensionless, mass-normalised coordinates), damping (1/s) and stiffness (1/s^2).
    """
    b, k2, k3 = arm.bodies, arm.link2, arm.link3
    c3 = math.cos(arm.theta[2])
    sc = b.s3 * c3
    c2_t3 = [b.J3 * k2.dphiL[r] + sc * k2.phiL[r] for r in range(k2.n)]
    c3_t2 = [k3.gamma[q] + k3.pi[q] * b.l2 * c3 for q in range(k3.n)]
    E = [[k3.gamma[q] * k2.dphiL[r] + k3.pi[q] * k2.phiL[r] * c3 for q in range(k3.n)] for r in range(k2.n)]
    coupling = (k2.gamma, c2_t3, c3_t2, k3.gamma, E)
    m22 = b.J2 + b.J3 + 2 * b.l2 * sc + b.rotor[1]
    M = coupled_mass_matrix(m22, b.J3 + b.l2 * sc, b.J3 + b.rotor[2], coupling, b, k2, k3, c3)[2:, 2:]
    if not coupled:
        M = np.eye(k2.n + k3.n)
    K = np.diag(k2.om2 + k3.om2)
    C = np.diag(k2.cdamp + k3.cdamp)
    for j, lm in enumerate((k2, k3)):
        v = np.zeros(k2.n + k3.n)
        v[(0 if j == 0 else k2.n):(k2.n if j == 0 else k2.n + k3.n)] = lm.dphi0
        C += arm.hub.c[j] * np.outer(v, v)
    return M, C, K


def held_joint_modes(arm, coupled: bool = True):
    """Natural frequencies, decay rates and shapes of the link modes with the joints held.

    Parameters
    ----------
    arm : ElasticArm
        The plant at the pose of interest.
    coupled : bool, optional
        ``False``: each link on its own BVP (what the one-way plant integrates).

    Returns
    -------
    freq_hz : ndarray, shape (n,)
        Undamped natural frequencies, increasing, Hz (``n = n2 + n3``).
    decay_per_s : ndarray, shape (n,)
        ``-Re(s)`` of the damped pole nearest each natural frequency, 1/s.
    shapes : ndarray, shape (n, n)
        Column ``i``: modal coordinates ``(eta2, eta3)`` of mode ``i`` (undamped).
    """
    from scipy.linalg import eigh
    M, C, K = held_joint_matrices(arm, coupled)
    w2, V = eigh(K, M)
    f = np.sqrt(np.maximum(w2, 0.0)) / (2 * np.pi)
    n = len(w2)
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ C]])
    s = eig(A, right=False)
    s = s[s.imag > 0]
    decay = np.array([-s[np.argmin(np.abs(s.imag - 2 * np.pi * fi))].real if len(s) else np.nan for fi in f])
    return f, decay, V
