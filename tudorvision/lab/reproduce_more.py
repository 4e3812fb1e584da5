"""Sections of ``tudorvision reproduce`` for chapter 8 (damping), the payload's deflection and catching.

They call the experiments of :mod:`tudorvision.lab.ch8_reproduce`,
:mod:`tudorvision.lab.ch8_extra` and :mod:`tudorvision.lab.catch.reproduce_rows`
on the soft (seed-measured) plant and turn their numbers into rows beside
the seed's. Chapter 8 is run with the seed's static-strain filter (the
moving average applied twice, section 2.2) as the reference; the project's
2 kHz filter is given beside it.
"""
from __future__ import annotations

import math
from dataclasses import asdict
from pathlib import Path

from .reproduce_table import Row, Section

__all__ = ["MORE_SECTIONS", "CATCH_CALIBRATIONS", "CATCH_HELD_OUT_OFFSETS", "damping_section", "damping_extra_section",
           "deflection_section", "catch_section", "catch_held_out_section"]

_LAWS = ("proportional", "integral", "half_integrator")
_LAW_NAMES = {"proportional": "proportional", "integral": "integral", "half_integrator": "half-integrator"}


def _num(x):
    return None if x is None or (isinstance(x, float) and not math.isfinite(x)) else float(x)


def damping_section(out_dir: str, quick: bool, seed: int) -> dict:
    """Chapter 8: figure 8.2 (settling cut of experiment 06, maximum strain), the integral law's drift, 8.3 sweep.

    Parameters
    ----------
    out_dir : str
        Output folder (runner records in ``ch8/``).
    quick : bool
        3 experiments and 1 noise seed, 3 drift cycles, 0/300/600 g (full: 12 experiments x 5 seeds,
        10 cycles, 0-600 g x 5 seeds).
    seed : int
        Unused (the runs' noise seeds come from the chapter-8 runner keys); part of the key.

    Returns
    -------
    dict
        ``rows``, ``figures``, ``notes``.
    """
    from .ch8_reproduce import integral_drift, payload_sweep_8_3, table_8_2
    root = Path(out_dir) / "ch8"
    t = table_8_2(quick, "serial", out=root)
    fs, f2, fi = t["filters"]["seed"], t["filters"]["2khz"], t["filters"].get("seed-iir")
    size = f"experiments {', '.join(t['experiments'])}, {t['reps']} noise seed(s), 300 g, soft plant"
    rows = []
    for law in _LAWS:
        rows.append(Row("8.2, fig. 8.2", f"exp. 06 strain settling cut, {_LAW_NAMES[law]} (seed's filter)", 80.0,
                        _num(fs["exp06_settling_cut_pct"][law]), "%", "within:0.10",
                        f"2 kHz filter {f2['exp06_settling_cut_pct'][law]:.0f} %"
                        + (f", seed's IIR variant {fi['exp06_settling_cut_pct'][law]:.0f} %" if fi else "")
                        + f"; {size}"))
    for group in ("medium", "large"):
        for law in _LAWS:
            seed_v = t["seed"]["max_strain_pct"][group][law]
            lab = fs["max_strain_pct"].get(group, {}).get(law)
            rows.append(Row("8.2, fig. 8.2", f"maximum strain, {group} steps, {_LAW_NAMES[law]} (% of undamped)",
                            seed_v, _num(lab), "%", "info", "the seed's bars read off the figure (about)"))
    d = integral_drift(quick)
    for law in _LAWS:
        r = d[law]
        rows.append(Row("8.6 (6.6)", f"steady-state joint error growth, {_LAW_NAMES[law]}",
                        "grows" if law == "integral" else "none", _num(r["growth_deg_per_cycle"]), "deg/cycle", "info",
                        f"{d['cycles']} out-and-back moves of exp. 06; error first {r['abs_error_deg_first']:.3f}, "
                        f"largest {r['abs_error_deg_max']:.3f}, last {r['abs_error_deg_last']:.3f} deg"))
    s = payload_sweep_8_3(quick, "serial", out=root)
    for grams in sorted(s["settling_cut_pct"]["proportional"], key=int):
        seed_v = s["seed"]["settling_cut_pct"].get(int(grams))
        rows.append(Row("8.3, fig. 8.3", f"exp. 06 settling cut with {grams} g, proportional (gains of 300 g)",
                        seed_v, _num(s["settling_cut_pct"]["proportional"][grams]), "%",
                        "within:0.10" if seed_v is not None else "info",
                        "half-integrator {:.0f} %, integral {:.0f} %".format(
                            s["settling_cut_pct"]["half_integrator"][grams], s["settling_cut_pct"]["integral"][grams])))
    return {"rows": [asdict(r) for r in rows], "figures": [], "notes": []}


