"""Benchmark: the rest of chapter 8 of the seed (8.4 external disturbances, 8.5 one-actuator damping).

Runs the three experiments of :mod:`tudorvision.lab.ch8_extra` on the soft plant
identified on the seed's measured modes (``PlantConfig.seed_measured()``), with the
joint layer's tuned gains and the seed's static strain filter, and prints each
lab number beside the seed's and beside the undamped arm (the peers), with ratios:

* 8.4 periodic excitation near the first resonance: strain amplitude before / after
  the damping is switched on (seed: ~400 -> ~100 um/m, a factor of 4);
* 8.4 disturbance steps, 600 g dropped from 0.5 m into the 120 g net at operating
  point 5: time until the link-2 root strain stays within 15 um/m (seed: damped in
  about 2 s), plus the same with the mass put in at rest (``drop_height_m = 0``);
* 8.5 experiment 06 damped by joint 3 only: strain settling cut against none and
  both joints (seed: between the two, half-integrator better).

Run:  nice .venv/bin/python benchmarks/bench_ch8_extra.py [--quick] [--out out/ch8_extra]
      [--figures docs/figures]
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

from _machine import cpu_model  # benchmarks/ is on sys.path
from tudorvision.io.atomic import write_text_atomic
from tudorvision.lab.ch8_extra import one_actuator_damping_8_5, payload_drop_8_4, periodic_disturbance_8_4


def _plain(x):
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items() if k != "series"}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    return x


def _fig_periodic(r, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    s = r["series"]
    fig, ax = plt.subplots(figsize=(8, 3.2))
    t_on = r["t_on_s"]
    for law, c in (("proportional", "C0"), ("half_integrator", "C1")):
        if law in s:
            m = s[law]["t"] > t_on - 4.0
            ax.plot(s[law]["t"][m] - t_on + 4.0, 1e6 * (s[law]["eps"][m] - s[law]["eps"][m].mean()), color=c,
                    lw=0.8, label=law)
    ax.axvline(4.0, color="k", ls=":", lw=0.8)
    for y in (100, -100, 400, -400):
        ax.axhline(y, color="0.8", lw=0.5)
    ax.set_xlabel("time, s (undamped until 4 s, then the law's gains)")
    ax.set_ylabel("link-2 root strain, um/m")
    ax.set_title(f"8.4 periodic force at {r['freq_hz']:.2f} Hz, {r['force_N']:.2f} N (seed: 400 -> 100 um/m)")
    ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _fig_series(r, keys, ylabel, title, path, t_max=None):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    s = r["series"]
    fig, ax = plt.subplots(figsize=(8, 3.2))
    for i, k in enumerate(keys):
        if k in s:
            ax.plot(s[k]["t"], 1e6 * s[k]["eps_dyn"], lw=0.8, label=k, color="0.5" if k == "off" else f"C{i}")
    ax.axhspan(-15, 15, color="C2", alpha=0.15, lw=0)
    if t_max:
        ax.set_xlim(0, t_max)
    ax.set_xlabel("time, s")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the short versions (about a minute in all)")
    ap.add_argument("--out", default="out/ch8_extra", help="folder of results.json")
    ap.add_argument("--figures", default=None, help="write ch8_extra_*.png into this folder")
    a = ap.parse_args(argv)
    os.makedirs(a.out, exist_ok=True)
    keep = a.figures is not None
    res, wall = {}, {}
    for name, fn, kw in (("periodic_8_4", periodic_disturbance_8_4, {}),
                         ("drop_8_4", payload_drop_8_4, {}),
                         ("drop_8_4_at_rest", payload_drop_8_4, {"drop_height_m": 0.0}),
                         ("one_actuator_8_5", one_actuator_damping_8_5, {})):
        t0 = time.perf_counter()
        res[name] = fn(quick=a.quick, keep_series=keep, **kw)
        wall[name] = time.perf_counter() - t0
        print(f"[{name}: {wall[name]:.1f} s wall]", file=sys.stderr)

    p = res["periodic_8_4"]
    seed = p["seed"]
    print(f"8.4 periodic: {p['freq_hz']:.3f} Hz (first mode {p['first_mode_hz']:.3f} Hz), force {p['force_N']:.3f} N,"
          f" damping on at {p['t_on_s']:.0f} s (+ phases {[round(x, 3) for x in p['phases_s']]} s)")
    print(f"  {'law':16s} {'before':>8s} {'after':>8s} {'factor':>7s} | seed {seed['undamped_um_m']:.0f} -> "
          f"{seed['damped_um_m']:.0f} (factor {seed['reduction']:.1f}) | ours/seed after, factor")
    for law, v in p["laws"].items():
        print(f"  {law:16s} {v['before_um_m']:8.0f} {v['after_um_m']:8.1f} {v['reduction']:7.2f} | "
              f"{v['after_um_m'] / seed['damped_um_m']:.2f}, {v['reduction'] / seed['reduction']:.2f}")
    for name in ("drop_8_4", "drop_8_4_at_rest"):
        d = res[name]
        print(f"8.4 step ({name}, drop {d['drop_height_m']} m, impulse {d['impulse_Ns']:.2f} N s, static strain "
              f"{d['static_um_m'][0]:.0f} -> {d['static_um_m'][1]:.0f} um/m): settling into 15 um/m after landing, "
              f"horizon {d['horizon_s']:.0f} s; seed: damped in ~{d['seed']['damped_settle_s']} s")
        off = d["laws"]["off"]["settle_s"]
        for law, v in d["laws"].items():
            print(f"  {law:16s} {v['settle_s']:6.2f} s (online {v['settle_online_s']:5.2f} s), peak "
                  f"{v['max_um_m']:5.0f} um/m, 2-3 s {v['residual_2s_um_m']:5.0f} um/m, "
                  f"decay {v['decay_per_s']:6.3f} 1/s"
                  f" | /undamped {v['settle_s'] / off:.2f}, /seed {v['settle_s'] / d['seed']['damped_settle_s']:.2f}")
    o = res["one_actuator_8_5"]
    print(f"8.5 one actuator (experiment 06, link-2 strain, settling horizon {o['horizon_s']:.0f} s); seed: "
          f"{o['seed']['ordering']}")
    print(f"  off              {o['off']['settle_s']:5.2f} s, IATS {o['off']['iats']:.2e} (m/m) s^2")
    for law, v in o["laws"].items():
        b, j = v["both"], v["joint3_only"]
        print(f"  {law:16s} both: {b['settle_s']:5.2f} s cut {b['cut_pct']:5.1f} %, IATS {b['iats_pct']:5.1f} % | "
              f"joint 3 only: {j['settle_s']:5.2f} s cut {j['cut_pct']:5.1f} %, IATS {j['iats_pct']:5.1f} % | "
              f"one/both (IATS cut) {o['iats_fraction'][law]:.2f}; gains {o['gains'][law]}")
        if "joint3_tuned" in v:
            tj = v["joint3_tuned"]
            print(f"  {'':16s} joint 3 alone, gain scanned {[round(k, 1) for k in v['joint3_scan']['k3']]}: IATS % "
                  f"{[round(x, 1) for x in v['joint3_scan']['iats_pct']]}; best k3 {tj['k3']:.1f}: "
                  f"{tj['settle_s']:.2f} s "
                  f"cut {tj['cut_pct']:.1f} %, IATS {tj['iats_pct']:.1f} %")
    meta = {"quick": a.quick, "wall_s": wall, "machine": cpu_model(), "date": time.strftime("%Y-%m-%d %H:%M UTC",
                                                                                             time.gmtime())}
    write_text_atomic(os.path.join(a.out, "results.json"),
                      json.dumps({"meta": meta, **_plain(res)}, indent=1, default=float))
    if keep:
        os.makedirs(a.figures, exist_ok=True)
        _fig_periodic(p, os.path.join(a.figures, "ch8_extra_periodic.png"))
        for name, fn in (("drop_8_4", "ch8_extra_drop.png"), ("drop_8_4_at_rest", "ch8_extra_drop_at_rest.png")):
            d = res[name]
            _fig_series(d, ["off"] + list(d["laws"])[1:], "link-2 dynamic strain, um/m",
                        f"8.4 600 g into the net at OP5 (drop {d['drop_height_m']} m)", os.path.join(a.figures, fn))
        _fig_series(o, ["off"] + [f"{law}_{c}" for law in o["laws"] for c in ("joint3", "both")],
                    "link-2 dynamic strain, um/m", "8.5 experiment 06, damping at joint 3 only vs both",
                    os.path.join(a.figures, "ch8_extra_one_actuator.png"))


if __name__ == "__main__":
    main()
