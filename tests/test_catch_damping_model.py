"""The catching demo's joint layer with the model-assisted static strain cancellation (issue 18).

The layer's damper can take an identified strain model (chapter 10) and gains of its own; the lab
identifies the model once per plant and keeps it in the cache folder.
"""
from __future__ import annotations

import numpy as np
import pytest

from tudorvision.joint import Damping
from tudorvision.joint.damping import SOFT_GAINS
from tudorvision.joint.strain_dynamics import StrainDynamicsModel
from tudorvision.lab.catch.options import DemoOptions
from tudorvision.lab.catch.run import demo_damping_model
from tudorvision.lab.ch10 import Ch10Options, identified_strain_model
from tudorvision.lab.simulation import SimCore
from tudorvision.robot import load_robot_params
from tudorvision.sim.arm import ElasticArm, Payload, PlantConfig

P = load_robot_params()
DEG = np.pi / 180.0
SHORT = Ch10Options(seconds=24.0, plates=(0, 2))


def test_given_gains_replace_the_tuned_ones_and_survive_a_payload_change():
    core = SimCore(np.deg2rad([0.0, 60.0, 60.0]), params=P, damping_gains=(0.0, 400.0, 400.0))
    core.set_modes(damping=Damping.PROPORTIONAL, collision=0)
    assert core.controlled.damper.config.k_eps == (0.0, 400.0, 400.0)
    core.set_payload(0.2)                             # the tuned gains would follow the payload schedule
    np.testing.assert_allclose(core.controlled.damper.k_eps, [0.0, 400.0, 400.0])
    plain = SimCore(np.deg2rad([0.0, 60.0, 60.0]), params=P)
    plain.set_modes(damping=Damping.PROPORTIONAL, collision=0)
    assert plain.controlled.damper.config.k_eps == SOFT_GAINS["proportional"]
    with pytest.raises(ValueError, match="damping_gains"):
        SimCore(params=P, damping_gains=(1.0, 2.0))
    with pytest.raises(ValueError, match="damping_gains"):
        DemoOptions(damping_gains=(0.0, np.nan, 1.0))


def test_the_identified_model_predicts_the_static_strain_and_is_cached(tmp_path):
    """Oracle: at rest the model's strain is the plant's static strain at poses the runs never held."""
    cfg = PlantConfig()
    model = identified_strain_model(cfg, SHORT, cache_dir=tmp_path)
    files = list(tmp_path.glob("strain_model_*.npz"))
    assert len(files) == 1
    np.savez(files[0], chi=2.0 * model.chi)                                # the file is what is read back
    again = identified_strain_model(cfg, SHORT, cache_dir=tmp_path)
    np.testing.assert_array_equal(again.chi, 2.0 * model.chi)
    other = identified_strain_model(cfg, Ch10Options(seconds=10.0, plates=(1,)), cache_dir=tmp_path)
    assert len(list(tmp_path.glob("strain_model_*.npz"))) == 2 and not np.array_equal(other.chi, model.chi)
    rng = np.random.default_rng(3)
    errs, spans = [], []
    for _ in range(6):
        th = np.array([0.0, rng.uniform(30, 150), rng.uniform(-50, 50)]) * DEG
        pay = Payload.from_parts(P, plates=1)
        arm = ElasticArm(th, payload=pay, params=P, config=PlantConfig(strain_noise_m_m=0.0))
        eps_true = np.asarray(arm.strain)[[0, 2]]
        zero = np.zeros(3)
        eps_model = model.predict(th[None], zero[None], zero[None], np.array([pay.mass_kg]))[0]
        errs.append(eps_model - eps_true)
        spans.append(eps_true)
    errs, spans = np.array(errs), np.array(spans)
    # within a tenth of the static strains' spread over these poses (link 2 root: hundreds of um/m)
    assert np.sqrt(np.mean(errs[:, 0] ** 2)) < 0.1 * np.ptp(spans[:, 0]), (errs, spans)


