"""Data-based kinematics under load (section 9.2)."""
import numpy as np
import pytest

from tudorvision.lab.data_collection import CollectionOptions, collect_settled_poses, load_or_collect
from tudorvision.catch.kinematics import (DeflectionModel, ForwardModel, InverseKinematics, StrainModel,
                                          fit_kinematics, rigid_regressors)
from tudorvision.robot import fk_ee, ik, load_robot_params, planar_from_joints


def _synthetic(rng, n=400):
    th23 = np.column_stack([rng.uniform(0, np.pi, n), rng.uniform(-1.5, 1.5, n)])
    m = rng.choice([0.0, 0.1, 0.2, 0.3, 0.4], n)
    R = rigid_regressors(th23)
    # a known model in the class: strains linear in m with regressor-dependent gains
    A_true = rng.normal(size=(15, 4)) * 1e-5
    B_true = rng.normal(size=(15, 4)) * 1e-4
    sm = StrainModel(A=A_true, B=B_true)
    eps = sm.predict(th23, m)
    D_true = rng.normal(size=(30, 2)) * 0.01
    dm_true = DeflectionModel(D=D_true)
    return th23, m, eps, dm_true(th23, m), (A_true, B_true, D_true), R


def test_fits_recover_a_known_synthetic_model():
    rng = np.random.default_rng(0)
    th23, m, eps, rz, (A, B, D), _ = _synthetic(rng)
    sm = StrainModel.fit(th23, m, eps)
    np.testing.assert_allclose(sm.predict(th23, m), eps, atol=1e-10)
    np.testing.assert_allclose(sm.payload(th23, eps), m, atol=1e-6)
    dm = DeflectionModel.fit(th23, m, rz)
    np.testing.assert_allclose(dm(th23, m), rz, atol=1e-9)
    fm = ForwardModel.fit(th23, eps, rz)
    assert np.sqrt(np.mean((fm(th23, eps) - rz) ** 2)) < 0.01      # a different model class: close, not exact


def test_inverse_remaps_onto_the_target_and_resolves_the_elbow_by_nearness_and_limits():
    rng = np.random.default_rng(1)
    th23, m, eps, rz, _, _ = _synthetic(rng)
    D = np.zeros((30, 2)); D[0] = [0.01, -0.02]; D[15] = [0.0, -0.05]     # offset + payload sag
    ikm = InverseKinematics(DeflectionModel(D=D))
    target = fk_ee([0.0, 1.0, 0.6])
    sols = ikm.solutions(target, 0.0, 0.2)
    assert set(sols) == {"up", "down"}
    for name, th in sols.items():
        np.testing.assert_allclose(ikm.model(th[None, 1:], 0.2)[0], [target[0], target[2]], atol=1e-5)
        assert (th[2] > 0) == (name == "up")
    up, down = sols["up"], sols["down"]
    assert np.allclose(ikm(target, 0.0, 0.2, near=up + 0.05), up)
    assert np.allclose(ikm(target, 0.0, 0.2, near=down - 0.05), down)
    # low in front: the elbow-up mirror of this pose needs theta2 < -14 deg (outside the range)
    low = fk_ee([0.0, np.deg2rad(-5.0), np.deg2rad(-60.0)])
    ikr = InverseKinematics(DeflectionModel(D=np.zeros((30, 2))))
    s = ikr.solutions(low, 0.0, 0.0)
    assert list(s) == ["down"]
    np.testing.assert_allclose(ikr(low, 0.0, 0.0, near=np.deg2rad([0.0, -60.0, 60.0])), s["down"])
    with pytest.raises(ValueError, match="not reachable"):
        ikr([0.0, 0.0, 2.0], 0.0, 0.0)


def test_collection_and_models_on_the_simulated_arm_beat_rigid_ik(tmp_path):
    opts = CollectionOptions(theta2_deg=(0, 180, 20), theta3_deg=(-90, 90, 20), payloads_kg=(0.0, 0.1, 0.2, 0.4))
    d = load_or_collect(tmp_path, opts)
    assert d["theta"].shape == (4 * 10 * 10, 3)
    assert len(list(tmp_path.glob("*.npz"))) == 1
    d2 = load_or_collect(tmp_path, opts)         # cached
    np.testing.assert_array_equal(d["p_meas_base"], d2["p_meas_base"])
    km = fit_kinematics(d, test_payloads_kg=[0.1])
    assert max(km.report["forward_rmse_m"]) < 0.003
    assert km.report["payload_rmse_kg"] < 0.03
    p = load_robot_params()
    from tudorvision.sim.arm import ElasticArm, Payload
    ikm = InverseKinematics(km.deflection, p)
    rng = np.random.default_rng(2)
    e_c, e_r = [], []
    while len(e_c) < 15:
        tgt = np.array([rng.uniform(-0.5, 0.5), 0.0, rng.uniform(0.6, 1.1)])
        mass = rng.uniform(0.0, 0.4)
        try:
            th_c = ikm(tgt, 0.0, mass, near=np.deg2rad([0, 60, 60]))
            th_r = ik(tgt, p, near=np.deg2rad([0, 60, 60]))
        except ValueError:
            continue
        pay = Payload(mass_kg=p.end_effector_mount_mass_kg + mass)
        e_c.append(np.linalg.norm(ElasticArm(th_c, payload=pay, params=p).ee_position() - tgt))
        e_r.append(np.linalg.norm(ElasticArm(th_r, payload=pay, params=p).ee_position() - tgt))
    rms_c, rms_r = np.sqrt(np.mean(np.square(e_c))), np.sqrt(np.mean(np.square(e_r)))
    assert rms_c < 0.005 < 0.01 < rms_r


def test_collected_poses_are_the_plants_static_equilibria():
    from tudorvision.sim.arm import ElasticArm, Payload
    p = load_robot_params()
    from tudorvision.lab.data_collection import plant_config
    opts = CollectionOptions(theta2_deg=(20, 160, 70), theta3_deg=(-60, 60, 60), payloads_kg=(0.3,),
                             measurement_sigma_m=0.0, strain_sigma=0.0, plant="seed_measured")
    d = collect_settled_poses(opts, p)
    for th, eps, pt in zip(d["theta"], d["strains"], d["p_true_base"]):
        arm = ElasticArm(th, payload=Payload(mass_kg=p.end_effector_mount_mass_kg + 0.3), params=p,
                         config=plant_config(opts.plant))
        np.testing.assert_allclose(eps, arm.strain, rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(pt, arm.ee_position(), atol=1e-12)
    assert np.max(np.linalg.norm(d["p_true_base"] - fk_ee(d["theta"]), axis=1)) > 0.01   # it deflects


def test_collection_rejects_a_bad_grid():
    with pytest.raises(ValueError, match="grid"):
        collect_settled_poses(CollectionOptions(theta2_deg=(0, 10, 0)))


def test_regressors_match_the_rigid_arm():
    th23 = np.array([[0.3, -0.7], [1.2, 0.4]])
    R = rigid_regressors(th23)
    r, z = planar_from_joints(th23[:, 0], th23[:, 1])
    p = load_robot_params()
    np.testing.assert_allclose(r, p.link2_length_m * R[:, 0] + p.link3_length_m * R[:, 2])
    np.testing.assert_allclose(z, p.link1_height_m + p.link2_length_m * R[:, 1] + p.link3_length_m * R[:, 3])
