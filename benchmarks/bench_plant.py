"""Benchmark: simulated elastic TUDOR with joint cascade at 2 kHz.

Target (issue 2, part 3): 10 s of simulated motion at 2 kHz in under 2 s of wall time.

Ours: ``tudorvision.sim.arm.simulate_ptp`` on the stiff one-way plant ``PlantConfig.stiff()``
(scalar 2 kHz loop, modes integrated exactly with a zero-order hold; the peer models that plant);
the default soft plant (issue 18) is timed beside it.
Peer: the same closed loop integrated the textbook way with
``scipy.integrate.solve_ivp`` (RK45): the discrete controller output is held
over each 0.5 ms period and the continuous plant (rigid multibody joints,
viscous + smoothed Coulomb friction, the same modal link equations) is
integrated between samples. The peer runs a shorter horizon and is reported
per simulated second; the ratio compares wall time per simulated second.

Run:  .venv/bin/python benchmarks/bench_plant.py [--seconds 10] [--peer-seconds 1]
"""
from __future__ import annotations

import argparse
import os

from _machine import cpu_model  # benchmarks/ is on sys.path when run as a script
import time

import numpy as np
from scipy.integrate import solve_ivp

from tudorvision.joint.cascade import JointCascade, design_cascade
from tudorvision.joint.planner import plan_motion
from tudorvision.robot import load_robot_params
from tudorvision.sim.arm import (ElasticArm, Payload, PlantConfig, bias_torques, mass_matrix,
                                 zero_config_inertia)
from tudorvision.lab.simulation import simulate_ptp

DEG = np.pi / 180



