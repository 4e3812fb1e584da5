"""Stereo sphere accuracy over the randomised scene family (issue 15), per apparent-radius bin.

For each of N seeded static stereo set-ups of :mod:`tudorvision.lab.scene_family`
(sphere radius 15-50 mm, camera distance 1.5-5 m, focal length 600-1400 px,
highlights, photo textures, white balance, exposure, sensor noise, JPEG,
link occlusion) this

- simulates a user's picks on the pick frames (the same view, independent
  noise): centre pixel and an edge pixel at 80 % of the apparent radius in a
  random direction, each with ~1 px of pick error (Gaussian, sigma 0.7 px
  per axis, then rounded to an integer pixel as a click is); ``--user sees``: a
  click that would land on an occluder or the other sphere moves onto the
  seen part of the sphere (the lab's ``FamilyScene.sphere_masks``);
- fits one colour model per pick (``fit_color_model``; ``--no-pick-check``:
  without its check that the model finds the whole picked circle); a refused
  pick leaves that sphere untracked in that set-up (counted as not found);
- runs ``StereoPipeline`` (one frame, tracking mode as the CLI, so the first
  and only frame is a full-frame search with the per-radius segmentation; luma-edge rim
  refinement on for JPEG set-ups, as ``tudorvision track stereo`` does; the
  stereo radius check of ``PipelineOptions.max_radius_mismatch`` on, its
  re-measured and refused spheres counted and printed) and,
  as the seed's method, the same with ``SegmentParams(centroid="moment")``;
- runs the named peer ``peer_hsv.detect_peer`` (HSV inRange +
  minEnclosingCircle, hand-set ranges) through the same triangulation;
- scores image centres against the exact silhouette centroid of the whole
  sphere and 3D centres (left camera frame) against the true centres.

Results per apparent-radius bin (pixels; image errors binned by the radius in
that camera, 3D errors by the mean of the two views): image centre error
median / p95 and found rate; 3D sphere-centre error RMS / median / p95 over
the found ones; for ours the share of picks ``fit_color_model`` accepted.
"ours, clear views" keeps the spheres that neither overlap the other sphere
in either image nor have the occluding link in front of them.
The "oracle" rows triangulate the exact silhouette centroids: the floor set
by the geometry (the silhouette centroid is not the projected centre, and
depth error grows as distance^2 / (f baseline)). A detection more than 10 px off (image) or 50 mm off (3D) is
a gross error: it counts in the statistics (they are over found ones) and
is also reported as a rate.
The "0.25 px bound" rows are not a method: they give, per bin, the 3D RMS that
image centres off by exactly the issue's 2D target would cause (each camera's
centre with isotropic Gaussian error whose median is 0.25 px, propagated
through the triangulation's Jacobian at the true centres). Where they exceed
1 mm the two targets of issue 15 cannot both be read as met at the bound: the
3D target then asks for image centres better than 0.25 px by that factor.

Run (about 2 s per set-up on one core)::

    .venv/bin/python benchmarks/bench_sphere_family.py --n 80 --seed 0
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, ".."))

from _machine import cpu_model  # noqa: E402
from peer_hsv import detect_peer  # noqa: E402
from tudorvision._checks import TudorVisionError  # noqa: E402
from tudorvision.io.frames import StereoFrame  # noqa: E402
from tudorvision.lab.record import calibration_from_cameras  # noqa: E402
from tudorvision.lab.scene_family import SPHERES, render_family_scene, sample_family  # noqa: E402
from tudorvision.stereo import (ColorModelSet, PipelineOptions, SegmentParams, StereoPipeline,  # noqa: E402
                                TrackerParams, fit_color_model, triangulate_spheres)

BINS = [(3, 4), (4, 5), (5, 8), (8, 15), (15, 30), (30, 80)]   # the targets start at 4 px
METHODS = ("ours", "ours, clear views", "ours, known radius", "ours, static median", "seed centroid", "peer HSV",
           "oracle", "0.25 px bound")
#: "0.25 px bound": the 3D RMS implied by image centres off by exactly the issue's 2D target (isotropic Gaussian
#: per camera whose median radial error is TARGET_PX), from the triangulation's Jacobian at the true centres.
PICK_SIGMA_PX = 0.7
GROSS_PX, GROSS_MM = 10.0, 50.0
TARGET_MM, TARGET_PX, MIN_FOUND = 1.0, 0.25, 0.95   # issue 15 (centre read as the median), plus 95 % found
# {centroid: [views re-measured, spheres refused, views on the luma rim]} by the stereo radius check
RADIUS_CHECK: dict = {}


def _on_seen_part(mask, c, e, uv):
    """The clicks ``c`` (centre) and ``e`` (edge) of a user who clicks on what is seen of the sphere (``mask``):
    a centre on a hidden pixel moves to the nearest seen pixel at least 1 px inside the seen part; an edge on a
    hidden pixel turns about the true centre ``uv`` (then shrinks towards it) to the nearest seen one; None
    when nothing of the sphere is seen (no click)."""
    import cv2
    h, w = mask.shape

    def seen(q):
        u, v = int(q[0]), int(q[1])
        return 0 <= u < w and 0 <= v < h and bool(mask[v, u])

    if not mask.any():
        return None
    if not seen(c):
        depth = cv2.distanceTransform(mask.astype(np.uint8), cv2.DIST_L2, 3)
        vv, uu = np.nonzero(depth >= min(2.0, float(depth.max())))
        k = int(np.argmin((uu - c[0]) ** 2 + (vv - c[1]) ** 2))
        c = np.array([uu[k], vv[k]], float)
    if not seen(e):
        d = e - uv
        a0, rad = np.arctan2(d[1], d[0]), max(float(np.hypot(*d)), 1.0)
        turned = (np.rint(uv + scale * rad * np.array([np.cos(a), np.sin(a)]))
                  for scale in (1.0, 0.75, 0.5) for da in np.deg2rad(np.arange(10, 181, 10))
                  for a in (a0 + da, a0 - da))
        e = next((q for q in turned if seen(q)), e)
    if not seen(e) or np.all(e == c):
        e = c + [1.0, 0.0]
    return c, e


def simulated_picks(scene, rng, user="issue"):
    """``(camera, sphere, centre, edge)`` picks a user would click on the pick frames.

    ``user="issue"``: the issue's user, the centre and an edge pixel at 80 % of the apparent radius wherever they
    fall (on an occluder or the other sphere in front too); ``"sees"``: the same clicks (same draws), moved
    onto the part of the sphere that is seen (:func:`_on_seen_part`; the lab's visibility masks), no click on a
    sphere hidden whole.
    """
    picks = []
    for cam in ("left", "right"):
        for s in SPHERES:
            uv = scene.uv_true[cam][s]
            r = scene.radius_px[cam][s]
            a = rng.uniform(0, 2 * np.pi)
            c = np.rint(uv + rng.normal(0, PICK_SIGMA_PX, 2))
            e = np.rint(uv + 0.8 * r * np.array([np.cos(a), np.sin(a)]) + rng.normal(0, PICK_SIGMA_PX, 2))
            if np.all(e == c):
                e = c + [1.0, 0.0]
            if user == "sees":
                ce = _on_seen_part(scene.sphere_masks[cam][s], c, e, uv)
                if ce is None:
                    continue
                c, e = ce
            picks.append((cam, s, c, e))
    return picks


#: ``fit_color_model``'s check that a pick's model finds the whole picked circle (``--no-pick-check``: off)
PICK_CIRCLE_CHECK = True


def fit_models(scene, picks):
    """ColorModelSet of the spheres whose picks were accepted in both cameras, and the refusals."""
    models = {"left": {}, "right": {}}
    refused = []
    for cam, s, c, e in picks:
        try:
            models[cam][s] = fit_color_model(scene.pick_frames[cam], c, e, check_pick_circle=PICK_CIRCLE_CHECK)
        except TudorVisionError as exc:
            refused.append(f"{cam}:{s}: {exc}")
    both = [s for s in SPHERES if s in models["left"] and s in models["right"]]
    if not both:
        return None, refused
    # what `tudorvision colormodel` warns of: left and right picks of different colour (one landed on the other
    # sphere in front): the simulated user drops that sphere, as a user reading the warning would re-click it
    for line in ColorModelSet({cam: {s: models[cam][s] for s in both} for cam in models}).colour_mismatches():
        name = line.split(":")[0]
        refused.append(f"left:{name}: {line}")
        both.remove(name)
    if not both:
        return None, refused
    return ColorModelSet({cam: {s: models[cam][s] for s in both} for cam in models}), refused


def _pipeline(scene, cal, models, centroid="shape", known_radius=False):
    """The pipeline as ``track stereo`` runs it (tracking mode: the first frame a full search; luma rim under JPEG)."""
    seg = SegmentParams(centroid=centroid, edge_refine=scene.params.jpeg_quality is not None)
    opts = PipelineOptions(tracker=TrackerParams(segment=seg),
                           sphere_radius_m=scene.params.sphere_radius_m if known_radius else None)
    return StereoPipeline(cal, models, options=opts)


def run_ours(scene, cal, models, centroid, known_radius=False):
    """{cam: {sphere: uv}}, {sphere: p_left} from one pipeline frame (NaN where not found)."""
    nan2, nan3 = np.full(2, np.nan), np.full(3, np.nan)
    uv = {cam: {s: nan2 for s in SPHERES} for cam in ("left", "right")}
    p = {s: nan3 for s in SPHERES}
    if models is None:
        return uv, p
    pipe = _pipeline(scene, cal, models, centroid, known_radius)
    res = pipe.process(StereoFrame(t=0.0, index=0, left=scene.frames["left"], right=scene.frames["right"]))
    key = {"shape": "ours", "moment": "seed centroid"}[centroid] + (", known radius" if known_radius else "")
    RADIUS_CHECK[key] = [a + b for a, b in zip(RADIUS_CHECK.get(key, (0, 0, 0)),
                                                    (pipe.n_radius_repaired, pipe.n_radius_refused,
                                                     pipe.n_luma_repaired))]
    for s in res.spheres:
        p[s] = np.asarray(res.spheres[s], float)
        for cam in ("left", "right"):
            uv[cam][s] = np.asarray(res.uv(cam, s), float)
    return uv, p


def run_ours_static(scene, cal, models):
    """As :func:`run_ours` over the frame and ``scene.static_frames`` in turn, each centre the median over its frames.

    A static sphere recorded for ``1 + len(scene.static_frames)`` frames (each with its own sensor noise): the
    tracker runs through them as ``tudorvision track stereo`` runs through a recording, and a sphere's image
    and 3D centres are the medians (per coordinate) over the frames it was found in (a mean let the odd frame
    whose segmentation took part of the sphere pull it); found in fewer than half of them, it counts as not found.
    """
    nan2, nan3 = np.full(2, np.nan), np.full(3, np.nan)
    pairs = [scene.frames, *scene.static_frames]
    uv = {cam: {s: [] for s in SPHERES} for cam in ("left", "right")}
    p = {s: [] for s in SPHERES}
    if models is not None:
        pipe = _pipeline(scene, cal, models)
        for i, pair in enumerate(pairs):
            res = pipe.process(StereoFrame(t=i / 50.0, index=i, left=pair["left"], right=pair["right"]))
            for s in res.spheres:
                xyz = np.asarray(res.spheres[s], float)
                if np.all(np.isfinite(xyz)):                     # a sphere missing in a frame is NaN there
                    p[s].append(xyz)
                    for cam in ("left", "right"):
                        uv[cam][s].append(np.asarray(res.uv(cam, s), float))

    def median(vals, nan):
        return np.median(vals, axis=0) if 2 * len(vals) >= len(pairs) else nan

    return ({cam: {s: median(uv[cam][s], nan2) for s in SPHERES} for cam in uv},
            {s: median(p[s], nan3) for s in SPHERES})


def run_peer(scene, cal):
    uv = {}
    for cam in ("left", "right"):
        found = detect_peer(scene.frames[cam])
        uv[cam] = {s: np.asarray(found[s], float) if found[s] is not None else np.full(2, np.nan) for s in SPHERES}
    tri = triangulate_spheres({s: uv["left"][s][None] for s in SPHERES}, {s: uv["right"][s][None] for s in SPHERES},
                              cal)
    return uv, {s: np.asarray(tri.spheres[s][0], float) for s in SPHERES}


def evaluate(scene, user="issue"):
    """Rows ``(kind, method, radius_px, error)``: kind "uv" (px) or "3d" (mm); error NaN when not found."""
    cal = calibration_from_cameras(scene.cameras, stereo=("left", "right"))
    rng = np.random.default_rng(scene.params.seed + 1)
    picks = simulated_picks(scene, rng, user)
    models, refused = fit_models(scene, picks)
    clicked = {(cam, sph) for cam, sph, _c, _e in picks}
    refused += [f"{cam}:{sph}: hidden whole, no click" for cam in ("left", "right") for sph in SPHERES
                if (cam, sph) not in clicked]
    t0 = time.perf_counter()
    results = {"ours": run_ours(scene, cal, models, "shape")}
    t_ours = time.perf_counter() - t0
    results["ours, known radius"] = run_ours(scene, cal, models, "shape", known_radius=True)
    if scene.static_frames:
        results["ours, static median"] = run_ours_static(scene, cal, models)
    results["seed centroid"] = run_ours(scene, cal, models, "moment")
    t0 = time.perf_counter()
    results["peer HSV"] = run_peer(scene, cal)
    t_peer = time.perf_counter() - t0
    tri = triangulate_spheres({s: scene.uv_true["left"][s][None] for s in SPHERES},
                              {s: scene.uv_true["right"][s][None] for s in SPHERES}, cal)
    results["oracle"] = (scene.uv_true, {s: np.asarray(tri.spheres[s][0], float) for s in SPHERES})
    rows = [("3d", "0.25 px bound", 0.5 * (scene.radius_px["left"][s] + scene.radius_px["right"][s]), rms)
            for s, rms in target_bound_mm(scene, cal).items()]
    picked = {(r.split(":")[0], r.split(":")[1]) for r in refused}
    for cam in ("left", "right"):
        for s in SPHERES:
            rows.append(("pick", "ours", scene.radius_px[cam][s], 0.0 if (cam, s) in picked else 1.0))
    clear = {}
    for cam in ("left", "right"):
        gap = np.linalg.norm(scene.uv_true[cam]["red"] - scene.uv_true[cam]["green"])
        apart = gap > scene.radius_px[cam]["red"] + scene.radius_px[cam]["green"]
        for s in SPHERES:
            clear[cam, s] = apart and scene.params.occluded_sphere != s
    results["ours, clear views"] = results["ours"]
    for method, (uv, p) in results.items():
        for s in SPHERES:
            if method == "ours, clear views" and not (clear["left", s] and clear["right", s]):
                continue
            for cam in ("left", "right"):
                rows.append(("uv", method, scene.radius_px[cam][s],
                             float(np.linalg.norm(uv[cam][s] - scene.uv_true[cam][s]))))
            r_mean = 0.5 * (scene.radius_px["left"][s] + scene.radius_px["right"][s])
            rows.append(("3d", method, r_mean, 1e3 * float(np.linalg.norm(p[s] - scene.centers_left[s]))))
    return rows, refused, t_ours, t_peer


def target_bound_mm(scene, cal, eps_px: float = 0.01) -> dict:
    """Per sphere, the 3D RMS error (mm) implied by image centres with a median error of ``TARGET_PX``.

    Each camera's centre off by isotropic Gaussian noise of ``sigma = TARGET_PX / sqrt(2 ln 2)`` per axis
    (its median radial error is ``TARGET_PX``), propagated through the triangulation's Jacobian
    (central differences of ``eps_px`` on the true centres): ``sigma * sqrt(trace(J J^T))``.
    """
    sigma = TARGET_PX / np.sqrt(2.0 * np.log(2.0))
    out = {}
    for s in SPHERES:
        rows = {cam: np.repeat(scene.uv_true[cam][s][None], 9, axis=0).astype(float) for cam in ("left", "right")}
        for k in range(4):          # u_left, v_left, u_right, v_right, +eps then -eps
            cam, ax = ("left", "right")[k // 2], k % 2
            rows[cam][1 + 2 * k, ax] += eps_px
            rows[cam][2 + 2 * k, ax] -= eps_px
        tri = triangulate_spheres({s: rows["left"]}, {s: rows["right"]}, cal)
        p = np.asarray(tri.spheres[s], float)
        J = np.stack([(p[1 + 2 * k] - p[2 + 2 * k]) / (2.0 * eps_px) for k in range(4)], axis=1)
        out[s] = 1e3 * sigma * float(np.sqrt(np.trace(J @ J.T)))
    return out


def summarise(rows):
    """{method: {bin: stats}} over the rows."""
    out = {}
    for method in [m for m in METHODS if any(r[1] == m for r in rows)]:
        out[method] = {}
        for lo, hi in BINS:
            sel = lambda kind: np.array([e for k, m, r, e in rows  # noqa: E731
                                         if k == kind and m == method and lo <= r < hi], float)
            uv, p3 = sel("uv"), sel("3d")
            fu, f3 = uv[np.isfinite(uv)], p3[np.isfinite(p3)]
            q = lambda x, pct: float(np.percentile(x, pct)) if x.size else float("nan")  # noqa: E731
            out[method][f"{lo}-{hi}"] = {
                "n_views": int(uv.size), "found": float(fu.size / uv.size) if uv.size else float("nan"),
                "uv_median_px": q(fu, 50), "uv_p95_px": q(fu, 95),
                "uv_gross": float(np.mean(fu > GROSS_PX)) if fu.size else float("nan"),
                "n_spheres": int(p3.size), "found_3d": float(f3.size / p3.size) if p3.size else float("nan"),
                "rms_3d_mm": float(np.sqrt(np.mean(f3 ** 2))) if f3.size else float("nan"),
                "median_3d_mm": q(f3, 50), "p95_3d_mm": q(f3, 95),
                "gross_3d": float(np.mean(f3 > GROSS_MM)) if f3.size else float("nan"),
                "pick_accepted": float(np.mean(sel("pick"))) if sel("pick").size else float("nan"),
                "rms_3d_inlier_mm": float(np.sqrt(np.mean(f3[f3 <= GROSS_MM] ** 2))) if np.any(f3 <= GROSS_MM)
                else float("nan"),
            }
    return out


def print_table(summary):
    print(f"\n{'method':14s} {'bin px':>7s} {'views':>5s} {'found':>6s} {'uv med':>7s} {'uv p95':>7s} "
          f"{'spheres':>7s} {'3D found':>8s} {'3D RMS':>8s} {'3D med':>7s} {'3D p95':>7s} {'gross':>6s} "
          f"{'RMS inl.':>8s} {'picks ok':>8s} target")
    for method, bins in summary.items():
        for b, s in bins.items():
            meets = (s["rms_3d_mm"] <= TARGET_MM and s["uv_median_px"] <= TARGET_PX and s["found"] >= MIN_FOUND)
            tgt = "-" if int(b.split("-")[0]) < 4 or not s["n_views"] else ("met" if meets else "not met")
            if method == "0.25 px bound":
                tgt = "(3D RMS at the 2D target)"
            print(f"{method:14s} {b:>7s} {s['n_views']:5d} {100 * s['found']:5.1f}% {s['uv_median_px']:7.3f} "
                  f"{s['uv_p95_px']:7.2f} {s['n_spheres']:7d} {100 * s['found_3d']:7.1f}% {s['rms_3d_mm']:8.2f} "
                  f"{s['median_3d_mm']:7.2f} {s['p95_3d_mm']:7.2f} {100 * s['gross_3d']:5.1f}% "
                  f"{s['rms_3d_inlier_mm']:8.2f} {100 * s['pick_accepted']:7.1f}% {tgt}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=80, help="number of set-ups")
    ap.add_argument("--seed", type=int, default=0, help="family seed")
    ap.add_argument("--json", help="also write the summary to this file")
    ap.add_argument("--procedural", action="store_true",
                    help="procedural textures instead of the real photographs (for comparison)")
    ap.add_argument("--static-frames", type=int, default=0, metavar="K",
                    help="also track each static set-up over K more frames with their own sensor noise "
                         "(rows 'ours, static median': the median centre over the 1 + K frames)")
    ap.add_argument("--user", choices=("issue", "sees"), default="issue",
                    help="the simulated user: 'issue' clicks the centre and an edge pixel wherever they fall "
                         "(default, as the issue describes); 'sees' moves a click that would land on an occluder "
                         "or the other sphere onto the part of the sphere that is seen")
    ap.add_argument("--no-pick-check", action="store_true",
                    help="fit_color_model(check_pick_circle=False): the former pick check, for comparison")
    args = ap.parse_args(argv)
    global PICK_CIRCLE_CHECK
    PICK_CIRCLE_CHECK = not args.no_pick_check
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                            cwd=os.path.join(HERE, "..")).stdout.strip()
    dirty = subprocess.run(["git", "status", "--porcelain", "--", "tudorvision"], capture_output=True, text=True,
                           cwd=os.path.join(HERE, "..")).stdout.strip()
    print(f"machine: {cpu_model()}, nproc {os.cpu_count()}, Python {platform.python_version()}; commit {commit}"
          f"{' (tudorvision/ has uncommitted changes)' if dirty else ''}; family seed {args.seed}, n {args.n}, "
          f"user {args.user}{'; pick check off' if args.no_pick_check else ''}")
    rows, notes, refusals = [], set(), []
    t_render = t_ours = t_peer = 0.0
    for params in sample_family(args.seed, args.n, textures=[] if args.procedural else None):
        t0 = time.perf_counter()
        scene = render_family_scene(params, static_frames=args.static_frames)
        t_render += time.perf_counter() - t0
        if scene.note:
            notes.add(scene.note)
        r, refused, to, tp = evaluate(scene, args.user)
        rows += r
        t_ours += to
        t_peer += tp
        refusals += [f"set-up {params.index}: {x}" for x in refused]
    for n in sorted(notes):
        print("NOTE:", n)
    print(f"render {t_render:.0f} s; tracking (not a speed benchmark: one frame per set-up, model set-up "
          f"included) ours {1e3 * t_ours / args.n:.1f} ms/pair, peer {1e3 * t_peer / args.n:.1f} ms/pair")
    print(f"picks refused by fit_color_model: {len(refusals)} of {4 * args.n}")
    for key, (fixed, refused_n, luma) in RADIUS_CHECK.items():
        print(f"stereo radius check ({key}): {fixed} sphere views "
              f"re-measured, {refused_n} spheres refused (counted as not found); {luma} views measured again on "
              f"their luma rim beside a luma view")
    for line in refusals[:12]:
        print("  ", line[:160])
    summary = summarise(rows)
    print_table(summary)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"commit": commit, "n": args.n, "seed": args.seed, "static_frames": args.static_frames,
                       "user": args.user,
                       "summary": summary,
                       "refused": refusals}, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
