"""Issue 18: the loaded net's two modes (the arm, the balls swinging in the bag) the catching agent shapes for."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from tudorvision.lab.catch.options import DemoOptions
from tudorvision.lab.catch.profile import ReferenceMirror, mode_frequency_hz, net_modes


def _pulse(t, t_pulse=0.15, peak=3.0):
    """A half-sine base acceleration, m/s^2."""
    return peak * math.sin(math.pi * t / t_pulse) if 0.0 <= t <= t_pulse else 0.0


@pytest.mark.parametrize("payload_kg, f0_hz, swing_hz", [(0.03, 3.0, 1.55), (0.21, 3.0, 1.55), (0.4, 2.6, 1.2),
                                                       (0.12, 2.0, 2.5)])
def test_modal_sum_reproduces_the_two_mass_system(payload_kg, f0_hz, swing_hz):
    """Oracle: the net (modal mass on the arm's spring) and the balls (a pendulum hanging from it) integrated as
    masses and springs under a base acceleration pulse; the net's motion is the sum of the modes' responses
    ``w_k eta_k``, ``eta_k'' + w_k^2 eta_k = -a``, with the frequencies and weights :func:`net_modes` gives."""
    m1, m2 = 0.26, payload_kg
    k1, k2 = m1 * (2 * math.pi * f0_hz) ** 2, m2 * (2 * math.pi * swing_hz) ** 2

    def masses(t, y):
        x1, x2, v1, v2 = y
        a = _pulse(t)
        return [v1, v2, (-k1 * x1 + k2 * (x2 - x1)) / m1 - a, -k2 * (x2 - x1) / m2 - a]

    modes = net_modes(payload_kg, f0_hz, 0.26, swing_hz)

    def modal(t, y):
        a = _pulse(t)
        return [v for k in range(len(modes)) for v in (y[2 * k + 1], -(2 * math.pi * modes[k][0]) ** 2 * y[2 * k] - a)]

    ts = np.linspace(0.0, 2.0, 401)
    opts = dict(t_eval=ts, rtol=1e-9, atol=1e-12, max_step=0.002)
    x_net = solve_ivp(masses, (0.0, 2.0), [0.0] * 4, **opts).y[0]
    eta = solve_ivp(modal, (0.0, 2.0), [0.0] * (2 * len(modes)), **opts).y[0::2]
    x_modal = sum(w * e for (_, w), e in zip(modes, eta))
    assert len(modes) == 2 and modes[0][0] < min(f0_hz, swing_hz) and modes[1][0] > max(f0_hz, swing_hz)
    assert sum(w for _, w in modes) == pytest.approx(1.0)          # at first the net lags a sudden push one to one
    assert np.max(np.abs(x_modal - x_net)) < 1e-4 * np.max(np.abs(x_net))


def test_a_rigid_or_empty_payload_is_the_one_mode_of_before():
    assert net_modes(0.2, 2.6, 0.26, 0.0) == ((mode_frequency_hz(0.2, 2.6, 0.26), 1.0),)
    assert net_modes(0.0, 3.0, 0.26, 1.55) == ((3.0, 1.0),)
    light = net_modes(1e-4, 3.0, 0.26, 1.55)                        # a feather in the bag: the arm's mode alone
    assert light[1][0] == pytest.approx(3.0, rel=1e-3) and light[1][1] == pytest.approx(1.0, abs=1e-3)
    with pytest.raises(ValueError, match="mode_swing_hz"):
        DemoOptions(mode_swing_hz=-1.0)


def test_the_residual_of_several_modes_is_their_weighted_sum():
    m = ReferenceMirror(1.6, 6.9)
    m.sent(np.deg2rad([0.0, 30.0, 60.0]), 0.0, theta_now=np.deg2rad([0.0, 60.0, 60.0]))
    goal = np.deg2rad([0.0, 40.0, 70.0])
    r1, t1 = m.residual_rad(goal, 0.3, 1.4)
    r2, t2 = m.residual_rad(goal, 0.3, 3.2)
    both, t_end = m.residual_rad(goal, 0.3, ((1.4, 0.3), (3.2, 0.7)))
    assert both == pytest.approx(0.3 * r1 + 0.7 * r2) and t_end == t1 == t2
    assert m.residual_rad(goal, 0.3, ((2.6, 1.0),))[0] == pytest.approx(m.residual_rad(goal, 0.3, 2.6)[0])
    v, a = m.choose_profile(goal, 0.3, 1.5, ((1.4, 0.3), (3.2, 0.7)))
    assert m.residual_rad(goal, 0.3, ((1.4, 0.3), (3.2, 0.7)), v_max=v, a_max=a)[0] <= both
