"""Damping and collision modes switched through the adapter act on the simulated core (SimCore.set_modes)."""
from __future__ import annotations

import numpy as np
import pytest

from tudorvision.joint import (Ack, CollisionMonitor, CollisionStrategy, Damping, DampingConfig, InProcessTransport,
                               JointAdapter, JointLayerServer, LockstepClientTransport, Mode, MomentumObserver,
                               StateFlags, StrainDamper, fit_strain_dynamics)
from tudorvision.joint.collision import thresholds_from_residuals
from tudorvision.joint.damping import ONE_WAY_GAINS, PD_SCALES
from tudorvision.joint.strain_dynamics import aprbs, derivatives
from tudorvision.joint.server import ServerConfig
from tudorvision.robot import load_robot_params
from tudorvision.sim.arm import ElasticArm, Payload, PlantConfig, SpringDamperObstacle
from tudorvision.joint.controlled import ControlledArm
from tudorvision.lab.simulation import SimCore

DT = 1.0 / 500.0
DEG = np.pi / 180.0
P = load_robot_params()


def _lockstep(core):
    client_end, server_end = InProcessTransport.pair()
    server = JointLayerServer(server_end, core, config=ServerConfig(rate_hz=1.0 / DT))
    return server, JointAdapter(LockstepClientTransport(client_end, server))


def _run(server, seconds, probe=None):
    out = []
    for _ in range(int(round(seconds / DT))):
        server.tick(DT)
        if probe is not None:
            out.append(probe())
    return out


def _oscillation_after_move(damping):
    """Peak-to-peak link-2 root strain 3-4.5 s after the command of a 45 deg move (experiment 06, 300 g)."""
    core = SimCore(np.zeros(3), payload=Payload.from_parts(P, plates=3), params=P,
                   config=PlantConfig.stiff(two_way=False))
    server, adapter = _lockstep(core)
    assert isinstance(adapter.set_mode(Mode.SETPOINT, damping=damping), Ack)
    assert isinstance(adapter.send_setpoint(np.array([0.0, 45.0, -45.0]) * DEG), Ack)
    _run(server, 3.0)
    eps = np.array(_run(server, 1.5, lambda: core.arm.strain[0]))
    st = adapter.request_state()
    return np.ptp(eps), core, st


def test_damping_modes_install_the_damper_and_damp():
    undamped, core0, st0 = _oscillation_after_move(Damping.OFF)
    assert core0.controlled.damper is None and st0.damping == Damping.OFF
    damped, core, st = _oscillation_after_move(Damping.PROPORTIONAL)
    d = core.controlled.damper
    assert isinstance(d, StrainDamper) and d.config.law == "proportional"
    assert d.config.k_eps == ONE_WAY_GAINS["proportional"] and st.damping == Damping.PROPORTIONAL
    assert damped < 0.4 * undamped                     # the damper acts on the plant
    np.testing.assert_allclose(st.theta, np.array([0.0, 45.0, -45.0]) * DEG, atol=0.02 * DEG)


def test_integral_law_halves_pd_gain_and_off_restores_it():
    core = SimCore(params=P)
    server, adapter = _lockstep(core)
    kpd0 = list(core.controlled.controller._kpd)
    adapter.set_mode(Mode.SETPOINT, damping=Damping.INTEGRAL)
    assert core.controlled.damper.config.law == "integral"
    # the soft plant's hold (1 / 3 ms): the integral law keeps the k_PD it was tuned with, half the 3 / 10 ms loop's
    np.testing.assert_allclose(core.controlled.controller._kpd, PD_SCALES["soft"]["integral"] * np.asarray(kpd0))
    np.testing.assert_allclose(core.controlled.controller._kpd, 0.5 * 0.25 / 0.01)
    first = core.controlled.damper
    adapter.set_mode(collision=CollisionStrategy.NONE)          # damping unchanged: the same damper stays
    assert core.controlled.damper is first
    adapter.set_mode(damping=Damping.OFF)
    assert core.controlled.damper is None
    np.testing.assert_allclose(core.controlled.controller._kpd, kpd0)
    with pytest.raises(ValueError, match="codes"):
        core.set_modes(damping=7, collision=0)


def test_collision_mode_without_model_warns_and_detects_nothing():
    core = SimCore(params=P)
    server, adapter = _lockstep(core)
    with pytest.warns(RuntimeWarning, match="collision_model"):
        adapter.set_mode(Mode.SETPOINT, collision=CollisionStrategy.STOP)
    assert core.controlled.reaction is None
    st = adapter.request_state()
    assert st.collision == CollisionStrategy.STOP and not st.flags & StateFlags.COLLISION
    with pytest.raises(ValueError, match="both or neither"):
        SimCore(params=P, collision_thresholds=[1e-4, 1e-4])


