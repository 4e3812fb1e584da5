"""Appendix B.5 of the seed in the virtual lab: stereo accuracy along a vertical rail.

For each seed (room, clutter, lighting, rail tilt and sensor noise) and each
rail place of the seed (workspace centre; 0.85 m along base x, tangent to
the workspace) this renders the rail recording of
:func:`tudorvision.lab.rail.record_rail` (slider 0.30 -> 1.50 m in 50 mm steps,
``--frames`` images per height, JPEG as the lab's default), then runs the
normal stereo pipeline on it, as ``tudorvision track stereo`` does:

- colour models fitted from a simulated user pick on the first frame (a
  centre pixel, the true centroid rounded to a pixel, and an edge pixel at
  0.8 of the apparent radius, verified as the CLI does; a refused pick is
  re-clicked smaller, then on the next height's first frame:
  :func:`tudorvision.lab.rail.user_pick_models`);
- ``track_stereo`` with the CLI's options (tracking mode, luma edge ``auto``,
  sphere-separation check from the robot parameters), results in the left
  camera frame (the seed's stereo camera frame);
- the peer, the seed's centroid: the same with ``SegmentParams(centroid="moment")``
  (``track stereo --centre centroid``);
- an oracle: the exact silhouette centroids through the same triangulation
  (what a perfect segmentation gives with the lab's exact calibration).

Only the evaluation reads the truth. Deviations are those of the seed's
figure B.3: the triangulated midpoint minus its foot on the straight line
fitted to all of that run's points, per axis of the left camera frame (x
right, y down, z forward) and height; also from the true rail line, and the
full error against the true midpoint. The band is ``max - min`` over the
heights of the per-height mean; "+-std" widens it by one standard deviation.
The seed's target: within a 2 mm band inside the workspace (heights up to
link1 + link2 + link3 = 1.19 m).

Run::

    nice .venv/bin/python benchmarks/bench_rail.py --seeds 0 1 2 --frames 20 \\
        --plot docs/figures/rail_residual.png --json /tmp/rail.json
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
from pathlib import Path

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, ".."))

from tudorvision.lab.rail import RAIL_HEIGHTS_M, RAIL_POSITIONS_M  # noqa: E402
from tudorvision.lab.rail_eval import RAIL_METHODS as METHODS  # noqa: E402
from tudorvision.lab.rail_eval import evaluate_rail, render_rail, workspace_top_m  # noqa: E402


def render(workdir: Path, seed: int, place: str, frames: int, heights, ext: str, distractors: int = 4) -> Path:
    return render_rail(workdir, seed, place, frames, heights, ext, distractors, log=lambda m: print(m, flush=True))


def evaluate(path: Path, pick_at=None) -> dict:
    try:
        return evaluate_rail(path, pick_at)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None


def fmt3(v) -> str:
    return "/".join(f"{x:.2f}" for x in v)


def print_per_height(r: dict) -> None:
    """Per height: valid fraction, mean position, mean +- std residual (fitted line), for ours and moment."""
    o, mo = r["ours"], r["moment"]
    print("   h[m] valid  position x/y/z [mm] (ours, left camera)  ours: fit residual mean+-std x/y/z [mm]"
          "    true-line mean x/y/z   | moment: valid  fit mean x/y/z")
    for hh in r["heights_m"]:
        line = f"   {hh:4.2f} {100 * o['valid_per_height'][hh]:4.0f}%  "
        if hh in o["heights_m"]:
            k = o["heights_m"].index(hh)
            line += (f"{fmt3(np.round(o['position_mm'][k], 1)):28s} "
                     + " ".join(f"{o['fit_mean_mm'][k][a]:+.2f}+-{o['fit_std_mm'][k][a]:.2f}" for a in range(3))
                     + f"   {fmt3(o['true_mean_mm'][k]):20s}")
        else:
            line += f"{'(no valid frame)':28s} {'':38s}   {'':20s}"
        line += f" | {100 * mo['valid_per_height'][hh]:4.0f}%  "
        if hh in mo["heights_m"]:
            line += fmt3(mo["fit_mean_mm"][mo["heights_m"].index(hh)])
        print(line)


def plot(results: dict, path: str) -> None:
    """Rows: rail places; columns: axes x/y/z; per seed, ours (solid, +-std bars) and moment (dashed)."""
    import io

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from tudorvision.io.atomic import write_bytes_atomic

    places = sorted({pl for pl, _ in results}, key=list(RAIL_POSITIONS_M).index)
    seeds = sorted({sd for _, sd in results})
    fig, axes = plt.subplots(len(places), 3, figsize=(8.0, 1.0 + 2.0 * len(places)), sharex=True, squeeze=False)
    top = workspace_top_m()
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, place in enumerate(places):
        for j, seed in enumerate(seeds):
            r = results.get((place, seed))
            if r is None:
                continue
            c = colors[j % len(colors)]
            o, mo = r["ours"], r["moment"]
            for k, ax in enumerate(axes[i]):
                hs = np.array(o["heights_m"])
                ax.errorbar(hs, np.array(o["fit_mean_mm"])[:, k], yerr=np.array(o["fit_std_mm"])[:, k], color=c,
                            lw=0.9, capsize=1.2, elinewidth=0.5, label=f"circle (ours), seed {seed}" if k == 0 else None)
                ax.plot(mo["heights_m"], np.array(mo["fit_mean_mm"])[:, k], color=c, lw=0.8, ls="--",
                        label=f"moment (seed's), seed {seed}" if k == 0 else None)
        for k, ax in enumerate(axes[i]):
            ax.axhspan(-1.0, 1.0, color="g", alpha=0.08)
            ax.axvline(top, color="r", lw=0.6, ls=":")
            ax.set_title(f"{place} rail, {'xyz'[k]} (left camera)", fontsize=8)
            ax.tick_params(labelsize=7)
            if i == len(places) - 1:
                ax.set_xlabel("slider height [m]", fontsize=8)
        axes[i][0].set_ylabel("residual [mm]", fontsize=8)
    fig.legend(*axes[0][0].get_legend_handles_labels(), fontsize=6, loc="lower center", ncol=3, frameon=False)
    fig.suptitle("B.5 rail: per-height mean (+-std) residual from the fitted line; green: a 2 mm band, "
                 "red: top of the workspace", fontsize=8)
    fig.tight_layout(rect=(0, 0.09, 1, 1))
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=72)
    plt.close(fig)
    write_bytes_atomic(path, buf.getvalue())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--places", nargs="+", choices=tuple(RAIL_POSITIONS_M), default=list(RAIL_POSITIONS_M))
    ap.add_argument("--frames", type=int, default=20, help="images per height (the seed: 100; default 20)")
    ap.add_argument("--every", type=int, default=1, help="use every N-th of the seed's 25 heights")
    ap.add_argument("--image-ext", choices=(".png", ".jpg"), default=".jpg")
    ap.add_argument("--workdir", default="/tmp/tudorvision_bench_rail", help="render cache")
    ap.add_argument("--json", help="also write the results to this file")
    ap.add_argument("--plot", help="PNG of the residual per height")
    ap.add_argument("--per-height", action="store_true", help="print the per-height table of every run")
    ap.add_argument("--replot", metavar="JSON", help="only redraw --plot from a --json file of an earlier run")
    ap.add_argument("--pick-at", type=float, default=None, metavar="H",
                    help="the simulated user picks on the first frame at height H m (default: the first frame)")
    ap.add_argument("--distractors", type=int, default=4,
                    help="reddish and greenish look-alike objects in the room (default 4, as the stereo lab)")
    args = ap.parse_args(argv)
    if args.replot:
        with open(args.replot) as fh:
            runs = json.load(fh)["runs"]
        results = {(k.split("/")[0], int(k.split("/seed")[1])): r for k, r in runs.items()}
        plot(results, args.plot or "rail_residual.png")
        print(f"wrote {args.plot or 'rail_residual.png'}")
        return 0
    heights = RAIL_HEIGHTS_M[::args.every]
    work = Path(args.workdir)
    work.mkdir(parents=True, exist_ok=True)
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, Python "
          f"{platform.python_version()}; {len(heights)} heights x {args.frames} frames, {args.image_ext}; "
          f"workspace top {workspace_top_m():.2f} m")
    results = {}
    for seed in args.seeds:
        for place in args.places:
            path = render(work, seed, place, args.frames, heights, args.image_ext, args.distractors)
            r = evaluate(path, args.pick_at)
            results[(place, seed)] = r
            for m in METHODS:
                s = r[m]
                print(f"seed {seed} {place:6s} {m:6s} valid {100 * s['valid']:5.1f}%  band x/y/z (fit) "
                      f"{fmt3(s['fit_band_mm'])} mm, inside ws {fmt3(s['fit_band_inside_mm'])}, +-std "
                      f"{fmt3(s['fit_band_std_mm'])}; RMS {s['fit_rms_mm']:.2f} mm; true line band "
                      f"{fmt3(s['true_band_mm'])} RMS {s['true_rms_mm']:.2f}; vs truth RMS {s['err_rms_mm']:.2f} mm "
                      f"({s['seconds']:.1f} s; {s['note']})"
                      + (f"; no valid frame at {s['heights_without_points_m']} m" if s["heights_without_points_m"]
                         else ""), flush=True)
            if args.per_height:
                print_per_height(r)

    print("\nsummary over seeds " + ", ".join(map(str, args.seeds))
          + " (band: max - min of the per-height mean residual from the fitted line, mm, per axis x/y/z of "
            "the left camera; worst seed / mean over seeds)")
    summary = {}
    for place in args.places:
        for m in METHODS:
            runs = [results[(place, s)][m] for s in args.seeds]
            band = np.array([r["fit_band_mm"] for r in runs])
            band_in = np.array([r["fit_band_inside_mm"] for r in runs])
            band_good = np.array([r["fit_band_inside_good_mm"] for r in runs])
            band_sd = np.array([r["fit_band_std_mm"] for r in runs])
            tband = np.array([r["true_band_mm"] for r in runs])
            s = {"band_max_mm": band.max(0).tolist(), "band_mean_mm": band.mean(0).tolist(),
                 "band_inside_max_mm": band_in.max(0).tolist(),
                 "band_inside_good_max_mm": band_good.max(0).tolist(), "band_std_max_mm": band_sd.max(0).tolist(),
                 "true_band_max_mm": tband.max(0).tolist(),
                 "rms_mm": float(np.sqrt(np.mean([r["fit_rms_mm"] ** 2 for r in runs]))),
                 "true_rms_mm": float(np.sqrt(np.mean([r["true_rms_mm"] ** 2 for r in runs]))),
                 "err_rms_mm": float(np.sqrt(np.mean([r["err_rms_mm"] ** 2 for r in runs]))),
                 "valid": float(np.mean([r["valid"] for r in runs])),
                 "heights_without_points_m": {f"seed{sd}": r["heights_without_points_m"]
                                              for sd, r in zip(args.seeds, runs) if r["heights_without_points_m"]},
                 "seconds": float(np.sum([r["seconds"] for r in runs]))}
            s["within_2mm_inside"] = bool(np.all(band_in <= 2.0))
            s["within_2mm_all"] = bool(np.all(band <= 2.0))
            summary[f"{place}/{m}"] = s
            print(f"{place:6s} {m:6s} band {fmt3(s['band_max_mm'])} / {fmt3(s['band_mean_mm'])}; inside ws (worst) "
                  f"{fmt3(s['band_inside_max_mm'])} (heights >= 50 % valid: {fmt3(s['band_inside_good_max_mm'])}); +-std (worst) {fmt3(s['band_std_max_mm'])}; RMS "
                  f"{s['rms_mm']:.2f} mm; true line band (worst) {fmt3(s['true_band_max_mm'])} RMS "
                  f"{s['true_rms_mm']:.2f}; vs truth RMS {s['err_rms_mm']:.2f}; valid {100 * s['valid']:.1f}%; "
                  f"2 mm band inside ws: {'met' if s['within_2mm_inside'] else 'NOT met'}"
                  + (f"; heights without a valid frame: {s['heights_without_points_m']}"
                     if s["heights_without_points_m"] else ""))
        a, b = summary[f"{place}/moment"], summary[f"{place}/ours"]
        print(f"{place:6s} ratio moment/ours: RMS from fitted line {a['rms_mm'] / b['rms_mm']:.2f}, worst band "
              f"{max(a['band_max_mm']) / max(b['band_max_mm']):.2f}, time {a['seconds'] / b['seconds']:.2f}")
    if args.plot:
        plot(results, args.plot)
        print(f"wrote {args.plot}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"args": vars(args), "summary": summary,
                       "runs": {f"{pl}/seed{s}": r for (pl, s), r in results.items()}}, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