def damping_extra_section(out_dir: str, quick: bool, seed: int) -> dict:
    """Chapter 8: the near-resonant periodic force, the 600 g drop into the net and damping at one actuator.

    Parameters
    ----------
    out_dir : str
        Output folder.
    quick : bool
        Short runs, one switching phase (full: three phases, longer horizons, the joint-3 gain scan).
    seed : int
        Unused; part of the key.

    Returns
    -------
    dict
        ``rows``, ``figures``, ``notes``.
    """
    from .ch8_extra import one_actuator_damping_8_5, payload_drop_8_4, periodic_disturbance_8_4
    rows = []
    p = periodic_disturbance_8_4(quick)
    f = f"{p['freq_hz']:.2f} Hz, {p['force_N']:g} N at the end effector"
    for law, r in p["laws"].items():
        rows.append(Row("8.4", f"periodic force near resonance: amplitude undamped, {_LAW_NAMES.get(law, law)} run",
                        p["seed"]["undamped_um_m"], _num(r["before_um_m"]), "µm/m", "info",
                        f + " (the force is chosen to give about the seed's undamped amplitude)"))
        rows.append(Row("8.4", f"periodic force near resonance: amplitude damped, {_LAW_NAMES.get(law, law)}",
                        p["seed"]["damped_um_m"], _num(r["after_um_m"]), "µm/m", "within:0.10", f))
    d = payload_drop_8_4(quick)
    for law in [k for k in d["laws"] if k != "off"]:
        rows.append(Row("8.4", f"600 g dropped into the net: strain settled, {_LAW_NAMES.get(law, law)}",
                        d["seed"]["damped_settle_s"], _num(d["laws"][law]["settle_s"]), "s", "max:2",
                        f"undamped {d['laws']['off']['settle_s']:.1f} s; settled: within the 15 µm/m band"))
    o = one_actuator_damping_8_5(quick)
    for law in [k for k in o["laws"] if k != "off"]:
        r = o["laws"][law]
        rows.append(Row("8.5", f"damping at joint 3 only, {_LAW_NAMES.get(law, law)}: exp. 06 settling cut",
                        "between none and both", _num(r["joint3_only"]["cut_pct"]), "%", "info",
                        f"both actuators {r['both']['cut_pct']:.0f} %; time-weighted strain (IATS) "
                        f"{r['joint3_only']['iats_pct']:.0f} % of undamped (both {r['both']['iats_pct']:.0f} %)"))
    return {"rows": [asdict(r) for r in rows], "figures": [], "notes": []}


def deflection_section(out_dir: str, quick: bool, seed: int) -> dict:
    """Section 9.1's premise: the static end-effector deflection a payload introduces, soft plant.

    Parameters
    ----------
    out_dir : str
        Output folder.
    quick : bool
        The held (simulated) deflection at the servo goal pose only.
    seed : int
        Unused; part of the key.

    Returns
    -------
    dict
        ``rows``, ``figures``, ``notes``.
    """
    from .ch8_reproduce import deflection_consistency, static_deflection
    s = static_deflection(quick)
    lo = s["seed"]["implied_min_mm"]
    rows = []
    for change, label in (("+400g_on_camera", "+400 g on the camera rig"), ("+450g_camera", "the 450 g camera")):
        rows.append(Row("9.1", f"static end-effector deflection, {label}, largest over the poses",
                        f"≥ {lo['from_90pct_8mm']:g} mm", _num(s[f"max_static_mm_{change}"]), "mm",
                        f"min:{lo['from_90pct_8mm']:g}",
                        "the seed: repeatability below 10 % of the static deflection (90 % under 8 mm)"))
    c = deflection_consistency(lo["from_90pct_8mm"])
    rows.append(Row("9.1 (A.1)", "static deflection, +400 g at full stretch, the A.1 blades alone (rigid clamps)",
                    round(c["blades_closed_form_mm"], 1), _num(c["blades_lab_mm"]), "mm", "within:0.1",
                    "seed value: Euler-Bernoulli closed form from appendix A.1 (E 200 GPa, 15 x 4 mm, 430 / 410 mm); "
                    f"lab: rigid hubs; the soft plant's hubs add {c['soft_lab_mm'] - c['blades_lab_mm']:.1f} mm"))
    rows.append(Row("9.1 / 4.7", f"link 2 first mode at theta = 0, 300 g, with a joint-2 hub soft enough for "
                    f"{lo['from_90pct_8mm']:g} mm", 2.0, _num(c["link2_first_hz_for_target"]), "Hz", "within:0.1",
                    f"hub {c['hub2_for_target_Nm_rad']:.0f} N m/rad instead of the identified "
                    f"{c['hub2_identified_Nm_rad']:.0f} ({c['link2_first_hz_identified']:.2f} Hz): the seed's "
                    "blades and its 2.0 Hz mode do not allow the 80 mm reading"))
    return {"rows": [asdict(r) for r in rows], "figures": [], "notes": []}


