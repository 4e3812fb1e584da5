"""Stereo end-effector tracking accuracy against the virtual lab's ground truth.

For each seed (the seed varies lighting, clutter and look-alike decoys) this
renders, with ``tudorvision.lab.record``:

- ``stereo-static``: settled poses over the workspace, no motion blur;
- ``stereo-step``: the step [0,45,-45] -> [0,135,45] deg at the joints'
  maximum speed with motion blur (6 ms exposure);
- ``stereo-step --rolling-shutter``: the same with a rolling shutter
  (30 us per row), tracked with and without rolling-shutter compensation;

fits the colour models from picks at the true centroids (edge at 0.9 of the
true radius) on the first of frames 0-9 where that circle is one colour, per
camera and sphere (a user picks a frame where the sphere is not partly hidden
behind the arm; a model fitted on a half-hidden sphere misses its darker
side in every frame), runs the tracking pipeline (tracking mode, epipolar re-pairing, sphere
separation check, as ``tudorvision track stereo``) and scores:

- RMS 3D end-effector error (base frame, using the true T_base_left so that
  the base calibration is not part of it), over the frames where the
  tracker gives a position, and the fraction of such frames;
- centroid RMS error (pixels) of the blur-free static frames against the
  exact silhouette centroids;
- an oracle: the true centroids through the same triangulation (the floor set
  by calibration and triangulation);
- the tutorial-style peer (``peer_hsv.py``: HSV inRange, contours,
  minEnclosingCircle) through the same triangulation;
- the centroid method: ours uses the circle fitted to the colour rim, refined
  on the luma edge when the frames are JPEG (``--luma-edge auto``, as
  ``tudorvision track stereo``); the same pipeline is also run with the other
  luma-edge setting ("alt") and with ``SegmentParams(centroid="moment")``
  (the region's first moment), see ``docs/stereo.md``.

Run::

    .venv/bin/python benchmarks/bench_stereo_accuracy.py --seeds 0 1 2

(``--image-ext .jpg`` renders JPEG frames, the lab's default, instead of
lossless PNG; ``--workdir`` keeps the renders between runs, keyed by a hash of
the lab's sources, so a changed lab renders anew.)
"""
from __future__ import annotations

import argparse
import functools
import hashlib
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
sys.path.insert(0, os.path.join(HERE, ".."))

from peer_hsv import detect_peer  # noqa: E402
from test_stereo_pipeline import good_picks, gt_ee, gt_picks, gt_transform, gt_uv  # noqa: E402
from tudorvision.io import open_sequence  # noqa: E402
from tudorvision.lab import RecordOptions, record  # noqa: E402
from tudorvision._checks import TudorVisionError  # noqa: E402
from tudorvision.stereo import (ColorModelSet, PipelineOptions, SegmentParams, TrackerParams,  # noqa: E402
                                fit_color_model, fit_color_model_set, parse_pick, track_stereo,
                                triangulate_spheres)

SPHERES = ("red", "green")
SEPARATION_M = 0.16
GROSS_M = 0.05          # 3D errors above this are gross (wrong object)
GROSS_PX = 10.0         # centroid errors above this are gross


def _inliers_px(e):
    e = np.asarray(e, float)
    return e[np.isfinite(e) & (e <= GROSS_PX)]


#: the sources a recording depends on; the render cache is keyed by their content
LAB_SOURCES = ("tudorvision/sim", "tudorvision/robot", "tudorvision/sensors.py", "tudorvision/lab/record.py",
               "tudorvision/lab/simulation.py")


