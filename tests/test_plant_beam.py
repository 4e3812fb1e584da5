"""Elastic-link beam model: static cantilever, tip-load BVP (4.4.6), mode shapes."""
import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid

from tudorvision.robot import load_robot_params
from tudorvision.sim.beam import (cantilever_static, characteristic_tip_load, link_rho,
                                  link_rigidity, modal_basis, surface_strain, tip_load_roots)

P = load_robot_params()


def test_clamped_free_roots_match_textbook():
    # classical cantilever eigenvalues beta_r L (Meirovitch): 1.87510, 4.69409, 7.85476
    beta = tip_load_roots(3, 0.0, 0.0)
    assert np.allclose(beta, [1.875104, 4.694091, 7.854757], atol=1e-5)
    # and the textbook closed form cos(b) cosh(b) = -1
    assert np.allclose(np.cos(beta) * np.cosh(beta), -1.0, atol=1e-8)


def test_roots_make_boundary_conditions_consistent():
    """Independent check of (4.4.6): the 2x2 tip-condition matrix is singular at its roots."""
    rng = np.random.default_rng(3)
    for _ in range(20):
        mu, io = rng.uniform(0, 5), rng.uniform(0, 2)
        for b in tip_load_roots(3, mu, io):
            sh, ch, s, c = np.sinh(b), np.cosh(b), np.sin(b), np.cos(b)
            # Phi = a (sinh - sin) + d (cosh - cos), L = 1, rho = 1
            A = np.array([[(sh + s) - b**3 * io * (ch - c), (ch + c) - b**3 * io * (sh + s)],
                          [(ch + c) + b * mu * (sh - s), (sh - s) + b * mu * (ch - c)]])
            assert abs(np.linalg.det(A)) / np.abs(A).max() ** 2 < 1e-8


def test_characteristic_sign_changes_only_at_roots():
    roots = tip_load_roots(2, 1.0, 0.5)
    b = np.linspace(0.01, roots[1] - 1e-3, 2000)
    f = characteristic_tip_load(b, 1.0, 0.5)
    assert np.count_nonzero(np.diff(np.sign(f)) != 0) == 1


def _basis(mL=0.7, IL=0.02, n=3):
    return modal_basis(P.link2, mL, IL, n)


def test_mode_shape_derivatives_match_finite_differences():
    B = _basis()
    x = np.linspace(0.02, B.length_m - 0.02, 15)
    h = 1e-5
    for d in (1, 2, 3):
        fd = (B.shape(x + h, d - 1) - B.shape(x - h, d - 1)) / (2 * h)
        assert np.allclose(B.shape(x, d), fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())


def test_mode_shapes_satisfy_beam_equation_and_boundary_conditions():
    B = _basis()
    L, rho, EI = B.length_m, B.rho_kg_m, B.flexural_rigidity_Nm2
    k = B.beta / L
    x = np.linspace(0.05, L - 0.05, 9)
    h = 1e-4
    d4 = (B.shape(x + h, 3) - B.shape(x - h, 3)) / (2 * h)
    assert np.allclose(d4, (k**4)[:, None] * B.shape(x), rtol=1e-4, atol=1e-6 * np.abs(d4).max())
    assert np.allclose(B.shape([0.0])[:, 0], 0.0, atol=1e-12)
    assert np.allclose(B.shape([0.0], 1)[:, 0], 0.0, atol=1e-12)
    # tip moment and force balance (4.4.3), (4.4.4)
    phi, d1, d2, d3 = (B.shape([L], j)[:, 0] for j in range(4))
    assert np.allclose(d2, k**4 * B.tip_inertia_kg_m2 / rho * d1, rtol=1e-7, atol=1e-9)
    assert np.allclose(d3, -k**4 * B.tip_mass_kg / rho * phi, rtol=1e-7, atol=1e-9)
    # frequency from the wave number (4.3.3)
    assert np.allclose(B.omega_rad_s, k**2 * np.sqrt(EI / rho))


def test_modes_are_orthonormal_with_tip_mass_and_inertia():
    B = _basis(n=4)
    x = np.linspace(0, B.length_m, 20001)
    phi = B.shape(x)
    G = B.rho_kg_m * np.trapezoid(phi[:, None, :] * phi[None, :, :], x, axis=2)
    tip = B.shape([B.length_m])[:, 0]
    dtip = B.shape([B.length_m], 1)[:, 0]
    G += B.tip_mass_kg * np.outer(tip, tip) + B.tip_inertia_kg_m2 * np.outer(dtip, dtip)
    assert np.allclose(G, np.eye(4), atol=1e-6)


def test_heavy_tip_mass_tends_to_massless_spring():
    link = P.link3
    rho, EI, L = link_rho(link), link_rigidity(link), float(link.length_m)
    m = 50.0 * rho * L
    B = modal_basis(link, m, 0.0, 1)
    # Rayleigh: tip mass plus 33/140 of the beam mass on a spring 3 EI / L^3
    w_ref = np.sqrt(3 * EI / L**3 / (m + 33 / 140 * rho * L))
    assert abs(B.omega_rad_s[0] / w_ref - 1) < 2e-3