def test_the_demo_identifies_only_when_asked(tmp_path, monkeypatch):
    import tudorvision.lab.ch10 as ch10
    from tudorvision.lab.data_collection import plant_config

    calls = []
    sentinel = StrainDynamicsModel(chi=np.random.default_rng(0).normal(0.0, 1e-4, (2, 32)))

    def fake(config, options=ch10.CATCH_IDENTIFICATION, *, params=None, cache_dir=None):
        calls.append((config, options, cache_dir))
        return sentinel

    monkeypatch.setattr(ch10, "identified_strain_model", fake)
    off = DemoOptions(render=False, cache_dir=str(tmp_path), damping_model_assist=False)
    assert demo_damping_model(off) is None and not calls
    # the cancellation was measured with the proportional law: the other laws keep the seed's filter
    assert demo_damping_model(DemoOptions(render=False, cache_dir=str(tmp_path), damping="integral")) is None
    assert not calls and DemoOptions().damping_model_assist and DemoOptions().damping_gains == (0.0, 400.0, 400.0)
    # measured on the seed-measured plant: the stiff plant keeps the seed's filter
    assert demo_damping_model(DemoOptions(render=False, cache_dir=str(tmp_path), plant="stiff")) is None
    o = DemoOptions(render=False, cache_dir=str(tmp_path))
    assert demo_damping_model(o) is sentinel
    assert calls == [(plant_config("seed_measured"), ch10.CATCH_IDENTIFICATION, str(tmp_path))]   # the demo's plant
    core = SimCore(np.deg2rad([0.0, 60.0, 60.0]), params=P, damping_model=sentinel, damping_gains=(0.0, 400.0, 400.0))
    core.set_modes(damping=Damping.PROPORTIONAL, collision=0)
    assert core.controlled.damper.strain_model is sentinel


def test_the_shipped_model_of_the_demos_plant_names_this_code(tmp_path):
    """The package ships the default plant's model (the demo identifies nothing); it names the code that identified
    it, and that must be today's (the identification afresh, 1-2 min, is ``benchmarks/check_shipped_calibration.py``,
    which ships it anew)."""
    from tudorvision.lab.ch10 import CATCH_IDENTIFICATION, identification_code_hash, strain_model_key
    from tudorvision.lab.data_collection import PACKAGED_DIR, plant_config

    cfg = plant_config(DemoOptions().plant)
    shipped = PACKAGED_DIR / f"strain_model_{strain_model_key(cfg, CATCH_IDENTIFICATION)}.npz"
    assert shipped.exists()
    model = identified_strain_model(cfg, cache_dir=tmp_path)
    assert not list(tmp_path.iterdir())                                   # read from the package
    with np.load(shipped) as z:
        np.testing.assert_array_equal(model.chi, z["chi"])
        code = str(z["code"]) if "code" in z.files else None
    assert code == identification_code_hash(), (
        f"the shipped strain model was identified by other code ({code}, today {identification_code_hash()}): "
        "run .venv/bin/python benchmarks/check_shipped_calibration.py --ship")


def test_the_identification_code_hash_covers_every_file_that_runs_in_an_identification(tmp_path):
    """A short identification profiled: every package file with code that ran is in ``IDENTIFICATION_CODE_FILES``
    (or exempt), so a change to any of them names other code and the shipped model is checked again."""
    import cProfile

    from tudorvision.lab import ch10
    from tudorvision.lab.code_hash import PACKAGE_ROOT, files_run

    prof = cProfile.Profile()
    prof.runcall(ch10.identified_strain_model, PlantConfig(), Ch10Options(seconds=10.0, plates=(1,)),
                 cache_dir=tmp_path)
    ran = files_run(prof)
    assert "sim/arm.py" in ran and "joint/identification.py" in ran       # the profile saw the identification
    missing = ran - set(ch10.IDENTIFICATION_CODE_FILES) - set(ch10.IDENTIFICATION_CODE_EXEMPT)
    assert not missing, f"files that run in an identification, not in IDENTIFICATION_CODE_FILES: {sorted(missing)}"
    assert all((PACKAGE_ROOT / rel).is_file()
               for rel in ch10.IDENTIFICATION_CODE_FILES + ch10.IDENTIFICATION_CODE_EXEMPT)


