"""Isolation on the decoupled link-3 residual r3 - c(m) r2 (ResidualCoupling)."""
import numpy as np
import pytest

from tudorvision.joint.collision import CollisionMonitor, ResidualCoupling, fit_residual_coupling, reaction_config
from tudorvision.joint.strain_dynamics import N_PARAMS, StrainDynamicsModel

DT = 5e-4


def _run(rows, coupling, payload=0.3):
    """Zero model: the residual is the strain through K_I / (s + K_I)."""
    mon = CollisionMonitor(StrainDynamicsModel(chi=np.zeros((2, 2 * N_PARAMS))), [10e-6, 10e-6], payload, DT,
                           reaction_config("none"), k_i=2000.0, isolation_coupling=coupling)
    th, d = [0.0, 0.5, 0.1], [0.0, 0.0, 0.0]
    for row in rows:
        mon.step(th, d, row, th, d, [0.0, 0.0, 0.0])
    return mon


def _rows(e2, e3):
    z = np.zeros_like(e2)
    return np.stack([e2, z, e3, z], axis=1)


def test_common_mode_load_is_link2_and_own_link3_load_is_link3():
    t = np.arange(0.0, 0.1, DT)
    rng = np.random.default_rng(3)
    c0, c1 = 0.28, 0.2                       # c(0.3 kg) = 0.34
    cp = ResidualCoupling(c0, c1, 5e-6)
    for _ in range(5):
        amp2, amp3, t0 = rng.uniform(60e-6, 150e-6), rng.uniform(15e-6, 40e-6), rng.uniform(0.01, 0.03)
        on = np.where(t >= t0, 1.0, 0.0)
        # a link-2 load whose link-3 answer is the common arm mode: r3 = c(m) r2, over its threshold
        common = _rows(amp2 * on, (c0 + 0.3 * c1) * amp2 * on)
        plain = _run(common, None)
        assert plain.isolated and plain.link == 3          # r3 alone stays over its threshold: link 3
        mon = _run(common, cp)
        assert mon.isolated and (mon.link, mon.direction) == (2, 1)
        assert mon.detected_at == pytest.approx(t0, abs=2e-3)
        # the same plus a load of link 3 itself (negative: compression on top)
        own = _run(_rows(amp2 * on, ((c0 + 0.3 * c1) * amp2 - amp3) * on), cp)
        assert own.isolated and (own.link, own.direction) == (3, -1)
    # the coupling follows the payload: at 0 kg, c = 0.28 leaves (0.34 - 0.28) amp2 = 6e-6 > 5e-6 in r3 - c r2
    on = np.where(t >= 0.02, 1.0, 0.0)
    mon = _run(_rows(100e-6 * on, 0.34 * 100e-6 * on), cp, payload=0.0)
    assert mon.link == 3
    mon = _run(_rows(100e-6 * on, 0.34 * 100e-6 * on), (c0, c1, 5e-6), payload=0.3)   # a plain tuple works
    assert mon.link == 2


def test_fit_residual_coupling_recovers_payload_affine_share_and_six_sigma():
    rng = np.random.default_rng(0)
    n = 30000
    m = rng.choice([0.0, 0.1, 0.2, 0.3, 0.4], size=n)
    r2 = rng.normal(0.0, 100e-6, n) * (1 + 2 * m)
    r3 = (0.27 + 0.25 * m) * r2 + rng.normal(0.0, 3e-6, n)
    cp = fit_residual_coupling(np.stack([r2, r3], axis=1), m)
    assert cp.c0 == pytest.approx(0.27, abs=2e-3) and cp.c1 == pytest.approx(0.25, abs=5e-3)
    assert cp.threshold == pytest.approx(18e-6, rel=0.03)
    assert cp.at_payload(0.4) == pytest.approx(cp.c0 + 0.4 * cp.c1)


def test_detect_decoupled_flags_an_own_link3_load_under_the_plain_thresholds():
    t = np.arange(0.0, 0.1, DT)
    on = np.where(t >= 0.02, 1.0, 0.0)
    cp = ResidualCoupling(0.3, 0.0, 2e-6)
    rows = _rows(20e-6 * on, (0.3 * 20e-6 - 5e-6) * on)     # r2 = 20e-6 and r3 = 1e-6: both under 1e-4
    zero = StrainDynamicsModel(chi=np.zeros((2, 2 * N_PARAMS)))

    def run(detect):
        mon = CollisionMonitor(zero, [1e-4, 1e-4], 0.3, DT, reaction_config("none"), k_i=2000.0,
                               isolation_coupling=cp, detect_decoupled=detect)
        for row in rows:
            mon.step([0.0, 0.5, 0.1], [0.0] * 3, row, [0.0] * 3, [0.0] * 3, [0.0] * 3)
        return mon

    assert not run(False).collision
    mon = run(True)
    assert mon.collision and mon.detected_at == pytest.approx(0.02, abs=2e-3)
    assert (mon.link, mon.direction) == (3, -1)
    with pytest.raises(ValueError, match="detect_decoupled"):
        CollisionMonitor(zero, [1e-4, 1e-4], 0.3, DT, detect_decoupled=True)