# ------------------------------------------------------------------ collision through the adapter
PLATES = 1
K_EPS = (0.0, 400.0, 1600.0)
START, GOAL = np.array([0.0, 45.0, -45.0]) * DEG, np.array([0.0, 150.0, 60.0]) * DEG


def _damped_arm(theta0, obstacles=()):
    arm = ElasticArm(theta0, payload=Payload.from_parts(P, plates=PLATES), params=P,
                     config=PlantConfig(two_way=True), obstacles=obstacles)
    ca = ControlledArm(arm)
    ca.set_damper(StrainDamper(DampingConfig(law="proportional", k_eps=K_EPS), arm.measured_strain(), arm.config.dt))
    return arm, ca


@pytest.fixture(scope="module")
def identified():
    """Strain dynamics identified on a short APRBS run (one payload, no noise) and 6-sigma thresholds."""
    rng = np.random.default_rng(3)
    times, levels = aprbs(rng, 16.0, [30 * DEG, -60 * DEG], [150 * DEG, 60 * DEG], hold_s=(0.8, 1.6))
    arm, ca = _damped_arm([0.0, levels[0, 0], levels[0, 1]])
    th, eps, dth = [], [], []
    nxt = 1
    n = int(round(times[-1] / arm.config.dt)) + 2000
    for k in range(n):
        if nxt < times.size and k * arm.config.dt >= times[nxt]:
            ca.set_goal([0.0, *levels[nxt]])
            nxt += 1
        ca.step()
        th.append(arm.measured_theta())
        eps.append((arm.strain[0], arm.strain[2]))
        dth.append(list(ca.controller.velocity))
    th, eps = np.asarray(th), np.asarray(eps)
    t = np.arange(n) * arm.config.dt
    d, dd = derivatives(t, th, window_s=0.04)
    half = n // 2
    sl = slice(200, half, 10)
    model = fit_strain_dynamics(th[sl], d[sl], dd[sl], eps[sl], arm.payload.mass_kg)
    obs = MomentumObserver(model, arm.payload.mass_kg, dt=arm.config.dt)    # DEFAULT_K_I, as SimCore's monitor
    res = np.array([obs.step(th[k], dth[k], eps[k]) for k in range(half, n)])[400:]   # held-out half
    return model, thresholds_from_residuals(res), arm.payload.mass_kg


def _obstacle_in_path():
    """A sphere where the end effector passes 0.6 s into the move (free run first)."""
    arm, ca = _damped_arm(START)
    ca.set_goal(GOAL)
    for _ in range(int(round(0.6 / arm.config.dt))):
        ca.step()
    p0 = arm._probe_position(3, arm.bodies.l3)
    ca.step()
    v = arm._probe_position(3, arm.bodies.l3) - p0
    centre = p0 + v / np.linalg.norm(v) * (0.05 + 0.02 + 0.002)
    return SpringDamperObstacle(kind="sphere", point_base=centre, radius_m=0.05, probe_link=3, probe_radius_m=0.02,
                                stiffness_N_m=5.0e3, damping_Ns_m=20.0)


def _contact_run(identified, strategy):
    model, thr, _ = identified
    core = SimCore(START, payload=Payload.from_parts(P, plates=PLATES), params=P, config=PlantConfig(two_way=True),
                   obstacles=(_obstacle_in_path(),), collision_model=model, collision_thresholds=thr)
    server, adapter = _lockstep(core)
    adapter.set_mode(Mode.SETPOINT, damping=Damping.PROPORTIONAL, collision=strategy)
    assert isinstance(core.controlled.reaction, CollisionMonitor)
    assert core.controlled.reaction.config.strategy == strategy.name.lower()
    adapter.send_setpoint(GOAL, max_speed=float(np.deg2rad(60.0)))
    force = _run(server, 1.5, lambda: float(np.linalg.norm(core.arm.contact_force)))
    return core, adapter.request_state(), np.asarray(force)


def test_stop_strategy_detects_isolates_and_stops(identified):
    core, st, force = _contact_run(identified, CollisionStrategy.STOP)
    mon = core.controlled.reaction
    assert force.max() > 0.0                                   # the arm did hit the obstacle
    assert st.flags & StateFlags.COLLISION and mon.collision and mon.isolated and mon.link == 3
    assert np.max(np.abs(st.residuals)) > 0.0
    assert np.all(np.abs(st.theta_dot) < 0.05)                 # stopped and holding
    _, st_none, force_none = _contact_run(identified, CollisionStrategy.NONE)
    assert st_none.flags & StateFlags.COLLISION                # detected and reported only
    assert force_none.max() > 0.0
    # without a reaction the arm pushes on past the sphere; the stop holds it near the contact
    assert st.theta[1] < st_none.theta[1] - 10.0 * DEG


