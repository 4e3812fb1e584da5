"""Chapter 8 reproduction helpers on the soft default plant (issue 18): drift of the integral law, static deflection."""
from __future__ import annotations

from tudorvision.lab.ch8_reproduce import integral_drift, static_deflection


def test_integral_law_error_grows_over_repeated_moves_and_the_half_integrator_has_none():
    r = integral_drift(True, laws=("integral", "half_integrator"))
    integ, half = r["integral"], r["half_integrator"]
    assert len(integ["joint_error_deg"]) == 2 * r["cycles"]
    # sections 6.6 / 8.6: the integral law's steady-state error grows with each repetition
    assert integ["growth_deg_per_cycle"] > 0.01 and integ["abs_error_deg_max"] > 0.1
    assert abs(half["growth_deg_per_cycle"]) < 0.005 and half["abs_error_deg_max"] < 0.03


def test_static_deflection_of_the_payload_on_the_soft_plant():
    r = static_deflection(True)
    goal = r["+400g_on_camera"]["servo_goal"]
    # about 14 mm at the servo goal pose; the joint servo holding the pose while the payload is added ends
    # there too (mean over 2 s of the still ringing links)
    assert 0.010 < goal["static_mm"] / 1e3 < 0.020
    assert abs(goal["held_mm"] / goal["static_mm"] - 1) < 0.15
    assert r["+400g"]["op3_vertical"]["static_mm"] < 0.1                  # the vertical pose barely bends
    assert r["max_static_mm_+400g"] == r["+400g"]["op1_stretched"]["static_mm"] > 40.0
    assert r["seed"]["implied_min_mm"]["from_90pct_8mm"] == 80.0