def lab_fingerprint(root: str = os.path.join(HERE, "..")) -> str:
    """Short hash (12 hex digits) of the lab's sources and data under ``root`` (see ``LAB_SOURCES``).

    Renders cached under an older lab (e.g. before the soft plant became the
    default, 3f152f5: every static pose sags 2-12 mm more) must not be scored
    as the current lab's.
    """
    h = hashlib.sha1()
    for rel in LAB_SOURCES:
        base = Path(root) / rel
        if not base.exists():
            raise FileNotFoundError(f"lab source {rel} not under {root}")
        files = sorted(base.rglob("*")) if base.is_dir() else [base]
        for f in files:
            if f.is_file() and "__pycache__" not in f.parts:
                h.update(f.relative_to(root).as_posix().encode())
                h.update(f.read_bytes())
    return h.hexdigest()[:12]


@functools.lru_cache(maxsize=1)
def _this_lab() -> str:
    """:func:`lab_fingerprint` of this checkout, read once per run (not once per recording)."""
    return lab_fingerprint()


def render(workdir: Path, kind: str, seed: int, ext: str, rolling: bool, frames) -> Path:
    name = (f"{kind}{'-rs' if rolling else ''}_seed{seed}{ext.replace('.', '_')}" + (f"_{frames}" if frames else "")
            + f"_lab{_this_lab()}")
    out = workdir / name
    if not (out / "sequence.yaml").is_file():
        t0 = time.perf_counter()
        record(kind, out, RecordOptions(seed=seed, small=True, frames=frames, rolling_shutter=rolling,
                                        image_ext=ext, show_progress=False))
        print(f"  rendered {name} in {time.perf_counter() - t0:.0f} s", flush=True)
    return out


def clean_pick_models(seq, max_frame: int = 10) -> ColorModelSet:
    """Per camera and sphere, the model from the first frame whose 0.9-radius pick circle is one colour."""
    models = {"left": {}, "right": {}}
    for k in range(min(max_frame, len(seq))):
        f = seq[k]
        for pick in gt_picks(seq, k, 0.9):
            cam, sphere, c, e = parse_pick(pick)
            if sphere in models[cam]:
                continue
            try:
                models[cam][sphere] = fit_color_model(getattr(f, cam), c, e)
            except TudorVisionError:
                continue
        if all(len(m) == len(SPHERES) for m in models.values()):
            return ColorModelSet(models)
    f0 = seq[0]
    return fit_color_model_set({"left": f0.left, "right": f0.right}, good_picks(seq))


def rms(x) -> float:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x ** 2))) if x.size else float("nan")


def ee_errors(p, seq) -> np.ndarray:
    return np.linalg.norm(np.asarray(p) - gt_ee(seq), axis=1)


def oracle(seq, rolling: bool) -> np.ndarray:
    uvl = {s: gt_uv(seq, "left", s) for s in SPHERES}
    uvr = {s: gt_uv(seq, "right", s) for s in SPHERES}
    t = seq.timestamps
    kw = dict(t_left=t, t_right=t, t_target=t) if rolling else {}
    return triangulate_spheres(uvl, uvr, seq.calibration, T_base_left=gt_transform(seq), **kw).ee


def peer(seq, rolling: bool):
    """(ee (N, 3), uv_left, uv_right, seconds) of the peer through the same triangulation."""
    uvl = {s: [] for s in SPHERES}
    uvr = {s: [] for s in SPHERES}
    frames = list(seq)
    t0 = time.perf_counter()
    for f in frames:
        for cam, img, store in (("left", f.left, uvl), ("right", f.right, uvr)):
            found = detect_peer(img)
            for s in SPHERES:
                store[s].append(found[s] if found[s] is not None else (np.nan, np.nan))
    dt = time.perf_counter() - t0
    uvl = {s: np.array(v, float) for s, v in uvl.items()}
    uvr = {s: np.array(v, float) for s, v in uvr.items()}
    t = seq.timestamps
    kw = dict(t_left=t, t_right=t, t_target=t) if rolling else {}
    tri = triangulate_spheres(uvl, uvr, seq.calibration, T_base_left=gt_transform(seq), **kw)
    return tri.ee, uvl, uvr, dt