def peer_simulate(start, goal, seconds, payload, params):
    """solve_ivp (RK45) between 2 kHz controller samples; returns final (theta, strain-free state)."""
    arm = ElasticArm(start, payload=payload, params=params)       # constants only
    b, lk2, lk3 = arm.bodies, arm.link2, arm.link3
    kM = np.array(arm.kM)
    kv = np.array(arm._kvp)
    kc = np.array(arm._kcp)
    n = lk2.n
    zeta = np.array([0.002, 0.004])[:n]
    gains = design_cascade(params, zero_config_inertia(arm))
    ctrl = JointCascade(gains, 0.0005, start)
    motion = plan_motion(start, goal, v_max=params.experiment_speed_rad_s,
                         a_max=params.experiment_accel_rad_s2, t0=0.1)
    g = params.gravity_m_s2
    om2 = [np.array(lk.om2) for lk in (lk2, lk3)]
    om = [np.sqrt(o) for o in om2]
    gam = [np.array(lk.gamma) for lk in (lk2, lk3)]
    phiL = [np.array(lk.phiL) for lk in (lk2, lk3)]
    dphiL = [np.array(lk.dphiL) for lk in (lk2, lk3)]
    iphi = [np.array(lk.iphi) for lk in (lk2, lk3)]
    pi3 = np.array(lk3.pi)

    def rhs(t, x, tau):
        th, dth = x[:3], x[3:6]
        e2, de2, e3, de3 = x[6:6 + n], x[6 + n:6 + 2 * n], x[6 + 2 * n:6 + 3 * n], x[6 + 3 * n:]
        fr = kv * dth + kc * np.tanh(dth / 1e-3)
        acc = np.linalg.solve(mass_matrix(th, b), tau - bias_torques(th, dth, b, g) - fr)
        ca, cb, c3 = np.cos(th[1]), np.cos(th[1] + th[2]), np.cos(th[2])
        q2, P2, M2 = -(b.m2 / b.l2) * g * ca, -(b.mA + b.m3 + b.mP) * g * ca, -g * b.s3 * cb
        q3, P3 = -(b.m3 / b.l3) * g * cb, -b.mP * g * cb
        u2 = (iphi[0] * q2 + phiL[0] * P2 + dphiL[0] * M2 - gam[0] * acc[1]
              - phiL[0] * b.s3 * c3 * acc[2] - dphiL[0] * b.J3 * acc[2])
        dde2 = u2 - 2 * zeta * om[0] * de2 - om2[0] * e2
        alpha = acc[1] + acc[2] + dphiL[0] @ dde2
        a_perp = (b.l2 * acc[1] + phiL[0] @ dde2) * c3
        u3 = iphi[1] * q3 + phiL[1] * P3 - gam[1] * alpha - pi3 * a_perp
        dde3 = u3 - 2 * zeta * om[1] * de3 - om2[1] * e3
        return np.concatenate([dth, acc, de2, dde2, de3, dde3])

    x = np.concatenate([start, np.zeros(3), arm.eta2, np.zeros(n), arm.eta3, np.zeros(n)])
    dt = 0.0005
    steps = int(round(seconds / dt))
    ref = motion.sample(dt * np.arange(steps))
    for k in range(steps):
        v = ctrl.step(x[:3].tolist(), ref[0][k].tolist(), ref[1][k].tolist())
        tau = np.clip(kM * np.array(v), -params.max_intermittent_torque_Nm, params.max_intermittent_torque_Nm)
        sol = solve_ivp(rhs, (0.0, dt), x, args=(tau,), method="RK45", rtol=1e-6, atol=1e-9)
        x = sol.y[:, -1]
    return x


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="simulated seconds for ours")
    ap.add_argument("--peer-seconds", type=float, default=1.0, help="simulated seconds for the peer")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    p = load_robot_params()
    start, goal = np.array([0, 45, -45]) * DEG, np.array([0, 135, 45]) * DEG
    payload = Payload.from_parts(p, plates=3)
    ours = []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        log = simulate_ptp(start, goal, args.seconds, payload=payload, t_move=0.1, config=PlantConfig.stiff())
        ours.append(time.perf_counter() - t0)
    t_ours = min(ours)
    t0 = time.perf_counter()
    simulate_ptp(start, goal, args.seconds, payload=payload, t_move=0.1, config=PlantConfig.stiff(two_way=True))
    t_two_way = time.perf_counter() - t0
    t0 = time.perf_counter()
    simulate_ptp(start, goal, args.seconds, payload=payload, t_move=0.1)
    t_soft = time.perf_counter() - t0
    t0 = time.perf_counter()
    x_peer = peer_simulate(start, goal, args.peer_seconds, payload, p)
    t_peer = time.perf_counter() - t0
    k = int(round(args.peer_seconds / 0.0005)) - 1
    agree = np.rad2deg(np.abs(x_peer[:3] - log.theta[k])).max()
    per_s_ours, per_s_peer = t_ours / args.seconds, t_peer / args.peer_seconds
    print(f"machine: {os.cpu_count()} CPUs, {cpu_model()}")
    print(f"ours : {args.seconds:g} s simulated at 2 kHz in {t_ours:.3f} s wall (best of {args.repeat}: "
          f"{', '.join(f'{t:.3f}' for t in ours)}) -> {per_s_ours * 1e3:.1f} ms per simulated s; "
          f"target < 2 s for 10 s: {'met' if per_s_ours * 10 < 2 else 'NOT met'}")
    print(f"ours, two-way coupled model (used with contacts): {args.seconds:g} s in {t_two_way:.3f} s wall")
    print(f"ours, default soft plant (hub springs, backlash, two-way): {args.seconds:g} s in {t_soft:.3f} s wall")
    print(f"peer : scipy solve_ivp RK45 per 0.5 ms period, {args.peer_seconds:g} s simulated in "
          f"{t_peer:.3f} s wall -> {per_s_peer * 1e3:.1f} ms per simulated s")
    print(f"ratio: peer / ours = {per_s_peer / per_s_ours:.1f}x; joint angles agree within {agree:.4f} deg "
          f"at t = {args.peer_seconds:g} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
