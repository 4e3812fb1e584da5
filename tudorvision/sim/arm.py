"""The simulated elastic TUDOR arm (the plant): joints, elastic links, payload and contacts at 2 kHz.

:class:`ElasticArm` integrates the model of :mod:`tudorvision.sim.model`
(assumptions in :data:`~tudorvision.sim.model.ASSUMPTIONS`); each elastic
link's modes are a :class:`~tudorvision.sim.link_modes.LinkModes`. The arm
implements the joint layer's :class:`~tudorvision.joint.plant.Plant`
protocol: amplifier voltages in, encoder and strain-gauge readings out.

Frames and signs: joint angles and the base frame follow
:mod:`tudorvision.robot.kinematics`; link deflections and strains follow
:mod:`tudorvision.sim.beam` (deflection toward increasing joint angle,
top-surface strain positive in tension).
"""
from __future__ import annotations

import math
import random

import numpy as np

from .._checks import check_vector
from ..robot.actuators import motor_gain
from ..robot.params import RobotParams, load_robot_params
from .beam import cantilever_static, modal_basis
from .joint_compliance import HubCompliance
from .mode_analysis import held_joint_modes
from .link_modes import LinkModes
from .model import (ASSUMPTIONS, ArmBodies, Payload, PlantConfig, SimLog, SpringDamperObstacle, arm_bodies,
                    bias_torques, coupled_mass_matrix, fk_elastic, link_static_loads, mass_matrix, rigid_energy,
                    spheres_from_T, zero_config_inertia)

__all__ = [
    "ASSUMPTIONS", "PlantConfig", "Payload", "ArmBodies", "arm_bodies", "mass_matrix",
    "bias_torques", "rigid_energy", "link_static_loads", "SpringDamperObstacle", "ElasticArm",
    "SimLog", "fk_elastic", "spheres_from_T", "zero_config_inertia",
]