def centroid_errors(seq, uvl, uvr) -> np.ndarray:
    return np.concatenate([np.linalg.norm(uv[s] - gt_uv(seq, cam, s), axis=1)
                           for cam, uv in (("left", uvl), ("right", uvr)) for s in SPHERES])


EDGE = {"on": True, "off": False}


def ours(seq, models, *, rolling_comp: bool = True, centroid: str = "shape", edge: bool | None = None):
    edge = EDGE["ours"] if edge is None else edge
    opts = PipelineOptions(sphere_separation_m=SEPARATION_M, rolling_shutter=rolling_comp,
                           tracker=TrackerParams(segment=SegmentParams(centroid=centroid, edge_refine=edge)))
    return track_stereo(seq, seq.calibration, models, T_base_left=gt_transform(seq), options=opts)


def evaluate(path: Path, *, rolling: bool) -> dict:
    seq = open_sequence(path)
    models = clean_pick_models(seq)
    res = ours(seq, models)
    e = ee_errors(res.trajectory.p, seq)
    pe, pl, pr, _ = peer(seq, rolling)
    e_peer = ee_errors(pe, seq)
    e_or = ee_errors(oracle(seq, rolling), seq)
    g = seq.groundtruth("ee")
    p_gt = gt_ee(seq)
    v_gt = np.linalg.norm(np.gradient(p_gt, g["t"], axis=0), axis=1)
    row = {
        "frames": len(seq),
        "rms_3d_mm": 1e3 * rms(e), "median_3d_mm": 1e3 * float(np.nanmedian(e)), "max_3d_mm": 1e3 * float(np.nanmax(e)),
        "valid": float(res.trajectory.valid.mean()),
        "centroid_rms_px": rms(centroid_errors(seq, res.uv_left, res.uv_right)),
        "centroid_median_px": float(np.nanmedian(centroid_errors(seq, res.uv_left, res.uv_right))),
        "oracle_rms_3d_mm": 1e3 * rms(e_or),
        "peer_rms_3d_mm": 1e3 * rms(e_peer), "peer_valid": float(np.isfinite(e_peer).mean()),
        # gross errors (a look-alike decoy taken for a sphere): 3D error above 50 mm
        "gross": float(np.mean(e > GROSS_M)), "peer_gross": float(np.mean(e_peer > GROSS_M)),
        "peer_inlier_rms_3d_mm": 1e3 * rms(e_peer[e_peer <= GROSS_M]),
        "peer_inlier_centroid_rms_px": rms(_inliers_px(centroid_errors(seq, pl, pr))),
        "peer_centroid_rms_px": rms(centroid_errors(seq, pl, pr)),
        "peak_speed_true_m_s": float(np.nanmax(v_gt)),
        "peak_speed_measured_m_s": float(np.nanmax(res.trajectory.speed)) if np.isfinite(res.trajectory.speed).any()
        else float("nan"),
    }
    mom = ours(seq, models, centroid="moment")
    row["moment_rms_3d_mm"] = 1e3 * rms(ee_errors(mom.trajectory.p, seq))
    row["moment_centroid_rms_px"] = rms(centroid_errors(seq, mom.uv_left, mom.uv_right))
    row["moment_centroid_median_px"] = float(np.nanmedian(centroid_errors(seq, mom.uv_left, mom.uv_right)))
    rim = ours(seq, models, edge=not EDGE["ours"])
    row["rim_rms_3d_mm"] = 1e3 * rms(ee_errors(rim.trajectory.p, seq))
    row["rim_centroid_rms_px"] = rms(centroid_errors(seq, rim.uv_left, rim.uv_right))
    if rolling:
        raw = ours(seq, models, rolling_comp=False)
        row["rms_3d_mm_without_rs_comp"] = 1e3 * rms(ee_errors(raw.trajectory.p, seq))
        pe_raw = peer(seq, False)[0]
        row["peer_rms_3d_mm_without_rs_comp"] = 1e3 * rms(ee_errors(pe_raw, seq))
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--image-ext", choices=(".png", ".jpg"), default=".png")
    ap.add_argument("--static-frames", type=int, default=None, help="poses per static recording (default 12)")
    ap.add_argument("--step-frames", type=int, default=None, help="frames per step recording (default 80)")
    ap.add_argument("--workdir", default="/tmp/tudorvision_bench_stereo", help="render cache")
    ap.add_argument("--luma-edge", choices=("auto", "on", "off"), default="auto",
                    help="luma-edge rim refinement of ours (auto: on for .jpg frames, as the CLI)")
    ap.add_argument("--json", help="also write the results to this file")
    args = ap.parse_args(argv)
    EDGE["ours"] = args.image_ext == ".jpg" if args.luma_edge == "auto" else args.luma_edge == "on"
    work = Path(args.workdir)
    work.mkdir(parents=True, exist_ok=True)
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, Python "
          f"{platform.python_version()}; frames {args.image_ext}; luma edge {'on' if EDGE['ours'] else 'off'}")
    cases = [("static", "stereo-static", False, args.static_frames),
             ("step (blur)", "stereo-step", False, args.step_frames),
             ("step (blur, rolling shutter)", "stereo-step", True, args.step_frames)]
    results = {}
    for seed in args.seeds:
        for label, kind, rolling, frames in cases:
            path = render(work, kind, seed, args.image_ext, rolling, frames)
            results.setdefault(label, {})[seed] = evaluate(path, rolling=rolling)
            r = results[label][seed]
            print(f"seed {seed} {label:30s} ours {r['rms_3d_mm']:6.2f} mm ({100 * r['valid']:5.1f}% valid)  "
                  f"peer {r['peer_rms_3d_mm']:7.2f} mm ({100 * r['peer_valid']:5.1f}%)  oracle "
                  f"{r['oracle_rms_3d_mm']:5.2f} mm; centroid {r['centroid_rms_px']:.3f} px "
                  f"(moment: {r['moment_rms_3d_mm']:.2f} mm, {r['moment_centroid_rms_px']:.3f} px; alt: "
                  f"{r['rim_rms_3d_mm']:.2f} mm, {r['rim_centroid_rms_px']:.3f} px)", flush=True)

    print("\nRMS over seeds " + ", ".join(map(str, args.seeds)) + " (3D: end effector, base frame, mm; "
          "centroid: px)")
    hdr = (f"{'case':30s} {'ours 3D':>8s} {'valid':>6s} {'gross':>6s} {'peer 3D':>8s} {'gross':>6s} "
           f"{'peer inl.':>9s} {'peer/ours':>9s} {'inl./ours':>9s} {'oracle':>7s}")
    print(hdr)
    summary = {}
    for label, rows in results.items():
        agg = lambda k: float(np.sqrt(np.nanmean([r[k] ** 2 for r in rows.values()])))  # noqa: E731
        mean = lambda k: float(np.mean([r[k] for r in rows.values()]))  # noqa: E731
        s = {"rms_3d_mm": agg("rms_3d_mm"), "valid": mean("valid"), "peer_rms_3d_mm": agg("peer_rms_3d_mm"),
             "peer_valid": mean("peer_valid"), "oracle_rms_3d_mm": agg("oracle_rms_3d_mm"),
             "centroid_rms_px": agg("centroid_rms_px"), "peer_centroid_rms_px": agg("peer_centroid_rms_px"),
             "centroid_median_px": mean("centroid_median_px"), "gross": mean("gross"),
             "peer_gross": mean("peer_gross"), "peer_inlier_rms_3d_mm": agg("peer_inlier_rms_3d_mm"),
             "peer_inlier_centroid_rms_px": agg("peer_inlier_centroid_rms_px"),
             "peak_speed_true_m_s": max(r["peak_speed_true_m_s"] for r in rows.values()),
             "peak_speed_measured_m_s": max(r["peak_speed_measured_m_s"] for r in rows.values()),
             "moment_rms_3d_mm": agg("moment_rms_3d_mm"), "moment_centroid_rms_px": agg("moment_centroid_rms_px"),
             "moment_centroid_median_px": mean("moment_centroid_median_px"),
             "rim_rms_3d_mm": agg("rim_rms_3d_mm"), "rim_centroid_rms_px": agg("rim_centroid_rms_px")}
        if "rms_3d_mm_without_rs_comp" in next(iter(rows.values())):
            s["rms_3d_mm_without_rs_comp"] = agg("rms_3d_mm_without_rs_comp")
            s["peer_rms_3d_mm_without_rs_comp"] = agg("peer_rms_3d_mm_without_rs_comp")
        summary[label] = s
        print(f"{label:30s} {s['rms_3d_mm']:8.2f} {100 * s['valid']:5.1f}% {100 * s['gross']:5.1f}% "
              f"{s['peer_rms_3d_mm']:8.1f} {100 * s['peer_gross']:5.1f}% {s['peer_inlier_rms_3d_mm']:9.2f} "
              f"{s['peer_rms_3d_mm'] / s['rms_3d_mm']:9.1f} {s['peer_inlier_rms_3d_mm'] / s['rms_3d_mm']:9.1f} "
              f"{s['oracle_rms_3d_mm']:7.2f}")
    print("(valid: frames with a 3D position; gross: frames with error > 50 mm (a decoy taken for a sphere); "
          "peer inl.: peer RMS over its non-gross frames; oracle: true centroids, same triangulation)")
    st = summary["static"]
    print(f"\ncentroid RMS on blur-free (static) frames: ours {st['centroid_rms_px']:.3f} px "
          f"(median {st['centroid_median_px']:.3f} px), peer {st['peer_centroid_rms_px']:.1f} px "
          f"(non-gross detections: {st['peer_inlier_centroid_rms_px']:.3f} px, ratio peer/ours "
          f"{st['peer_inlier_centroid_rms_px'] / st['centroid_rms_px']:.1f})")
    on = "on" if EDGE["ours"] else "off"
    print(f"\ncentroid method (same pipeline; 3D RMS mm / centroid RMS px; ours: colour-rim circle, luma edge "
          f"{on}; alt: luma edge {'off' if EDGE['ours'] else 'on'}; moment: first moment):")
    print(f"{'case':30s} {'ours 3D':>10s} {'alt 3D':>7s} {'moment 3D':>10s} {'ours px':>10s} "
          f"{'alt px':>7s} {'moment px':>10s}")
    for label, s in summary.items():
        print(f"{label:30s} {s['rms_3d_mm']:10.2f} {s['rim_rms_3d_mm']:7.2f} {s['moment_rms_3d_mm']:10.2f} "
              f"{s['centroid_rms_px']:10.3f} {s['rim_centroid_rms_px']:7.3f} {s['moment_centroid_rms_px']:10.3f}")
    print(f"(static centroid median: ours {st['centroid_median_px']:.3f} px, moment "
          f"{st['moment_centroid_median_px']:.3f} px; the centroid columns of the step rows include blurred "
          f"frames)")
    rs = summary["step (blur, rolling shutter)"]
    print(f"rolling shutter: ours {rs['rms_3d_mm_without_rs_comp']:.2f} mm without compensation -> "
          f"{rs['rms_3d_mm']:.2f} mm with; peer {rs['peer_rms_3d_mm_without_rs_comp']:.2f} -> "
          f"{rs['peer_rms_3d_mm']:.2f} mm")
    step = summary["step (blur)"]
    print(f"step: peak end-effector speed {step['peak_speed_true_m_s']:.2f} m/s (truth), "
          f"{step['peak_speed_measured_m_s']:.2f} m/s (measured, finite differences)")
    print(f"targets: static <= 1.0 mm, step with blur <= 2.0 mm, centroid <= 0.25 px RMS")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"args": vars(args), "per_seed": results, "summary": summary}, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
