"""Issue 18, chapter 10: table 10.1 (motor-current and strain models) on the lab's plants beside the seed.

For each plant (``soft``: the default plant ``PlantConfig()``, identified on
the seed's measured modes; ``stiff``: the earlier rigid-hub one-way plant
``PlantConfig.stiff()``) one
APRBS run per payload 0-400 g drives joints 2 and 3 through the joint layer's
cascade with proportional strain damping (``tudorvision.lab.ch10``); the
motor-current model (10.1.2) and the strain model (10.2.8) are identified on
alternate 5 s blocks and validated on the others. The peer is the seed's
table 10.1 (analytical model, AN column; the data-driven ELM column beside
it): the script prints both and the ratio lab / seed of the mean validation
fit. ``--current-noise`` adds white noise to the recorded currents of the
same runs and refits (the seed's currents are noisy at rest, figure 10.4;
it gives no noise level).

Usage::

    nice .venv/bin/python benchmarks/bench_ch10.py --seconds 60 --jobs 2 --out out/ch10
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from _machine import cpu_model  # benchmarks/ is on sys.path when run as a script

from tudorvision.io.atomic import write_text_atomic
from tudorvision.lab.ch10 import (SEED_TABLE_10_1, Ch10Options, format_table_10_1, reproduce_table_10_1,
                                  summarize_table_10_1, with_current_noise)
from tudorvision.sim.arm import PlantConfig

PLANTS = {"soft": PlantConfig, "stiff": PlantConfig.stiff}


_summary = summarize_table_10_1


def _strain_levels(runs) -> list:
    return [[round(float(np.std(r["eps"][:, i]) * 1e6), 1) for i in range(2)] for r in runs]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="APRBS seconds per payload (seed: 10 x 80 s)")
    ap.add_argument("--plants", default="soft,stiff", help="comma list of " + ", ".join(PLANTS))
    ap.add_argument("--current-noise", default="0.15", help="comma list of extra current noise levels, A")
    ap.add_argument("--k-eps", help="proportional damping gains k1,k2,k3 (default: the joint layer's assisted gains)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="out/ch10")
    a = ap.parse_args(argv)
    out = Path(a.out)
    k_eps = tuple(float(x) for x in a.k_eps.split(",")) if a.k_eps else None
    opts = Ch10Options(seconds=a.seconds, k_eps=k_eps)
    noises = [float(x) for x in a.current_noise.split(",") if x.strip()]
    report = {"machine": cpu_model(), "seconds_per_payload": a.seconds, "k_eps": k_eps, "plants": {},
              "seed_table_10_1": SEED_TABLE_10_1}
    md = []
    for name in a.plants.split(","):
        if name not in PLANTS:
            ap.error(f"--plants: unknown plant {name!r} (choose from {', '.join(PLANTS)})")
        t0 = time.perf_counter()
        res = reproduce_table_10_1(PLANTS[name](), opts, jobs=a.jobs)
        wall = time.perf_counter() - t0
        entry = {"wall_s": round(wall, 1), "summary": _summary(res), "friction_A": res["friction"],
                 "strain_std_um_m": _strain_levels(res["runs"]),
                 "current_std_A": [[round(float(np.std(r["i_M"][:, i])), 3) for i in range(2)] for r in res["runs"]],
                 "current_fits": res["current"]["fits"], "strain_fits": res["strain"]["fits"], "noise": {}}
        md += [f"### {name} plant ({a.seconds:g} s per payload, {wall:.0f} s wall)", ""]
        md += format_table_10_1(res, title=name) + [""]
        s = entry["summary"]
        print(f"{name}: {wall:.0f} s wall")
        for model in ("current", "strain"):
            print(f"  {model}: validation fit lab {s[model]['lab_validation_mean']:.1f} % vs seed AN "
                  f"{s[model]['seed_AN_validation_mean']:.1f} % (ratio {s[model]['ratio_validation']:.2f}); "
                  f"identification lab {s[model]['lab_identification_mean']:.1f} % vs seed AN "
                  f"{s[model]['seed_AN_identification_mean']:.1f} %")
        print("  friction identified / plant (A s/rad, A s/rad, A):", np.round(res["friction"]["identified"], 4).tolist(),
              np.round(res["friction"]["plant"], 4).tolist())
        for sig in noises:
            noisy = with_current_noise(res["runs"], sig, 123)
            rn = reproduce_table_10_1(None, opts, runs=noisy)
            sn = _summary(rn)["current"]
            entry["noise"][f"{sig:g}"] = {"summary": sn, "fits": rn["current"]["fits"]}
            md += [f"{name} plant, current model with {sig:g} A white noise on the currents: validation fit "
                   f"{sn['lab_validation_mean']:.1f} % (joint 2 {sn['lab_validation_range_out2'][0]:.1f}-"
                   f"{sn['lab_validation_range_out2'][1]:.1f} %, joint 3 {sn['lab_validation_range_out3'][0]:.1f}-"
                   f"{sn['lab_validation_range_out3'][1]:.1f} %), identification {sn['lab_identification_mean']:.1f} %",
                   ""]
            print(f"  current + {sig:g} A noise: validation {sn['lab_validation_mean']:.1f} % (ratio "
                  f"{sn['ratio_validation']:.2f}), identification {sn['lab_identification_mean']:.1f} %")
        report["plants"][name] = entry
    write_text_atomic(out / "ch10.json", json.dumps(report, indent=1))
    write_text_atomic(out / "table_10_1.md", "\n".join(md) + "\n")
    print(f"wrote {out / 'ch10.json'} and {out / 'table_10_1.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