# ------------------------------------------------------------ model-assisted static strain cancellation
def _identify_one_way(seconds=12.0, plates=(1, 3)):
    """Strain dynamics (10.2.8) of the one-way plant from short APRBS runs (assisted gains damp)."""
    from tudorvision.joint.damping import ASSISTED_GAINS
    rows = []
    for pl in plates:
        rng = np.random.default_rng(500 + pl)
        times, levels = aprbs(rng, seconds, np.deg2rad([-5.0, -60.0]), np.deg2rad([185.0, 60.0]))
        arm = ElasticArm([0.0, levels[0, 0], levels[0, 1]], payload=Payload.from_parts(P, plates=pl), params=P,
                         config=PlantConfig.stiff(strain_noise_m_m=2e-6, noise_seed=pl))
        ca = ControlledArm(arm)
        ca.set_damper(StrainDamper(DampingConfig(law="proportional", k_eps=ASSISTED_GAINS["one-way"]),
                                   arm.measured_strain(), arm.config.dt))
        n = int(round(seconds / arm.config.dt))
        th, eps = np.empty((n, 3)), np.empty((n, 2))
        nxt = 1
        for k in range(n):
            if nxt < times.size and k * arm.config.dt >= times[nxt]:
                ca.set_goal([0.0, levels[nxt, 0], levels[nxt, 1]])
                nxt += 1
            ca.step()
            th[k] = arm.measured_theta()
            eps[k] = arm.measured_strain()[0], arm.measured_strain()[2]
        t = np.arange(n) * arm.config.dt
        d, dd = derivatives(t, th, window_s=0.04)
        sl = slice(200, -200, 20)
        rows.append((th[sl], d[sl], dd[sl], eps[sl], np.full(th[sl].shape[0], arm.payload.mass_kg)))
    return fit_strain_dynamics(*(np.concatenate([r[i] for r in rows]) for i in range(5)))


def test_model_assisted_damping_through_the_adapter_settles_sooner():
    """SimCore(damping_model=...) installs the assisted damper; on experiment 06 the strain the layer
    sees (eps_tilde of the link-2 root) settles into the 15 um/m band sooner than with the plain filter,
    and the joint reaches its goal."""
    from tudorvision.joint.damping import ASSISTED_GAINS
    from tudorvision.joint.metrics import settling_time
    model = _identify_one_way()
    out = {}
    for name, m in (("plain", None), ("assisted", model)):
        core = SimCore(np.zeros(3), payload=Payload.from_parts(P, plates=3), params=P,
                       config=PlantConfig.stiff(two_way=False, strain_noise_m_m=2e-6, noise_seed=3), damping_model=m)
        server, adapter = _lockstep(core)
        adapter.set_mode(Mode.SETPOINT, damping=Damping.PROPORTIONAL)
        adapter.send_setpoint(np.array([0.0, 45.0, -45.0]) * DEG)
        d = core.controlled.damper
        assert d.strain_model is m
        if m is not None:
            assert d.config.k_eps == ASSISTED_GAINS["one-way"] and d.payload_kg == core.arm.payload.mass_kg
        e = np.array(_run(server, 5.0, lambda: d.eps_tilde[0]))
        out[name] = settling_time(np.arange(e.size) * DT, e, band=15e-6)
        np.testing.assert_allclose(core.arm.theta, np.array([0.0, 45.0, -45.0]) * DEG, atol=0.01 * DEG)
    assert out["assisted"] < out["plain"] - 0.4, out


def test_sim_core_passes_the_residual_coupling_to_the_monitor():
    from tudorvision.joint.collision import ResidualCoupling
    from tudorvision.joint.strain_dynamics import StrainDynamicsModel
    model = StrainDynamicsModel(chi=np.zeros((2, 32)))
    coupling = ResidualCoupling(c0=0.24, c1=0.29, threshold=1.2e-5)
    core = SimCore(params=P, collision_model=model, collision_thresholds=[6e-4, 2e-4], collision_coupling=coupling)
    core.set_modes(damping=0, collision=1)
    mon = core.controlled.reaction
    assert isinstance(mon, CollisionMonitor) and mon.isolation_coupling is coupling
    plain = SimCore(params=P, collision_model=model, collision_thresholds=[6e-4, 2e-4])
    plain.set_modes(damping=0, collision=1)
    assert plain.controlled.reaction.isolation_coupling is None
    with pytest.raises(ValueError, match="collision_coupling"):
        SimCore(params=P, collision_coupling=coupling)
