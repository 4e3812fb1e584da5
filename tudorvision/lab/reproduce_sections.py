"""The sections of ``tudorvision reproduce``: each runs one of the seed's experiments in the lab.

Every section is a module-level function ``fn(out_dir, quick, seed) -> dict``
(a task of the experiment runner: everything it needs travels as its
arguments) returning ``rows`` (:class:`~tudorvision.lab.reproduce.Row` as
dicts), ``figures`` (paths relative to ``out_dir``) and ``notes``. ``quick``
shrinks every experiment to about a minute; the numbers are then indicative.
The seed's values are quoted from the dissertation (sections named in each
row); targets from the issues are written as ``max:``/``min:`` rules.
"""
from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import numpy as np

from .reproduce_table import Row, Section

__all__ = ["SECTIONS", "plant_section", "servo_section", "depth_noise_section", "models_section",
           "collision_section", "rail_section"]

#: The seed's measured modes and workspace map with 300 g (sections 4.7, 4.8, figures 4.6, 4.8).
SEED_CH4 = {"link2_hz": (2.0, 9.9), "link3_hz": 6.3, "f1_range_hz": (1.56, 2.74), "decay_range_per_s": (0.03, 1.24)}


def _rows(*rows: Row) -> list:
    return [asdict(r) for r in rows]


# --------------------------------------------------------------------------- chapter 4

def _plot_modes_map(path: Path, m: dict) -> None:
    from matplotlib.figure import Figure

    from ..io.atomic import atomic_path
    t2, t3 = np.array(m["theta2_deg"]), np.array(m["theta3_deg"])
    step = t2[1] - t2[0] if len(t2) > 1 else 10.0
    ext = [t2[0] - step / 2, t2[-1] + step / 2, t3[0] - step / 2, t3[-1] + step / 2]
    fig = Figure(figsize=(8.0, 3.0))
    ax = fig.subplots(1, 2)
    for k, (key, title) in enumerate((("ringdown_hz", "first frequency [Hz]"), ("decay_per_s", "decay ζ₁ [1/s]"))):
        im = ax[k].imshow(np.array(m[key]), origin="lower", extent=ext, aspect="auto", cmap="viridis")
        ax[k].set_xlabel("θ2 [deg]")
        ax[k].set_ylabel("θ3 [deg]")
        ax[k].set_title(f"lab, 300 g: {title}", fontsize=9)
        fig.colorbar(im, ax=ax[k])
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=80, format="png")


def plant_section(out_dir: str, quick: bool, seed: int) -> dict:
    """Chapter 4: link modes at 300 g (figure 4.6) and the workspace map of frequency and decay (figure 4.8).

    Parameters
    ----------
    out_dir : str
        Output folder (the map's PNG goes to ``figures/``).
    quick : bool
        A 45 deg grid instead of the seed's 10 deg.
    seed : int
        Unused (the plant runs are deterministic); part of the runner's key.

    Returns
    -------
    dict
        ``rows``, ``figures``, ``notes``.
    """
    from ..sim.arm import PlantConfig
    from .plant_modes import SEED_HOLD_TIME_CONSTANTS_S, linear_modes, modes_map, plant_modes
    cfg = PlantConfig.seed_measured()
    fig46 = linear_modes(np.deg2rad([0.0, 0.0, 0.0]), 0.3, cfg)
    step = 45.0 if quick else 10.0
    m = modes_map(step, 0.3, cfg)
    F, Z = np.array(m["ringdown_hz"]), np.array(m["decay_per_s"])
    # the slowest pose of the full map held by the softer loop the layer ran before issue 18's identification
    softer = plant_modes(np.deg2rad([0.0, 190.0, 10.0]), 0.3, cfg, duration_s=6.0, servo_time_constants_s=(0.003, 0.01))
    t_d_ms, t_l_ms = (1e3 * x for x in SEED_HOLD_TIME_CONSTANTS_S)
    held = (f"the joint layer's holding loop, identified on this map (t_d / t_l {t_d_ms:g} / {t_l_ms:g} ms; "
            "the seed gives no values; docs/simulation.md)")
    fig = Path("figures") / "ch4_modes_map.png"
    _plot_modes_map(Path(out_dir) / fig, m)
    grid = f"{len(m['theta2_deg'])} x {len(m['theta3_deg'])} poses, {step:g} deg grid, 6 s ring-downs"
    w10 = "within:0.10"
    rows = _rows(
        Row("4.7, fig. 4.6", "link 2 first mode, 300 g, θ = 0", SEED_CH4["link2_hz"][0], fig46["link2_hz"][0], "Hz", w10,
            "linearised, seed-measured plant"),
        Row("4.7, fig. 4.6", "link 2 second mode, 300 g", SEED_CH4["link2_hz"][1], fig46["link2_hz"][1], "Hz", w10),
        Row("4.7, fig. 4.6", "link 3 first mode, 300 g", SEED_CH4["link3_hz"], fig46["link3_hz"][0], "Hz", w10),
        Row("4.8, fig. 4.8", "first frequency, minimum over the workspace", SEED_CH4["f1_range_hz"][0],
            float(F.min()), "Hz", w10, grid),
        Row("4.8, fig. 4.8", "first frequency, maximum over the workspace", SEED_CH4["f1_range_hz"][1],
            float(F.max()), "Hz", w10),
        Row("4.8, fig. 4.8", "decay of the first mode, minimum", SEED_CH4["decay_range_per_s"][0], float(Z.min()),
            "1/s", w10, held),
        Row("4.8, fig. 4.8", "decay of the first mode, maximum", SEED_CH4["decay_range_per_s"][1], float(Z.max()),
            "1/s", w10),
        Row("4.8, fig. 4.8", "decay at θ = (0, 190, 10) deg under the softer 3 / 10 ms loop",
            SEED_CH4["decay_range_per_s"][0], float(softer["decay_per_s"]), "1/s", "info",
            "the loop the layer ran before: its joints give way to the swing and dissipate it"),
    )
    notes = [] if not quick else ["the quick grid (45 deg) misses the lowest-frequency pose θ = (0, 90, 0) deg"]
    return {"rows": rows, "figures": [str(fig)], "notes": notes, "map": m}


