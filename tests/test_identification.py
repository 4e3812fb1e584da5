"""Block-wise fit and validation of the strain-referred dynamics (shared by the collision core and the damper)."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tudorvision.joint.strain_dynamics import StrainDynamicsModel
from tudorvision.joint.identification import fit_with_validation


def _run(rng, chi, plates, n=3000, dt=0.01, noise=0.0):
    t = np.arange(n) * dt
    th = np.c_[np.zeros(n), rng.uniform(0.1, 3.0, n), rng.uniform(-1.0, 1.0, n)]
    d = np.c_[np.zeros(n), rng.normal(0, 1, (n, 2))]
    dd = np.c_[np.zeros(n), rng.normal(0, 3, (n, 2))]
    m = np.full(n, 0.05 + 0.1 * plates)
    eps = StrainDynamicsModel(chi=chi).predict(th, d, dd, m) + rng.normal(0, noise, (n, 2))
    return {"t": t, "theta": th, "d": d, "dd": dd, "eps": eps, "m": m, "plates": plates}


def test_recovers_a_payload_affine_model_and_reports_each_run():
    rng = np.random.default_rng(4)
    chi = rng.normal(0, 1e-4, (2, 32))
    runs = [_run(rng, chi, pl) for pl in (0, 2, 4)]
    model, fits = fit_with_validation(runs)
    np.testing.assert_allclose(model.chi, chi, rtol=1e-6, atol=1e-12)
    assert set(fits) == {"0 g", "200 g", "400 g"}
    assert all(f["fit_pct"][0] > 99.99 and f["rmse_um_m"][1] < 1e-6 for f in fits.values())
    # with noise the validation blocks (never fitted) show it
    noisy = [_run(rng, chi, pl, noise=2e-5) for pl in (0, 4)]
    _, fits_n = fit_with_validation([dict(r, label=f"run{i}") for i, r in enumerate(noisy)])
    assert set(fits_n) == {"run0", "run1"}
    assert all(15.0 < f["rmse_um_m"][0] < 25.0 for f in fits_n.values())
    # the identification blocks (the other half of table 10.1) see the same noise level
    assert all(15.0 < f["rmse_um_m_id"][0] < 25.0 and 15.0 < f["sigma_um_m"][1] < 25.0 for f in fits_n.values())


def test_rejects_bad_input():
    with pytest.raises(ValueError, match="runs"):
        fit_with_validation([])
    with pytest.raises(ValueError, match=r"runs\[0\]: missing \['eps'\]"):
        fit_with_validation([{"t": [0.0], "theta": [], "d": [], "dd": [], "m": []}])
    with pytest.raises(ValueError, match="block_s"):
        fit_with_validation([{}], block_s=0.0)


_angle = st.floats(-4.0, 4.0, allow_nan=False)
_rate = st.floats(-20.0, 20.0, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(st.lists(_angle, min_size=3, max_size=3), st.lists(_rate, min_size=3, max_size=3),
       st.lists(_rate, min_size=3, max_size=3), st.floats(0.0, 1.0), st.integers(0, 2**32 - 1))
def test_the_one_sample_prediction_is_predict_bit_for_bit(theta, dtheta, ddtheta, payload_kg, seed):
    """The joint layer's 2 kHz path (``predict_one``) gives exactly :meth:`predict`'s numbers for one row."""
    chi = np.random.default_rng(seed).normal(0.0, 1e-4, (2, 32))
    model = StrainDynamicsModel(chi=chi)
    want = model.predict(np.array([theta]), np.array([dtheta]), np.array([ddtheta]), payload_kg)[0]
    got = model.predict_one(theta, dtheta, ddtheta, payload_kg)
    assert got.shape == (2,)
    np.testing.assert_array_equal(got, want)


def test_the_one_sample_prediction_refuses_what_predict_refuses():
    model = StrainDynamicsModel(chi=np.ones((2, 32)))
    for k in range(6):
        args = [[0.0, 0.3, -0.2], [0.0, 0.1, 0.0], [0.0, 0.0, 0.5]]
        args[k // 2][1 + k % 2] = float("nan") if k % 2 else float("inf")
        with pytest.raises(ValueError, match="NaN or infinite"):
            model.predict([args[0]], [args[1]], [args[2]], 0.1)
        with pytest.raises(ValueError, match="NaN or infinite"):
            model.predict_one(*args, 0.1)
