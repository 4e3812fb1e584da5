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


def test_the_shipped_model_of_the_demos_plant_is_what_identification_gives(tmp_path):
    """The package ships the default plant's model (the demo identifies nothing); it must be today's result."""
    from tudorvision.lab.ch10 import CATCH_IDENTIFICATION, strain_model_key
    from tudorvision.lab.data_collection import PACKAGED_DIR, plant_config

    cfg = plant_config(DemoOptions().plant)
    shipped = PACKAGED_DIR / f"strain_model_{strain_model_key(cfg, CATCH_IDENTIFICATION)}.npz"
    assert shipped.exists()
    model = identified_strain_model(cfg, cache_dir=tmp_path)
    assert not list(tmp_path.iterdir())                                   # read from the package
    with np.load(shipped) as z:
        np.testing.assert_array_equal(model.chi, z["chi"])
    from tudorvision.joint.identification import fit_with_validation
    from tudorvision.lab.ch10 import collect_aprbs_run

    o = CATCH_IDENTIFICATION
    runs = [collect_aprbs_run(pl, o, cfg, seed=o.seed0 + k) for k, pl in enumerate(o.plates)]
    fresh, _ = fit_with_validation(runs)                                  # identified again: the same model
    # compared by what it predicts: the small coefficients of the least-squares fit move by up to 25 % between
    # numpy / LAPACK builds (the fit is ill-conditioned there), the strains it predicts by 1e-4 of their RMS; a
    # change to the plant or the identification moves them by far more
    for r in runs:
        a = fresh.predict(r["theta"], r["d"], r["dd"], r["m"])
        b = model.predict(r["theta"], r["d"], r["dd"], r["m"])
        rel = np.sqrt(np.mean((a - b) ** 2, axis=0)) / np.sqrt(np.mean(r["eps"] ** 2, axis=0))
        assert np.all(rel < 1e-3), rel


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