# --------------------------------------------------------------------------- chapter 9

def servo_section(out_dir: str, quick: bool, seed: int) -> dict:
    """Section 9.1: repeatability of the hybrid visual servo (8 start poses x 3 payloads x N repetitions).

    Parameters
    ----------
    out_dir : str
        Output folder (the runs go to ``servo/``).
    quick : bool
        One repetition (24 runs) instead of the seed's 20 (480 runs).
    seed : int
        Seed of the experiment.

    Returns
    -------
    dict
        ``rows``, ``figures``, ``notes``.
    """
    from .servo_experiments import repeatability
    reps = 1 if quick else 20
    s = repeatability(Path(out_dir) / "servo", repetitions=reps, seed=seed, laws=("hybrid",), workers=1,
                      scheduler="serial", show_progress=False)
    n = f"hybrid law, {s['runs_done']} runs ({reps} per start pose and payload); the issue's goal 2 / 4 / 7 mm"
    rows = _rows(
        Row("9.1", "servo end error, mean", 4.0, 1e3 * s["mean_error_m"], "mm", "max:2", n),
        Row("9.1", "servo end error, 90th percentile", 8.0, 1e3 * s["p90_error_m"], "mm", "max:4"),
        Row("9.1", "servo end error, enclosing radius", 14.0, 1e3 * s["radius_m"], "mm", "max:7"),
        Row("9.1", "runs converged", "all", 100.0 * s["convergence_rate"], "%", "min:100"),
    )
    return {"rows": rows, "figures": [], "notes": []}


def depth_noise_section(out_dir: str, quick: bool, seed: int) -> dict:
    """Sections 2.3 / 9.3: the depth noise sigma_z(z) calibrated from planar-target recordings of the lab's sensor.

    Parameters
    ----------
    out_dir : str
        Output folder (recordings in ``depth_plane/``).
    quick : bool
        4 distances x 10 frames instead of 12 x 100.
    seed : int
        Seed of the recordings.

    Returns
    -------
    dict
        ``rows``, ``figures``, ``notes``.
    """
    from ..io import open_sequence
    from ..rgbd.depth_model import calibrate_depth_model
    from ..rgbd.frames import Intrinsics
    from ..sensors import KINECT_SIGMA_Z_COEFFS
    from .record import RecordOptions, record_rgbd_plane
    root = record_rgbd_plane(Path(out_dir) / "depth_plane",
                             RecordOptions(seed=seed, small=quick, frames=10 if quick else 100, show_progress=False,
                                           force=True))
    stacks, nominal, K = [], [], None
    for sub in sorted(p for p in Path(root).iterdir() if (p / "sequence.yaml").is_file()):
        seq = open_sequence(sub)
        try:
            if K is None:
                cam = next(iter(seq.calibration.cameras.values()))
                K = Intrinsics.from_matrix(cam.K, cam.width, cam.height)
            stacks.append(np.stack([f.depth_m for f in seq]))
            nominal.append(float(np.median(seq.groundtruth("target")["distance_m"])))
        finally:
            seq.close()
    model, table = calibrate_depth_model(stacks, K, nominal_distances_m=nominal)
    seed_mm = {z: float(np.polyval(KINECT_SIGMA_Z_COEFFS, z)) for z in (1.0, 2.0, 5.0)}
    rows = []
    for z in (1.0, 2.0, 5.0):
        rows.append(asdict(Row("9.3 (2.3, fig. 2.5)", f"depth noise σz at {z:g} m (calibrated)", seed_mm[z],
                               1e3 * float(np.polyval(model.coeffs, z)), "mm", "within:0.10",
                               "the seed's polynomial read in mm; lab fit over " +
                               ", ".join(f"{r.distance_m:.1f}" for r in table) + " m")))
    return {"rows": rows, "figures": [], "notes": []}