def test_the_maintainer_check_keeps_an_equal_model_and_replaces_another(tmp_path, monkeypatch):
    """``check_shipped_strain_model`` with the package data in a scratch folder and synthetic runs (a known
    payload-affine model, so no simulation): a shipped model that predicts other strains is reported and, with
    ``ship``, replaced by the fresh fit; one that predicts the same keeps its coefficients, bit for bit; both get
    today's code hash."""
    import tudorvision.lab.ch10 as ch10
    import tudorvision.lab.data_collection as dc

    rng = np.random.default_rng(7)
    truth = rng.normal(0.0, 1e-4, (2, 32))

    def synthetic_run(plates, options, config, *, seed, params=None):
        r = np.random.default_rng(seed)
        n = 2000
        th = np.c_[np.zeros(n), r.uniform(0.1, 3.0, n), r.uniform(-1.0, 1.0, n)]
        d, dd = np.c_[np.zeros(n), r.normal(0, 1, (n, 2))], np.c_[np.zeros(n), r.normal(0, 3, (n, 2))]
        m = np.full(n, 0.05 + 0.1 * plates)
        eps = StrainDynamicsModel(chi=truth).predict(th, d, dd, m) + r.normal(0, 1e-6, (n, 2))
        return {"t": np.arange(n) * 0.01, "theta": th, "d": d, "dd": dd, "eps": eps, "m": m, "plates": plates}

    monkeypatch.setattr(dc, "PACKAGED_DIR", tmp_path)
    monkeypatch.setattr(ch10, "collect_aprbs_run", synthetic_run)
    cfg, opts = PlantConfig(), Ch10Options(seconds=20.0, plates=(0, 2, 4))
    path = tmp_path / f"strain_model_{ch10.strain_model_key(cfg, opts)}.npz"
    assert ch10.check_shipped_strain_model(cfg, opts)["shipped"] is False      # nothing shipped
    other = 1.5 * truth
    np.savez(path, chi=other, code=np.array("0123456789abcdef"))
    res = ch10.check_shipped_strain_model(cfg, opts)                            # compare only
    assert res["shipped"] and res["shipped_code"] == "0123456789abcdef" and not res["same"]
    assert res["max_relative_rms"] > 0.1 and res["shipped_to"] is None
    with np.load(path) as z:
        np.testing.assert_array_equal(z["chi"], other)                         # untouched without ship
    res = ch10.check_shipped_strain_model(cfg, opts, ship=True)
    assert not res["kept_coefficients"] and res["shipped_to"] == str(path)
    with np.load(path) as z:
        fresh = np.array(z["chi"])
        assert str(z["code"]) == ch10.identification_code_hash()
    run = synthetic_run(2, opts, cfg, seed=99)                                  # the fresh fit was shipped
    a = StrainDynamicsModel(chi=fresh).predict(run["theta"], run["d"], run["dd"], run["m"])
    b = StrainDynamicsModel(chi=truth).predict(run["theta"], run["d"], run["dd"], run["m"])
    assert np.sqrt(np.mean((a - b) ** 2)) < 1e-2 * np.sqrt(np.mean(b ** 2))
    nudged = fresh * (1.0 + 1e-9)                                               # the same model by its predictions
    np.savez(path, chi=nudged, code=np.array("0123456789abcdef"))
    res = ch10.check_shipped_strain_model(cfg, opts, ship=True)
    assert res["same"] and res["kept_coefficients"] and res["max_relative_rms"] < 1e-6
    with np.load(path) as z:
        np.testing.assert_array_equal(z["chi"], nudged)                         # the shipped numbers stay
        assert str(z["code"]) == ch10.identification_code_hash()


def test_catch_cli_no_model_assist(tmp_path, capsys, monkeypatch):
    import tudorvision.lab.catch_demo as catch_demo
    from tudorvision.cli import main

    assert main(["catch", str(tmp_path), "--no-model-assist"]) != 0
    assert "only with 'catch demo'" in capsys.readouterr().err
    seen = []

    def fake(out, options, recording=None):
        seen.append(options)
        raise KeyboardInterrupt                      # stop here (the CLI's controlled stop): only the options

    monkeypatch.setattr(catch_demo, "run_demo", fake)
    for argv in (["--no-model-assist"], []):
        assert main(["catch", "demo", "--no-render", "--no-rerun", "--out", str(tmp_path / "d"), *argv]) != 0
    assert (seen[0].damping_model_assist, seen[0].damping_gains) == (False, None)
    assert (seen[1].damping_model_assist, seen[1].damping_gains) == (True, (0.0, 400.0, 400.0))


def test_a_gain_table_follows_the_payload_the_layer_is_told():
    table = ((0.11, 0.0, 600.0, 400.0), (0.17, 0.0, 400.0, 400.0))
    core = SimCore(np.deg2rad([0.0, 60.0, 60.0]), params=P, damping_gains=np.ravel(table))   # flattened, as --set
    core.set_payload(0.05)
    core.set_modes(damping=Damping.PROPORTIONAL, collision=0)
    np.testing.assert_allclose(core.controlled.damper.k_eps, [0.0, 600.0, 400.0])     # below the first row
    core.set_payload(0.14)
    np.testing.assert_allclose(core.controlled.damper.k_eps, [0.0, 500.0, 400.0])     # halfway
    core.set_payload(0.26)
    np.testing.assert_allclose(core.controlled.damper.k_eps, [0.0, 400.0, 400.0])     # beyond the last
    assert DemoOptions(damping_gains=np.ravel(table).tolist()).damping_gains is not None
    for bad in (((0.17, 0, 600, 400), (0.11, 0, 400, 400)), (0.1, 0, 1, 2, 3), ((0.1, 0, -1, 2),)):
        with pytest.raises(ValueError, match="damping_gains"):
            SimCore(params=P, damping_gains=bad)