def test_static_formula_matches_integrated_moment_distribution():
    L, EI = 0.43, 16.0
    q, F, M = -3.6, -12.0, -2.5
    x = np.linspace(0, L, 40001)
    # bending moment at x from the loads beyond x (positive = sagging-free convention of w'')
    moment = q * (L - x) ** 2 / 2 + F * (L - x) + M
    slope = cumulative_trapezoid(moment / EI, x, initial=0.0)
    w = cumulative_trapezoid(slope, x, initial=0.0)
    w_f, s_f, k_f = cantilever_static(x, L, EI, q_N_m=q, tip_force_N=F, tip_moment_Nm=M)
    assert np.allclose(k_f, moment / EI)
    assert np.allclose(s_f, slope, atol=1e-8)
    assert np.allclose(w_f, w, atol=1e-8)


def test_modal_static_coordinates_reproduce_static_shape():
    B = modal_basis(P.link2, 1.2, 0.1, 6)
    loads = (-3.6, -12.0, -2.5)
    eta = B.static_coordinates(*loads)
    x = np.linspace(0, B.length_m, 50)
    w_modal = eta @ B.shape(x)
    w, _, _ = cantilever_static(x, B.length_m, B.flexural_rigidity_Nm2, q_N_m=loads[0],
                                tip_force_N=loads[1], tip_moment_Nm=loads[2])
    assert np.max(np.abs(w_modal - w)) < 2e-3 * np.max(np.abs(w))
    # mass-weighted projection of the static shape equals generalized force / omega^2
    xx = np.linspace(0, B.length_m, 20001)
    ws, ss, _ = cantilever_static(xx, B.length_m, B.flexural_rigidity_Nm2, q_N_m=loads[0],
                                  tip_force_N=loads[1], tip_moment_Nm=loads[2])
    phi = B.shape(xx)
    proj = (B.rho_kg_m * np.trapezoid(phi * ws, xx, axis=1) + B.tip_mass_kg * phi[:, -1] * ws[-1]
            + B.tip_inertia_kg_m2 * B.shape([B.length_m], 1)[:, 0] * ss[-1])
    assert np.allclose(proj, eta, rtol=1e-5, atol=1e-9)


def test_participation_factors_are_complete():
    """Sum of Gamma_r^2 over many modes tends to the rigid inertia about the hub."""
    B = modal_basis(P.link3, 0.3, 1.6e-4, 8)
    rho, L = B.rho_kg_m, B.length_m
    I_rigid = rho * L**3 / 3 + B.tip_mass_kg * L**2 + B.tip_inertia_kg_m2
    m_rigid = rho * L + B.tip_mass_kg
    assert abs(np.sum(B.rotation_participation**2) / I_rigid - 1) < 1e-3
    # translation of a clamped hub converges slowly (tail ~ 1/r^2) but monotonically
    short = modal_basis(P.link3, 0.3, 1.6e-4, 4)
    gap8 = 1 - np.sum(B.translation_participation**2) / m_rigid
    gap4 = 1 - np.sum(short.translation_participation**2) / m_rigid
    assert 0 < gap8 < gap4 < 0.06


def _link2_tip_load(payload_kg):
    """Tip load of link 2: actuator 3, link 3, mount + payload (inertia about the tip axis)."""
    rho3, l3 = link_rho(P.link3), float(P.link3.length_m)
    mP = P.end_effector_mount_mass_kg + payload_kg
    IP = payload_kg * 0.08**2 / 12
    mL = float(P.actuator_mass_kg[2]) + rho3 * l3 + mP
    IL = 7.5e-5 + rho3 * l3**3 / 3 + mP * l3**2 + IP
    return mL, IL


@pytest.mark.parametrize("payload_kg", [0.0, 0.1, 0.3, 0.6])
def test_link2_frequencies_in_seed_range(payload_kg):
    B = modal_basis(P.link2, *_link2_tip_load(payload_kg), 2)
    f1, f2 = B.frequency_hz
    assert 2.0 <= f1 <= 4.5          # section 4.5: 2.2 .. 4.5 Hz for 0 .. 600 g
    assert 7.5 <= f2 <= 22.0         # second around 10 Hz (8.6 .. 21.8 Hz theoretical)


def test_link2_frequencies_fall_with_payload():
    f = np.array([modal_basis(P.link2, *_link2_tip_load(m), 2).frequency_hz for m in (0, .2, .4, .6)])
    assert np.all(np.diff(f, axis=0) < 0)
    assert 8.5 <= modal_basis(P.link2, *_link2_tip_load(0.3), 2).frequency_hz[1] <= 11.5


def test_surface_strain_sign():
    _, _, k = cantilever_static(0.0, 0.43, 16.0, tip_force_N=-10.0)
    assert surface_strain(k, 0.004) > 0       # sagging horizontal blade: top surface in tension


def test_bad_arguments_raise():
    with pytest.raises(ValueError, match="mass_ratio"):
        tip_load_roots(2, -1.0, 0.0)
    with pytest.raises(ValueError, match="n_roots"):
        tip_load_roots(0, 0.0, 0.0)
    with pytest.raises(ValueError, match="tip load"):
        modal_basis(P.link2, -0.1, 0.0)
    with pytest.raises(ValueError, match="derivative"):
        modal_basis(P.link2, 0.1, 0.0).shape([0.1], 4)


def test_shape_at_one_point_is_shape_and_read_only():
    """The arm's probes read the mode shapes at fixed points through ``shape_at``: the same numbers, remembered."""
    p = load_robot_params()
    b = modal_basis(p.link3, 0.2, 1e-3)
    for x in (0.0, 0.17, p.link3.length_m):
        row = b.shape_at(x)
        np.testing.assert_array_equal(row, b.shape([x])[:, 0])
        assert b.shape_at(x) is row                       # remembered
        with pytest.raises(ValueError):
            row[0] = 1.0                                  # a shared row cannot be changed by a caller