# --------------------------------------------------------------------------- chapter 10

def models_section(out_dir: str, quick: bool, seed: int) -> dict:
    """Chapter 10, table 10.1: the strain-referred and the motor-current dynamics models, validation fits.

    Parameters
    ----------
    out_dir : str
        Output folder.
    quick : bool
        20 s of APRBS motion per payload instead of 60 s.
    seed : int
        Offset of the runs' seeds.

    Returns
    -------
    dict
        ``rows``, ``figures``, ``notes``.
    """
    from ..sim.arm import PlantConfig
    from .ch10 import Ch10Options, reproduce_table_10_1, summarize_table_10_1, with_current_noise
    opts = Ch10Options(seconds=20.0 if quick else 60.0, seed0=900 + 10 * int(seed))
    res = reproduce_table_10_1(PlantConfig.seed_measured(), opts)
    s = summarize_table_10_1(res)
    noisy = summarize_table_10_1(reproduce_table_10_1(None, opts, runs=with_current_noise(res["runs"], 0.15, seed)))
    w10 = "within:0.10"
    cur, st, cn = s["current"], s["strain"], noisy["current"]
    per = f"{opts.seconds:g} s APRBS per payload (seed: 10 x 80 s), validation blocks, mean over 0-400 g"
    rows = _rows(
        Row("10.5, table 10.1", "strain model fit (AN column), validation", st["seed_AN_validation_mean"],
            st["lab_validation_mean"], "%", w10, per),
        Row("10.5, table 10.1", "current model fit, noise-free currents", cur["seed_AN_validation_mean"],
            cur["lab_validation_mean"], "%", "info", "the lab's currents carry no amplifier noise"),
        Row("10.5, table 10.1", "current model fit, 0.15 A current noise", cn["seed_AN_validation_mean"],
            cn["lab_validation_mean"], "%", w10, "white noise of a real amplifier's current measurement"),
    )
    return {"rows": rows, "figures": [], "notes": []}


# --------------------------------------------------------------------------- chapter 11

