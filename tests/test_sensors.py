"""Depth sensor basics: the raw <-> metric depth pair and the depth-noise model (tudorvision.sensors)."""
import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.sensors import (DEFAULT_SIGMA_FLOOR_M, KINECT_DEPTH_NOISE, KINECT_SIGMA_UNIT,
                                 KINECT_SIGMA_Z_COEFFS, SIGMA_UNITS_PER_M, DepthNoiseModel, depth_m_from_raw,
                                 raw_from_depth_m)


def seed_sigma_mm(z):
    """The seed's Kinect fit written out independently (z in m; sigma in mm, the lab's reading since issue 18)."""
    return 0.51 * z ** 3 - 2.1 * z ** 2 + 5.12 * z - 2.18


def test_kinect_polynomial_values_at_1_2_5_m():
    # hand-evaluated: 0.51 - 2.1 + 5.12 - 2.18; 4.08 - 8.4 + 10.24 - 2.18; 63.75 - 52.5 + 25.6 - 2.18
    expected_mm = np.array([1.35, 3.74, 34.67])
    z = np.array([1.0, 2.0, 5.0])
    np.testing.assert_allclose(seed_sigma_mm(z), expected_mm, rtol=1e-12)
    np.testing.assert_allclose(KINECT_DEPTH_NOISE.sigma_m(z), expected_mm / 1000.0, rtol=1e-12)
    assert KINECT_SIGMA_UNIT == "mm" and SIGMA_UNITS_PER_M[KINECT_SIGMA_UNIT] == 1000.0
    assert DepthNoiseModel() == KINECT_DEPTH_NOISE
    # the lab's model is the seed's coefficients read in mm, converted to metres (bit for bit)
    np.testing.assert_allclose(KINECT_DEPTH_NOISE.coeffs, (0.00051, -0.0021, 0.00512, -0.00218), rtol=1e-15)
    assert KINECT_DEPTH_NOISE.coeffs == tuple(c / 1000.0 for c in KINECT_SIGMA_Z_COEFFS)
    # published Kinect noise (Khoshelham and Elberink 2012; Nguyen et al. 2012): about 1.5-2 mm at 1 m
    # and up to about 4 cm at 5 m; the model is within a factor 1.5 of both, the cm reading 7-9 times above
    assert 1e-3 < KINECT_DEPTH_NOISE.sigma_m(1.0) < 3e-3 and 0.025 < KINECT_DEPTH_NOISE.sigma_m(5.0) < 0.045


def test_noise_model_floor_and_shape():
    m = KINECT_DEPTH_NOISE
    z = np.linspace(0.6, 6.0, 55).reshape(5, 11)
    s = m.sigma_m(z)
    assert s.shape == z.shape and s.dtype == np.float64
    assert np.all(np.diff(s.ravel()) > 0)                    # the cubic increases over the range
    assert m.sigma_m(0.3) == m.floor_m == DEFAULT_SIGMA_FLOOR_M == 2e-4     # cubic negative there
    assert np.all(s > m.floor_m)                             # the floor never bites inside 0.6-6 m
    np.testing.assert_allclose(s, seed_sigma_mm(z) / 1000.0, rtol=1e-12)
    assert float(DepthNoiseModel(floor_m=0.0).sigma_m(0.3)) == 0.0
    assert DepthNoiseModel.from_dict(m.as_dict()) == m


@pytest.mark.parametrize("z", [0.8, 2.0, 5.0])
def test_noise_model_statistics_on_a_seeded_sample(z):
    n = 200_000
    d = KINECT_DEPTH_NOISE.noisy_depth_m(np.full(n, z), np.random.default_rng(7))
    sigma = seed_sigma_mm(z) / 1000.0
    # mean within 4 standard errors, std within 4 standard errors of the std (sigma / sqrt(2 n))
    assert abs(d.mean() - z) < 4 * sigma / np.sqrt(n)
    assert abs(d.std(ddof=1) / sigma - 1) < 4 / np.sqrt(2 * n)


