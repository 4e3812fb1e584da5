"""Issue 18: the net's payload between weighings (tudorvision.catch.payload) and the agent's use of it."""
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from _catch_stubs import LayerStub

from tudorvision.catch.payload import PayloadBelief, after_emptying, after_throw, between_throws, weighed
from tudorvision.lab.catch.agent import CatchAgent, ThrowLog
from tudorvision.lab.catch.options import DemoOptions
from tudorvision.robot import load_robot_params

finite = st.floats(-1.0, 1.0, allow_nan=False)
positive = st.floats(1e-3, 0.2, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(mean=finite, var=st.floats(0.0, 0.04), ball=st.floats(0.0, 0.1), p=st.floats(0.0, 1.0))
def test_after_throw_is_the_moments_of_the_two_outcomes(mean, var, ball, p):
    """Oracle: mixture of "no catch" (prob 1 - p) and "one more ball" (prob p), each the prior shifted."""
    b = after_throw(PayloadBelief(mean, var), ball, p)
    m_mix = (1 - p) * mean + p * (mean + ball)
    second = (1 - p) * (var + mean ** 2) + p * (var + (mean + ball) ** 2)
    assert b.mean_kg == pytest.approx(m_mix, abs=1e-12)
    assert b.var_kg2 == pytest.approx(second - m_mix ** 2, abs=1e-10)


@settings(max_examples=60, deadline=None)
@given(mean=st.floats(-0.2, 0.4), sd=positive, z_off=st.floats(-2.0, 2.0), r=positive)
def test_weighed_is_the_product_of_the_two_gaussians(mean, sd, z_off, r):
    """Oracle: the posterior's mean and variance by numerical integration of prior x likelihood (inside the gate)."""
    z = mean + z_off * np.hypot(sd, r)            # within 4 innovation sigmas: a Kalman update
    b = weighed(PayloadBelief(mean, sd ** 2), z, r)
    x = np.linspace(mean - 12 * sd, mean + 12 * sd, 20001)
    w = np.exp(-0.5 * ((x - mean) / sd) ** 2 - 0.5 * ((z - x) / r) ** 2)
    w /= w.sum()
    m = float((w * x).sum())
    assert b.mean_kg == pytest.approx(m, abs=1e-6 * max(1.0, sd / r))
    assert b.var_kg2 == pytest.approx(float((w * (x - m) ** 2).sum()), rel=1e-3)


def test_a_weighing_far_outside_the_belief_replaces_it_and_bad_values_are_refused():
    b = weighed(PayloadBelief(0.21, 0.01 ** 2), 0.0, 0.012)           # the net emptied unseen
    assert b == PayloadBelief(0.0, 0.012 ** 2)
    assert after_emptying() == PayloadBelief(0.0, 0.0)
    for bad in (lambda: weighed(PayloadBelief(), 0.1, 0.0), lambda: weighed(PayloadBelief(), float("nan"), 0.01),
                lambda: after_throw(PayloadBelief(), 0.03, 1.5), lambda: after_throw(PayloadBelief(), -0.03, 0.5),
                lambda: weighed(PayloadBelief(), 0.1, 0.01, gate_sigmas=0.0)):
        with pytest.raises(ValueError):
            bad()


def _session(rng, n=400, ball=0.03, p_true=0.9, p_rest=0.35, sd_weigh=0.012, capacity=8):
    """A net that fills by Bernoulli catches, emptied at capacity; weighings at rest only now and then."""
    true, rows, balls = [], [], 0
    for _ in range(n):
        balls += int(rng.random() < p_true)
        emptied = balls >= capacity
        if emptied:
            balls = 0
        z = balls * ball + rng.normal(0, sd_weigh) if rng.random() < p_rest else None
        true.append(balls * ball)
        rows.append((z, emptied))
    return np.array(true), rows


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_belief_tracks_a_filling_net_better_than_the_last_weighing(seed):
    """Seeded simulation: the belief beats the stale last weighing, and its sigma is honest (about 95 % in 2 sigma)."""
    rng = np.random.default_rng(seed)
    true, rows = _session(rng)
    b, last, err_b, err_last, inside = PayloadBelief(), 0.0, [], [], 0
    for t, (z, emptied) in zip(true, rows):
        b = between_throws(b, z, ball_kg=0.03, p_catch=0.9, emptied=emptied, sigma_kg=0.012)
        if z is not None:
            last = z
        err_b.append(b.mean_kg - t)
        err_last.append(last - t)
        inside += abs(b.mean_kg - t) <= 2 * b.sigma_kg + 1e-12
    rms_b, rms_last = np.sqrt(np.mean(np.square(err_b))), np.sqrt(np.mean(np.square(err_last)))
    assert rms_b < 0.6 * rms_last
    assert rms_b < 0.02
    assert inside / len(true) > 0.85


def _agent(prior, weighing_kg=0.12):
    strain = SimpleNamespace(payload=lambda theta23, eps: np.array([weighing_kg]))
    return CatchAgent(LayerStub(), None, strain, None, None, np.eye(4), params=load_robot_params(),
                      options=DemoOptions(payload_catch_prior=prior), payload_range_kg=(0.0, 0.4))


def test_the_agent_raises_its_payload_for_a_tried_throw_without_a_weighing():
    ball = load_robot_params().ball_mass_kg
    agent = _agent(0.9)
    agent.log = ThrowLog(setpoint=np.zeros(3))           # the agent tried to catch this throw
    agent.weigh([])                                       # the arm did not rest: no weighing
    assert agent.payload_est_kg == pytest.approx(0.9 * ball)
    agent.log = ThrowLog()                                # a throw it did not try: nothing added
    agent.weigh([])
    assert agent.payload_est_kg == pytest.approx(0.9 * ball)
    agent.log = ThrowLog(setpoint=np.zeros(3))
    agent.weigh([], emptied=True)                         # the operator emptied the net
    assert agent.payload_est_kg == 0.0
    assert agent.layer.payloads[-1] == pytest.approx(agent.mount_kg)
    agent.log = ThrowLog(setpoint=np.zeros(3))
    agent.weigh([np.zeros(4)])                            # at rest: the weighing (0.12) pulls the belief up
    assert 0.9 * ball < agent.payload_est_kg <= 0.12
    # off (the default): the last weighing stays, as before
    off = _agent(0.0)
    off.log = ThrowLog(setpoint=np.zeros(3))
    off.weigh([])
    assert off.payload_est_kg == 0.0 and off.layer.payloads == []
    off.weigh([np.zeros(4)])
    assert off.payload_est_kg == pytest.approx(0.12)


@pytest.mark.parametrize("bad", [{"payload_catch_prior": 1.5}, {"payload_catch_prior": float("nan")},
                                 {"payload_weigh_sigma_kg": 0.0}])
def test_bad_payload_options_are_refused(bad):
    with pytest.raises(ValueError, match="payload_catch_prior, payload_weigh_sigma_kg"):
        DemoOptions(**bad)


def test_the_demo_weighs_with_the_belief_from_the_command_line(tmp_path, capsys):
    """End to end (``catch demo --payload-catch-prior``): every throw's payload estimate within a ball of the truth;
    a bad value is a one-line error that writes nothing."""
    import csv

    from tudorvision.cli import main

    out = tmp_path / "d"
    assert main(["catch", "demo", "--throws", "3", "--seed", "3", "--no-render", "--no-rerun",
                 "--payload-catch-prior", "0.9", "--out", str(out)]) == 0
    rows = list(csv.DictReader((out / "throws.csv").open()))
    assert len(rows) == 3
    for r in rows:
        assert abs(float(r["payload_est_kg"]) - float(r["payload_true_kg"])) <= 0.03 + 1e-9
    capsys.readouterr()
    assert main(["catch", "demo", "--payload-catch-prior", "1.5", "--out", str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--payload-catch-prior" in err[0] and "0-1" in err[0]
    assert not (tmp_path / "bad").exists()