class ElasticArm:
    """State of the simulated arm; advance it with :meth:`step` at ``config.dt``.

    Parameters
    ----------
    theta0 : array_like, shape (3,)
        Initial joint angles, radians; the arm starts at rest in static equilibrium.
    payload : Payload, optional
        Default: mount plus the eye-in-hand camera with the tracking spheres.
    params : RobotParams, optional
        Robot parameters; default the packaged ``tudor.yaml``.
    config : PlantConfig, optional
        Options of the simulated arm (step, bending modes, gravity, friction,
        encoder and strain noise).
    obstacles : sequence of SpringDamperObstacle, optional
        Contact obstacles in the base frame (they switch on the two-way
        coupling unless ``config.two_way`` says otherwise).

    Raises
    ------
    ValueError
        If ``config.dt`` is not positive, ``config.n_modes < 1`` or ``theta0``
        is not three finite angles.

    Attributes
    ----------
    t : float
        Simulated time, seconds.
    theta, dtheta, ddtheta : list of 3 floats
        Joint angles (rad), velocities (rad/s), accelerations of the last step (rad/s^2).
    tau : list of 3 floats
        Electrical torques ``tau_E`` applied in the last step, N m.
    strain : list of 4 floats
        Top-surface strains at the gauges (link 2 near, far; link 3 near, far), m/m.
    tip2, tip3 : list of 2 floats
        Tip deflection (m) and slope (rad) of links 2 and 3.
    contact_force : list of 3 floats
        Total obstacle force on the arm, N, base frame.

    Notes
    -----
    The state attributes are read after each step; they are Python lists for speed.

    Examples
    --------
    >>> arm = ElasticArm([0.0, 0.0, 0.0])
    >>> arm.tip2[0] < 0   # the horizontal arm sags
    True
    """

    def __init__(self, theta0, *, payload: Payload | None = None, params: RobotParams | None = None,
                 config: PlantConfig = PlantConfig(), obstacles=()):
        self.params = params or load_robot_params()
        self.config = config
        if not config.dt > 0 or config.n_modes < 1:
            raise ValueError(f"config: expected dt > 0 and n_modes >= 1, got {config.dt}, {config.n_modes}")
        p = self.params
        self.g = float(p.gravity_m_s2) if config.gravity else 0.0
        self.kM = [float(x) for x in motor_gain(p)]
        self.tau_max = [float(x) for x in p.max_intermittent_torque_Nm]
        n = np.asarray(p.gear_ratio, float)
        self._kvp = [float(x) for x in n**2 * p.viscous_pos_Nms_rad]
        self._kvn = [float(x) for x in n**2 * p.viscous_neg_Nms_rad]
        cf = 1.0 if config.coulomb_friction else 0.0
        self._kcp = [cf * float(x) for x in n * p.coulomb_pos_Nm]
        self._kcn = [cf * float(x) for x in n * p.coulomb_neg_Nm]
        if config.encoder_counts_per_rev:
            self._quant = [float(2 * np.pi / (config.encoder_counts_per_rev * nj)) for nj in n]
        else:
            self._quant = None
        self._noise = random.Random(config.noise_seed)
        self.hub = HubCompliance(config.hub_stiffness_Nm_rad, config.hub_damping_Nms_rad, config.backlash_rad)
        self._hub_m = [0.0, 0.0]     # backlash/damper moment on the link roots (explicit, previous step)
        self.obstacles = tuple(obstacles)
        self._two_way = bool(self.obstacles) if config.two_way is None else bool(config.two_way)
        th = check_vector(theta0, "theta0", 3)
        self.t = 0.0
        self.theta = [float(x) for x in th]
        self.dtheta = [0.0, 0.0, 0.0]
        self.ddtheta = [0.0, 0.0, 0.0]
        self.tau = [0.0, 0.0, 0.0]
        self.contact_force = [0.0, 0.0, 0.0]
        self._in_contact = False
        self._contact_tau = [0.0, 0.0, 0.0]
        self._contact_q = ([], [])
        self._probe_prev = None
        self.payload = payload or Payload.from_parts(p, camera=True)
        self._build(self.payload)
        n_m = config.n_modes
        self.eta2, self.deta2 = [0.0] * n_m, [0.0] * n_m
        self.eta3, self.deta3 = [0.0] * n_m, [0.0] * n_m
        self._eta_acc_prev = ([0.0] * n_m, [0.0] * n_m)
        self._settle()
        self._outputs()

    # -- model set-up -------------------------------------------------------------------------
    def _build(self, payload: Payload) -> None:
        p, cfg = self.params, self.config
        self._build_id = getattr(self, "_build_id", 0) + 1
        self._mass_cache = None
        b = arm_bodies(p, payload, cfg)
        self.bodies = b
        zeta = cfg.modal_damping_ratio or tuple(float(z) for z in p.modal_damping_ratio)
        mL2 = b.mA + b.m3 + b.mP
        IL2 = b.IA + b.J3                         # distal inertia about the link-2 tip axis
        basis2 = modal_basis(p.link2, mL2, IL2, cfg.n_modes, cfg.hub_stiffness_Nm_rad[0])
        basis3 = modal_basis(p.link3, b.mP, b.IP, cfg.n_modes, cfg.hub_stiffness_Nm_rad[1])
        g2 = p.gauge_positions_m["link2"]
        g3 = p.gauge_positions_m["link3"]
        self.link2 = k2 = LinkModes(basis2, g2, zeta, cfg.dt)
        self.link3 = k3 = LinkModes(basis3, g3, zeta, cfg.dt)
        # constant and cos(theta3) parts of the coupling terms (see _coupling)
        self._kc = {
            "c2_t2": k2.gamma,
            "c2_t3": [(b.J3 * k2.dphiL[r], b.s3 * k2.phiL[r]) for r in range(k2.n)],
            "c3_t2": [(k3.gamma[q], k3.pi[q] * b.l2) for q in range(k3.n)],
            "c3_t3": k3.gamma,
            "E": [[(k3.gamma[q] * k2.dphiL[r], k3.pi[q] * k2.phiL[r]) for q in range(k3.n)]
                  for r in range(k2.n)],
        }

    def _loads(self):
        th, b, g = self.theta, self.bodies, self.g
        ca, cb = math.cos(th[1]), math.cos(th[1] + th[2])
        hm = self._hub_m
        l2 = (-(b.m2 / b.l2) * g * ca, -(b.mA + b.m3 + b.mP) * g * ca, -g * b.s3 * cb, hm[0])
        l3 = (-(b.m3 / b.l3) * g * cb, -b.mP * g * cb, 0.0, hm[1])
        return l2, l3

    def _settle(self) -> None:
        """Put the modal coordinates at the static equilibrium of the current configuration."""
        if not self.config.elastic:
            return
        self._hub_m = [0.0, 0.0]
        l2, l3 = self._loads()
        if self.hub.nonlinear:      # at rest against the side of the gap the load pushes to
            self._hub_m = [self.hub.static_moment(j, ld[0] * lm.L**2 / 2 + ld[1] * lm.L + ld[2])
                           for j, (ld, lm) in enumerate(((l2, self.link2), (l3, self.link3)))]
            l2, l3 = self._loads()
        for lm, eta, deta, loads in ((self.link2, self.eta2, self.deta2, l2),
                                     (self.link3, self.eta3, self.deta3, l3)):
            f = lm.generalised_force(*loads)
            for r in range(lm.n):
                eta[r] = f[r] / lm.om2[r]
                deta[r] = 0.0

    @property
    def dt(self) -> float:
        """Plant step, seconds (``config.dt``, 0.5 ms: the joint layer's 2 kHz)."""
        return self.config.dt

    @property
    def two_way(self) -> bool:
        """Whether joints and link modes are coupled both ways (contacts or ``config.two_way``)."""
        return self._two_way

    @property
    def gain_set(self) -> str:
        """Which tuned damping gains fit this plant: ``"soft"`` (hub springs), ``"two-way"`` or ``"one-way"``."""
        if self.hub.active:
            return "soft"
        return "two-way" if self._two_way else "one-way"

    @property
    def payload_kg(self) -> float:
        """Current payload mass at the end effector, kg."""
        return float(self.payload.mass_kg)

    def design_inertia_kg_m2(self) -> np.ndarray:
        """Joint inertias at the zero configuration, kg m^2, shape (3,): the cascade's design point.

        Returns
        -------
        ndarray, shape (3,)
            Inertia seen by each joint at the gear output, kg m^2.
        """
        return zero_config_inertia(self)

    def reset_at_rest(self, theta) -> None:
        """Put the arm at rest in static equilibrium at ``theta`` (rad, shape (3,)), as the constructor does.

        Time, payload and obstacles are kept; joint velocities and modal rates are zeroed and the
        link shapes set to the static deflection of the new configuration.

        Parameters
        ----------
        theta : array_like, shape (3,)
            Joint angles, rad.

        Raises
        ------
        ValueError
            If ``theta`` is not three finite angles.
        """
        th = check_vector(theta, "theta", 3)
        self.theta = [float(x) for x in th]
        self.dtheta = [0.0, 0.0, 0.0]
        for lst in (self.deta2, self.deta3):
            lst[:] = [0.0] * len(lst)
        self._settle()
        self._outputs()

    def set_payload(self, payload: Payload) -> None:
        """Change the payload (e.g. a caught ball) keeping the current link shapes.

        The deflection and its rate are projected onto the new modes, so the
        links start to oscillate about the new static equilibrium.

        Parameters
        ----------
        payload : Payload
            New end-effector payload (mass, kg, and inertia, kg m^2).
        """
        old2, old3 = self.link2, self.link3
        shapes = []
        if self.config.elastic:
            l2, l3 = self._loads()
            for lm, eta, deta, loads in ((old2, self.eta2, self.deta2, l2),
                                         (old3, self.eta3, self.deta3, l3)):
                shapes.append(lm.shape_on_grid(eta, deta, loads))
        self.payload = payload
        self._build(payload)
        self._eta_acc_prev = ([0.0] * self.link2.n, [0.0] * self.link3.n)
        if self.config.elastic:
            for lm, (xg, wg, w, dw, wL, sL, vL, svL), eta, deta in zip(
                    (self.link2, self.link3), shapes, (self.eta2, self.eta3), (self.deta2, self.deta3)):
                B = lm.basis
                phi = B.shape(xg)
                rho = B.rho_kg_m
                eta[:] = [float(v) for v in rho * phi @ (wg * w) + B.tip_mass_kg * np.array(lm.phiL) * wL
                          + B.tip_inertia_kg_m2 * np.array(lm.dphiL) * sL]
                deta[:] = [float(v) for v in rho * phi @ (wg * dw) + B.tip_mass_kg * np.array(lm.phiL) * vL
                           + B.tip_inertia_kg_m2 * np.array(lm.dphiL) * svL]
        self._outputs()

    # -- sensors --------------------------------------------------------------------------------
    def measured_theta(self) -> list:
        """Encoder readings (quantised joint angles), radians.

        Returns
        -------
        list of 3 floats
            Joint angles quantised to the encoder resolution (exact without
            ``config.encoder_counts_per_rev``), rad.
        """
        if self._quant is None:
            return list(self.theta)
        return [round(self.theta[j] / self._quant[j]) * self._quant[j] for j in range(3)]

    def measured_strain(self) -> list:
        """Gauge readings: :attr:`strain` plus white noise of ``config.strain_noise_m_m``, m/m.

        Returns
        -------
        list of 4 floats
            Strains at the gauges (link 2 near, far; link 3 near, far), m/m.
        """
        sd = self.config.strain_noise_m_m
        if not sd:
            return list(self.strain)
        g = self._noise.gauss
        return [x + g(0.0, sd) for x in self.strain]

    def T_base_ee(self) -> np.ndarray:
        """Current deflected end-effector pose, shape (4, 4).

        Returns
        -------
        T_base_ee : ndarray, shape (4, 4)
            Homogeneous end-effector pose, ``p_base = T_base_ee @ p_ee``, metres.
        """
        return fk_elastic(self.theta, self.tip2, self.tip3, self.params)

    def ee_position(self) -> np.ndarray:
        """Current deflected end-effector position, metres, base frame.

        Returns
        -------
        p_base : ndarray, shape (3,)
            End-effector position, metres, base frame.
        """
        return self.T_base_ee()[:3, 3]

    def sphere_positions(self) -> dict:
        """Current tracking-sphere centres ``{"red": (3,), "green": (3,)}``, base frame.

        Returns
        -------
        dict of str to ndarray, shape (3,)
            Sphere centre per colour, metres, base frame.
        """
        return spheres_from_T(self.T_base_ee(), self.params)

    # -- dynamics -------------------------------------------------------------------------------
    def step(self, v_M) -> None:
        """Advance one step ``config.dt`` with amplifier input voltages ``v_M`` (3 floats).

        Parameters
        ----------
        v_M : sequence of 3 floats
            Amplifier input voltages, volts (the torque ``k_M v_M`` saturates
            at the intermittent torque limit).
        """
        dt = self.config.dt
        b = self.bodies
        th, dth = self.theta, self.dtheta
        tau = [0.0, 0.0, 0.0]
        for j in range(3):
            tj = self.kM[j] * v_M[j]
            lim = self.tau_max[j]
            tau[j] = lim if tj > lim else (-lim if tj < -lim else tj)
        self.tau = tau
        t2, t3 = th[1], th[2]
        ca, sa = math.cos(t2), math.sin(t2)
        cb, sb = math.cos(t2 + t3), math.sin(t2 + t3)
        c3, s3_ = math.cos(t3), math.sin(t3)
        l2, l3 = b.l2, b.l3
        # joint-1 inertia and its partials (see _m11_and_partials)
        rA = l2 * ca
        rP = rA + l3 * cb
        f = (b.I_base + b.m2 * l2 * l2 * ca * ca / 3 + b.mA * rA * rA
             + b.m3 * (rA * rA + rA * l3 * cb + l3 * l3 * cb * cb / 3) + b.mP * rP * rP)
        drA2 = -l2 * sa
        f2 = (-2 * b.m2 * l2 * l2 * ca * sa / 3 + 2 * b.mA * rA * drA2
              + b.m3 * (2 * rA * drA2 + drA2 * l3 * cb - rA * l3 * sb - 2 * l3 * l3 * cb * sb / 3)
              + 2 * b.mP * rP * (drA2 - l3 * sb))
        f3 = b.m3 * (-rA * l3 * sb - 2 * l3 * l3 * cb * sb / 3) - 2 * b.mP * rP * l3 * sb
        d1, d2, d3 = dth
        J3, s3 = b.J3, b.s3
        h = l2 * s3 * s3_
        g = self.g
        bias1 = (f2 * d2 + f3 * d3) * d1
        bias2 = -h * (2 * d2 * d3 + d3 * d3) - 0.5 * f2 * d1 * d1 + g * (b.s2 * ca + s3 * cb)
        bias3 = h * d2 * d2 - 0.5 * f3 * d1 * d1 + g * s3 * cb
        rhs = [tau[0] - bias1, tau[1] - bias2, tau[2] - bias3]
        for j in range(3):          # viscous friction, explicit
            v = dth[j]
            rhs[j] -= (self._kvp[j] if v > 0 else self._kvn[j]) * v
        if self._in_contact:
            for j in range(3):
                rhs[j] += self._contact_tau[j]
        m11 = f + b.rotor[0]
        m22 = b.J2 + J3 + 2 * l2 * s3 * c3 + b.rotor[1]
        m23 = J3 + l2 * s3 * c3
        m33 = J3 + b.rotor[2]
        elastic = self.config.elastic
        self._c3 = c3
        if elastic:
            loads = self._loads()
            gforces = (self.link2.generalised_force(*loads[0]), self.link3.generalised_force(*loads[1]))
            coupling = self._coupling(c3)
        if elastic and self._two_way:
            acc, self._eta_acc = self._coupled_accelerations(m22, m23, m33, rhs, gforces, coupling)
            acc.insert(0, rhs[0] / m11)
        else:
            det = m22 * m33 - m23 * m23
            acc = [rhs[0] / m11, (m33 * rhs[1] - m23 * rhs[2]) / det, (m22 * rhs[2] - m23 * rhs[1]) / det]
            self._eta_acc = None
        mdiag = (m11, m22, m33)
        for j in range(3):          # Coulomb friction with sticking
            v_old = dth[j]
            vt = v_old + acc[j] * dt
            if vt > 0:
                dv = self._kcp[j] * dt / mdiag[j]
                v_new = vt - dv if vt > dv else 0.0
            elif vt < 0:
                dv = self._kcn[j] * dt / mdiag[j]
                v_new = vt + dv if -vt > dv else 0.0
            else:
                v_new = 0.0
            self.ddtheta[j] = (v_new - v_old) / dt
            dth[j] = v_new
            th[j] += v_new * dt
        self.t += dt
        if elastic:
            if self._eta_acc is not None:
                if abs(self.ddtheta[1] - acc[1]) > 1e-12 or abs(self.ddtheta[2] - acc[2]) > 1e-12:
                    # friction changed the joint motion: the modes follow the actual joints
                    self._eta_acc = self._modal_accelerations(self.ddtheta[1], self.ddtheta[2])
                for eta, deta, a1, a0 in ((self.eta2, self.deta2, self._eta_acc[0], self._eta_acc_prev[0]),
                                          (self.eta3, self.deta3, self._eta_acc[1], self._eta_acc_prev[1])):
                    for r in range(len(eta)):
                        eta[r] += dt * deta[r] + 0.25 * dt * dt * (a0[r] + a1[r])
                        deta[r] += 0.5 * dt * (a0[r] + a1[r])
                self._eta_acc_prev = (list(self._eta_acc[0]), list(self._eta_acc[1]))
            else:
                self._step_modes(loads, gforces, coupling)
            self._outputs(loads, gforces)
        else:
            self._outputs()
        if self.obstacles:
            self._contact()

    def _coupling(self, c3: float):
        """Mass-matrix coupling terms at the current elbow angle.

        Returns ``(c2_t2, c2_t3, c3_t2, c3_t3, E)``: couplings of the link-2
        modes with theta2 and theta3, of the link-3 modes with theta2 and theta3,
        and ``E[r][s]`` between link-2 mode r and link-3 mode s.
        """
        k = self._kc
        c2_t3 = [a + b * c3 for a, b in k["c2_t3"]]
        c3_t2 = [a + b * c3 for a, b in k["c3_t2"]]
        E = [[a + b * c3 for a, b in row] for row in k["E"]]
        return k["c2_t2"], c2_t3, c3_t2, k["c3_t3"], E

    def _coupled_accelerations(self, m22, m23, m33, rhs, gforces, coupling, h=None):
        """Assumed-modes equations of joints 2, 3 and all modes (two-way coupling).

        The mass matrix is the exact kinetic energy of the lumped bodies with the
        BVP mode shapes as Ritz functions: beyond the BVP's tip mass and tip
        inertia it contains the first moment ``s3`` of the distal body about
        joint 3, which couples tip deflection and tip slope of link 2.
        """
        b, k2, k3 = self.bodies, self.link2, self.link3
        n2, n3 = k2.n, k3.n
        h = self.config.dt if h is None else h
        # M depends on the pose only through theta3: reuse it (and its inverse) while
        # theta3 stays within 1e-4 rad
        key = (self._build_id, h, round(self.theta[2] * 1e4))
        cache = self._mass_cache
        if cache is None or cache[0] != key:
            M = coupled_mass_matrix(m22, m23, m33, coupling, b, k2, k3, self._c3)
            for k, lm in ((0, k2), (1, k3)):
                off = 2 + (0 if k == 0 else n2)
                for i in range(lm.n):
                    M[off + i, off + i] += 0.5 * h * lm.cdamp[i] + 0.25 * h * h * lm.om2[i]
            cache = self._mass_cache = (key, M, np.linalg.inv(M), np.linalg.inv(M[2:, 2:]))
        M, Minv = cache[1], cache[2]
        qc2, qc3 = self._contact_q if self._in_contact else ([0.0] * n2, [0.0] * n3)
        # Newmark average acceleration on the modal stiffness and damping (unconditionally
        # stable, no numerical damping): solve for the end-of-step accelerations
        a0 = self._eta_acc_prev
        r_ = [rhs[1], rhs[2]]
        for k, lm, eta, deta, qg, qc in ((0, k2, self.eta2, self.deta2, gforces[0], qc2),
                                         (1, k3, self.eta3, self.deta3, gforces[1], qc3)):
            off = 2 + (0 if k == 0 else n2)
            for i in range(lm.n):
                a_prev = a0[k][i]
                x_pred = eta[i] + h * deta[i] + 0.25 * h * h * a_prev
                v_pred = deta[i] + 0.5 * h * a_prev
                r_.append(qg[i] + qc[i] - lm.om2[i] * x_pred - lm.cdamp[i] * v_pred)
        sol = (Minv @ np.asarray(r_)).tolist()
        self._coupled_system = (M, r_)
        return sol[:2], (sol[2:2 + n2], sol[2 + n2:])

    def coupled_frequencies_hz(self) -> np.ndarray:
        """Natural frequencies of the coupled links with the joints held, at the current pose.

        Generalised eigenvalues of the modal block of the assumed-modes mass
        matrix (two-way model) and the modal stiffness ``diag(omega_r^2)``
        (:func:`tudorvision.sim.mode_analysis.held_joint_modes`; hub springs
        engaged). Unlike the BVP values they depend on theta3 (first moment of
        the distal bodies) and include the flexibility of link 3.

        Returns
        -------
        ndarray, shape (2 n_modes,)
            Increasing, Hz.
        """
        return held_joint_modes(self)[0]

    def _modal_accelerations(self, a2: float, a3: float):
        """Modal accelerations for given joint accelerations (after friction sticking)."""
        M, r_ = self._coupled_system
        n2 = self.link2.n
        rhs = np.asarray(r_[2:]) - M[2:, 0] * a2 - M[2:, 1] * a3
        sol = (self._mass_cache[3] @ rhs).tolist()
        return sol[:n2], sol[n2:]

    def _step_modes(self, loads, gforces, coupling):
        """Advance the modal coordinates exactly (zero-order hold of their forcing)."""
        a2, a3 = self.ddtheta[1], self.ddtheta[2]
        c2_t2, c2_t3, c3_t2, c3_t3, E = coupling
        f2g, f3g = gforces
        b, k2, k3 = self.bodies, self.link2, self.link3
        contact = self._in_contact
        if contact:
            q2c, q3c = self._contact_q
        if self._eta_acc is not None:
            e2acc, e3acc = self._eta_acc
        else:
            e2acc, e3acc = None, [0.0] * k3.n
        # link 2: hub rotation theta2, joint-3 reaction and link-3 vibration at the tip
        new2 = []
        for r in range(k2.n):
            u = f2g[r] - c2_t2[r] * a2 - c2_t3[r] * a3
            for s_ in range(k3.n):
                u -= E[r][s_] * e3acc[s_]
            if contact:
                u += q2c[r]
            new2.append(k2.zoh_step(r, self.eta2, self.deta2, u, self.config.dt))
        if e2acc is None:          # one-way: link 3 sees link 2's average modal acceleration
            e2acc = [acc for acc in new2]
        # link 3: hub rotation theta2 + theta3 + link-2 tip slope, hub translation
        for s_ in range(k3.n):
            u = f3g[s_] - c3_t2[s_] * a2 - c3_t3[s_] * a3
            for r in range(k2.n):
                u -= E[r][s_] * e2acc[r]
            if contact:
                u += q3c[s_]
            k3.zoh_step(s_, self.eta3, self.deta3, u, self.config.dt)

    def _outputs(self, loads=None, forces=None) -> None:
        if not self.config.elastic:
            self.strain = [0.0, 0.0, 0.0, 0.0]
            self.tip2, self.tip3 = [0.0, 0.0], [0.0, 0.0]
            return
        if loads is None:
            loads = self._loads()
            forces = (self.link2.generalised_force(*loads[0]), self.link3.generalised_force(*loads[1]))
        strain = []
        tips = []
        hub = self.hub
        for j, (lm, eta, (q, P, M, Mh), f) in enumerate(((self.link2, self.eta2, loads[0], forces[0]),
                                                         (self.link3, self.eta3, loads[1], forces[1]))):
            L, EI = lm.L, lm.EI
            wL = (q * L**4 / 8.0 + P * L**3 / 3.0 + M * L**2 / 2.0) / EI
            sL = (q * L**3 / 6.0 + P * L**2 / 2.0 + M * L) / EI
            nu = [eta[r] - f[r] / lm.om2[r] for r in range(lm.n)]
            if hub.active:          # rigid rotation on the hub spring; backlash/damper moment for the next step
                ph = (q * L * L / 2.0 + P * L + M + Mh) * lm.kinv
                wL += L * ph
                sL += ph
                if hub.nonlinear:
                    deta = self.deta2 if j == 0 else self.deta3
                    phi = ph + sum(lm.dphi0[r] * nu[r] for r in range(lm.n))
                    self._hub_m[j] = hub.moment(j, phi, sum(lm.dphi0[r] * deta[r] for r in range(lm.n)))
            for k, x in enumerate(lm.gauges):
                c = (q * (L - x) ** 2 / 2.0 + P * (L - x) + M) / EI
                row = lm.ddphi_g[k]
                for r in range(lm.n):
                    c += row[r] * nu[r]
                strain.append(-0.5 * lm.h * c)
            for r in range(lm.n):
                wL += lm.phiL[r] * nu[r]
                sL += lm.dphiL[r] * nu[r]
            tips.append([wL, sL])
        self.strain = strain
        self.tip2, self.tip3 = tips

    def _probe_position(self, link: int, x: float) -> np.ndarray:
        """Deflected position of the point ``x`` metres along ``link`` (2 or 3), base frame."""
        th = self.theta
        lm = self.link2 if link == 2 else self.link3
        loads = self._loads()[0 if link == 2 else 1]
        ws, _, _ = cantilever_static(x, lm.L, lm.EI, q_N_m=loads[0], tip_force_N=loads[1],
                                     tip_moment_Nm=loads[2])
        ws = ws + x * lm.static_hub_angle(*loads)
        eta = self.eta2 if link == 2 else self.eta3
        nu = np.asarray(eta) - lm.basis.static_coordinates(*loads)
        w = float(ws) + float(nu @ lm.basis.shape_at(x)) if self.config.elastic else 0.0
        a = th[1]
        if link == 2:
            r = x * math.cos(a) - w * math.sin(a)
            z = x * math.sin(a) + w * math.cos(a)
        else:
            l2 = self.bodies.l2
            w2, s2 = self.tip2
            bb = a + th[2] + s2
            r = l2 * math.cos(a) - w2 * math.sin(a) + x * math.cos(bb) - w * math.sin(bb)
            z = l2 * math.sin(a) + w2 * math.cos(a) + x * math.sin(bb) + w * math.cos(bb)
        return np.array([r * math.cos(th[0]), r * math.sin(th[0]), self.bodies.h1 + z])

    def _contact(self) -> None:
        """Obstacle forces, their joint torques (rigid point Jacobians) and modal forces."""
        dt = self.config.dt
        th = self.theta
        b = self.bodies
        t1, a, bb = th[0], th[1], th[1] + th[2]
        total = np.zeros(3)
        tau = np.zeros(3)
        q2 = np.zeros(self.link2.n)
        q3 = np.zeros(self.link3.n)
        any_force = False
        if self._probe_prev is None:
            self._probe_prev = [None] * len(self.obstacles)
        for i, ob in enumerate(self.obstacles):
            x = ob.probe_x_m if ob.probe_x_m is not None else (b.l2 if ob.probe_link == 2 else b.l3)
            p = self._probe_position(ob.probe_link, x)
            prev = self._probe_prev[i]
            v = np.zeros(3) if prev is None else (p - prev) / dt
            self._probe_prev[i] = p
            F = ob.force(p, v)
            if not F.any():
                continue
            any_force = True
            total += F
            c1, s1 = math.cos(t1), math.sin(t1)
            e_t = np.array([-s1, c1, 0.0])
            ey2 = np.array([-math.sin(a) * c1, -math.sin(a) * s1, math.cos(a)])
            if ob.probe_link == 2:
                r = x * math.cos(a)
                J = np.stack([r * e_t, x * ey2, np.zeros(3)], axis=1)
                q2 += self.link2.basis.shape_at(x) * float(F @ ey2)
            else:
                r = b.l2 * math.cos(a) + x * math.cos(bb)
                ey3 = np.array([-math.sin(bb) * c1, -math.sin(bb) * s1, math.cos(bb)])
                J = np.stack([r * e_t, b.l2 * ey2 + x * ey3, x * ey3], axis=1)
                fy3 = float(F @ ey3)
                q3 += self.link3.basis.shape_at(x) * fy3
                q2 += np.asarray(self.link2.phiL) * float(F @ ey2) + np.asarray(self.link2.dphiL) * x * fy3
            tau += J.T @ F
        self.contact_force = [float(v) for v in total]
        self._in_contact = any_force
        self._contact_tau = [float(v) for v in tau]
        self._contact_q = ([float(v) for v in q2], [float(v) for v in q3])