#: Wall-camera calibrations the catching sections take in turn (one disc sweep each; issue 18's family).
CATCH_CALIBRATIONS = 8

#: The catching demo's seeds never looked at while its rules were tuned, as offsets from ``--seed``
#: (the rules were chosen on seeds 0 and 1; 100 and 200 vetoed some; 300-600 were only ever measured).
CATCH_HELD_OUT_OFFSETS = (300, 400, 500, 600)


def _catch_rows(c: dict, which: str, note: str) -> list:
    rate = None if c["success_rate"] is None else 100.0 * c["success_rate"]
    rate_c = None if c["success_rate_centre"] is None else 100.0 * c["success_rate_centre"]
    return [Row("9.3", f"catch success, whole ball through the ring, {which}", "> 66 % (lenient)", rate, "%",
                "min:95", note),
            Row("9.3", f"catch success, ball centre within the net radius, {which}", "> 66 %", rate_c, "%",
                "min:66", "the earlier, lenient criterion")]


def _catch_notes(c: dict) -> list:
    misses = ", ".join(f"{k} {v}" for k, v in sorted(c["misses"].items()) if v)
    return [f"misses: {misses}"] if misses else []


def catch_section(out_dir: str, quick: bool, seed: int) -> dict:
    """Section 9.3: catching success under the strict criterion (the whole ball through the ring).

    The sessions take :data:`CATCH_CALIBRATIONS` wall-camera calibrations in turn.

    Parameters
    ----------
    out_dir : str
        Output folder (runner records in ``catch/``).
    quick : bool
        120 throws (about 50 cross the workspace) instead of 2000 (about 840).
    seed : int
        Seed of the throws.

    Returns
    -------
    dict
        ``rows``, ``figures``, ``notes``.
    """
    from .catch.reproduce_rows import catch_success
    n = 120 if quick else 2000
    c = catch_success(n, seed, "serial", out=Path(out_dir) / "catch", calibrations=CATCH_CALIBRATIONS)
    note = (f"{c['caught']} of {c['crossing']} throws crossing the workspace ({n} thrown, {CATCH_CALIBRATIONS} "
            "wall-camera calibrations in turn); soft plant, wall camera calibrated from the disc sweep, "
            "detection-noise model; seed 0 is the one the demo's rules were tuned on")
    return {"rows": [asdict(r) for r in _catch_rows(c, f"seed {seed}", note)], "figures": [],
            "notes": _catch_notes(c)}


def catch_held_out_section(out_dir: str, quick: bool, seed: int) -> dict:
    """Section 9.3 on seeds never tuned on: ``seed`` + :data:`CATCH_HELD_OUT_OFFSETS`, 480 throws each.

    Parameters
    ----------
    out_dir : str
        Output folder (runner records in ``catch-held-out/seed<S>/``).
    quick : bool
        60 throws of the first of those seeds instead of 480 of each (about 850 crossing in all).
    seed : int
        Base seed (the default 0 gives seeds 300, 400, 500 and 600).

    Returns
    -------
    dict
        ``rows``, ``figures``, ``notes``.
    """
    from .catch.reproduce_rows import catch_success_seeds
    seeds = [seed + k for k in CATCH_HELD_OUT_OFFSETS[:1 if quick else None]]
    n = 60 if quick else 480
    c = catch_success_seeds(n, seeds, "serial", out=Path(out_dir) / "catch-held-out", calibrations=CATCH_CALIBRATIONS)
    each = ", ".join(f"{r['caught']} / {r['crossing']}" for r in c["per_seed"])
    note = (f"{c['caught']} of {c['crossing']} throws crossing the workspace; seeds {', '.join(map(str, seeds))} "
            f"({n} thrown each, {CATCH_CALIBRATIONS} calibrations in turn; per seed {each}), never looked at "
            "while the demo's rules were chosen")
    return {"rows": [asdict(r) for r in _catch_rows(c, "seeds never tuned on", note)], "figures": [],
            "notes": _catch_notes(c)}


#: Sections added to :data:`tudorvision.lab.reproduce_sections.SECTIONS`.
MORE_SECTIONS = (
    Section("damping", "8", "damping laws: figs. 8.2, 8.3, the integral drift (6.6, 8.6)", damping_section, 3.0, 60.0),
    Section("damping-extra", "8", "periodic force, 600 g drop, one actuator (8.4, 8.5)", damping_extra_section,
            2.0, 10.0),
    Section("deflection", "9", "static deflection a payload introduces (9.1)", deflection_section, 0.5, 2.0),
    Section("catch", "9", "ball catching, strict criterion (9.3)", catch_section, 5.0, 50.0),
    Section("catch-held-out", "9", "ball catching on seeds never tuned on (9.3, issue 18)", catch_held_out_section,
            3.0, 50.0),
)