def test_noisy_depth_draws_one_standard_normal_per_pixel():
    depth = np.full((4, 5), 2.0)
    d = KINECT_DEPTH_NOISE.noisy_depth_m(depth, np.random.default_rng(3))
    expected = depth + 0.00374 * np.random.default_rng(3).standard_normal((4, 5))
    np.testing.assert_allclose(d, expected, rtol=1e-12)


def test_raw_round_trip_property():
    rng = np.random.default_rng(11)
    for scale in (1000.0, 5000.0):
        raw = rng.integers(1, 65536, (40, 30)).astype(np.uint16)
        raw[rng.random(raw.shape) < 0.1] = 0
        for dtype in (np.float32, np.float64):
            d = depth_m_from_raw(raw, scale, dtype=dtype)
            assert d.dtype == dtype
            np.testing.assert_array_equal(raw_from_depth_m(d, scale), raw)
        d = rng.uniform(0.05, 13.0, (40, 30))
        back = depth_m_from_raw(raw_from_depth_m(d, scale), scale, dtype=np.float64)
        np.testing.assert_array_less(np.abs(back - d), 0.5 / scale + 1e-12)


def test_invalid_pixels_are_nan_and_zero():
    d = depth_m_from_raw(np.array([[0, 1000, 2000]], np.uint16), 1000.0)
    assert np.isnan(d[0, 0]) and d[0, 1:].tolist() == [1.0, 2.0]
    raw = raw_from_depth_m(np.array([np.nan, np.inf, -np.inf, -1.0, 0.0, 0.0004, 0.0006]), 1000.0)
    assert raw.tolist() == [0, 0, 0, 0, 0, 0, 1]


def test_out_of_range_is_explicit():
    d = np.array([[1.0, 70.0]])
    assert raw_from_depth_m(d, 1000.0).tolist() == [[1000, 0]]             # like a sensor out of range
    assert raw_from_depth_m(d, 1000.0, out_of_range="invalid").tolist() == [[1000, 0]]
    assert raw_from_depth_m(np.array([65.5354]), 1000.0, out_of_range="raise").tolist() == [65535]
    with pytest.raises(ValueError, match=r"70\.000 m exceeds 16 bits at depth_scale=1000"):
        raw_from_depth_m(d, 1000.0, out_of_range="raise")
    with pytest.raises(ValueError, match="out_of_range"):
        raw_from_depth_m(d, 1000.0, out_of_range="clip")


def test_check_range_catches_a_wrong_scale():
    raw = np.full((10, 10), 1500, np.uint16)
    assert np.all(depth_m_from_raw(raw, 1000.0, check_range=True) == np.float32(1.5))
    with pytest.raises(TudorVisionError, match=r"implausible median depth.*depth_scale=1000"):
        depth_m_from_raw(raw, 1.0, check_range=True)
    assert np.all(depth_m_from_raw(raw, 1.0) == 1500.0)                    # unchecked by default
    zeros = np.zeros((4, 4), np.uint16)
    assert np.all(np.isnan(depth_m_from_raw(zeros, 1000.0)))
    with pytest.raises(TudorVisionError, match="no valid pixel"):
        depth_m_from_raw(zeros, 1000.0, check_range=True)


@pytest.mark.parametrize("scale", [0.0, -1.0, float("nan"), float("inf"), "1000", True])
def test_bad_depth_scale(scale):
    with pytest.raises(ValueError, match="depth_scale"):
        depth_m_from_raw(np.ones((2, 2), np.uint16), scale)
    with pytest.raises(ValueError, match="depth_scale"):
        raw_from_depth_m(np.ones((2, 2)), scale)


@pytest.mark.parametrize("kwargs, match", [
    (dict(coeffs=()), "coeffs"),
    (dict(coeffs=(1.0, float("nan"))), "coeffs"),
    (dict(floor_m=-1e-3), "floor_m"),
    (dict(z_range_m=(2.0, 1.0)), "z_range_m"),
])
def test_bad_noise_model(kwargs, match):
    with pytest.raises(ValueError, match=match):
        DepthNoiseModel(**kwargs)
    with pytest.raises(TudorVisionError, match="missing or invalid"):
        DepthNoiseModel.from_dict({"z_range_m": [0.6, 6.0]})