def collision_section(out_dir: str, quick: bool, seed: int) -> dict:
    """Chapter 11: identification, 6-sigma thresholds, false positives and contacts with the stop strategy.

    The lab's default (soft) plant with the collision runs' damping
    (:data:`~tudorvision.lab.collision_experiments.SOFT_COLLISION_K_EPS`); thresholds
    scheduled on the known payload (per payload the larger of its own and the pooled
    6 sigma, :func:`~tudorvision.joint.collision_thresholds.payload_thresholds`);
    isolation on the decoupled link-3 residual; contacts on link 3 and link 2 at 300 g
    and 400 g. Identification, thresholds and false positives use different seeds.

    Parameters
    ----------
    out_dir : str
        Output folder.
    quick : bool
        20 s identification and threshold runs per payload and 1 minute of false-positive motion (full: 60 s
        and 10 minutes).
    seed : int
        Offset of the runs' seeds.

    Returns
    -------
    dict
        ``rows``, ``figures``, ``notes``.
    """
    from ..joint.collision import fit_residual_coupling
    from ..joint.collision_thresholds import payload_thresholds
    from ..joint.identification import fit_with_validation
    from .collision_experiments import (PLATES, CollisionSetup, contact_run, identification_run, residual_run)
    setup = CollisionSetup()
    sec = 20.0 if quick else 60.0
    fp_min = 1.0 if quick else 10.0
    s0 = 1000 * int(seed)
    model, _ = fit_with_validation([identification_run(setup, pl, sec, s0 + 100 + pl) for pl in PLATES])
    chi = np.asarray(model.chi)
    rs = [residual_run(setup, pl, sec, s0 + 200 + pl, chi, [np.inf, np.inf], "none", None, True) for pl in PLATES]
    _, thr = payload_thresholds([r["res"] for r in rs])
    cp = fit_residual_coupling(np.concatenate([r["res"] for r in rs]),
                               np.concatenate([np.full(r["res"].shape[0], r["payload"]) for r in rs]))
    cpl = [float(cp.c0), float(cp.c1), float(cp.threshold)]
    per = fp_min * 60.0 / len(PLATES)
    fp = sum(len(residual_run(setup, pl, per, s0 + 300 + pl, chi, thr[pl], "none", cpl, False)["detections"])
             for pl in PLATES)
    rows = [asdict(Row("11.1", "false positives, collision-free motion 0-400 g", 0, float(fp), "events", "max:0",
                       f"{fp_min:g} min of random motion, thresholds 6σ per payload from {sec:g} s runs"))]
    for plates in (3, 4):
        contacts = {k: contact_run(setup, k, "stop", chi, thr[plates], cpl, plates) for k in ("link3", "link2")}
        for k, c in contacts.items():
            link = 3 if k == "link3" else 2
            delay = c.get("delay_ms")
            rows.append(asdict(Row("11.3", f"detection delay, contact on link {link} ({100 * plates} g, stop)", "–",
                                   None if delay is None else float(delay), "ms", "max:20",
                                   "the issue's target (the seed gives no delay)")))
            rows.append(asdict(Row("11.3", f"isolated link, contact on link {link} ({100 * plates} g)", float(link),
                                   None if c.get("link") is None else float(c["link"]), "", "within:0")))
        c3 = contacts["link3"]
        if plates == 3 and c3.get("peak_force_N"):
            rows.append(asdict(Row("11.3, fig. 11.3", "end-effector contact: steady force / peak force (stop)",
                                   100 * 0.17 / 1.90, 100 * float(c3["final_force_N"]) / float(c3["peak_force_N"]),
                                   "%", "info",
                                   f"peak {float(c3['peak_force_N']):.2f} N (seed 1.90 N on its contact cube)")))
    return {"rows": rows, "figures": [], "notes": []}


# --------------------------------------------------------------------------- appendix B.5

def rail_section(out_dir: str, quick: bool, seed: int) -> dict:
    """Appendix B.5: stereo accuracy along a vertical rail, band of the per-height mean deviation per axis.

    Parameters
    ----------
    out_dir : str
        Output folder (renders in ``rail/``).
    quick : bool
        5 frames at every second height, workspace centre only (full: 20 frames, 25 heights, both places).
    seed : int
        Seed of the room and noise.

    Returns
    -------
    dict
        ``rows``, ``figures``, ``notes``.
    """
    from .rail import RAIL_HEIGHTS_M
    from .rail_eval import evaluate_rail, render_rail
    frames, heights = (5, RAIL_HEIGHTS_M[::2]) if quick else (20, RAIL_HEIGHTS_M)
    places = ("centre",) if quick else ("centre", "border")
    rows = []
    for place in places:
        path = render_rail(Path(out_dir) / "rail", seed, place, frames, heights, ".jpg")
        r = evaluate_rail(path, methods=("ours", "moment"))
        band = r["ours"]["fit_band_inside_mm"]
        for axis, b in zip("xyz", band):
            rows.append(asdict(Row("B.5, fig. B.3", f"{place} rail: band of the mean deviation, {axis} axis", 2.0,
                                   float(b), "mm", "max:2",
                                   f"inside the workspace; {frames} frames x {len(heights)} heights; "
                                   f"valid {100 * r['ours']['valid']:.0f} %; seed's centroid "
                                   f"{r['moment']['fit_band_inside_mm']['xyz'.index(axis)]:.2f} mm")))
    return {"rows": rows, "figures": [], "notes": []}


def _extra_sections() -> list:
    from .reproduce_more import MORE_SECTIONS
    return list(MORE_SECTIONS)


#: The reproduction's sections in report order.
SECTIONS = (
    Section("plant", "4", "link modes and the workspace map (figs. 4.6, 4.8)", plant_section, 1.0, 15.0),
    *_extra_sections(),
    Section("servo", "9", "hybrid visual servo repeatability (9.1)", servo_section, 1.5, 25.0),
    Section("depth", "9", "depth noise of the RGB-D sensor (2.3, 9.3)", depth_noise_section, 0.5, 3.0),
    Section("models", "10", "strain and current dynamics models (table 10.1)", models_section, 1.5, 5.0),
    Section("collision", "11", "collision detection and isolation (11.1, 11.3)", collision_section, 2.0, 10.0),
    Section("rail", "B.5", "stereo accuracy along a vertical rail", rail_section, 1.5, 15.0),
)
