"""Centre accuracy on real, hand-labelled ball videos (issue 15, "Real frames with labels").

For each of ball2.mp4, ball3.mp4, ball4.mp4 in ../shared/realdata/ball_videos
(trflorian/ball-tracking-live-plot, MIT) the colour model is fitted from one
pick on one clean labelled frame, as a user would pick it: the labelled centre
and an edge pixel at 80 % of the labelled radius to its left (the side away
from the hand). Then

* ours, tracking: ``track_mono`` over the whole video (window search around
  the prediction), scored at the labelled frames;
* ours, full frame: ``detect_sphere`` on each labelled frame alone;
* full frame with the colour-rim circle alone (``SegmentParams(chroma_edge_below=0)``:
  the segmentation before the chroma edge of issue 15);
* the same two with the luma-edge rim (``SegmentParams(edge_refine=True)``,
  what the CLI's ``--luma-edge auto`` chooses for videos);
* peer: ``benchmarks/peer_hsv.detect_peer`` (Gaussian blur, HSV ``cv2.inRange``,
  erode/dilate, largest contour, ``cv2.minEnclosingCircle``), once with its
  tutorial "green" range and once with a range set from the same pick
  (hue +-12 levels around the pick's median, S and V at least half the pick's
  median), on each labelled frame.

Scored against tests/data/ball_labels/labels.csv: found rate on clean frames,
centre error median / p90 / max over found clean frames, radius error (ours),
and false detections on labelled no-ball frames.

Run: ``.venv/bin/python benchmarks/bench_real_balls.py [--no-tracking]``
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT))

from peer_hsv import RANGES, detect_peer  # noqa: E402

from tudorvision.io import open_sequence  # noqa: E402
from tudorvision.io.labels import read_ball_labels  # noqa: E402
from tudorvision.stereo import (SegmentParams, TrackerParams, detect_sphere, fit_color_model,  # noqa: E402
                                track_mono)

LUMA = SegmentParams(edge_refine=True)   # what `tudorvision track mono --luma-edge auto` uses for videos
COLOUR_RIM = SegmentParams(chroma_edge_below=0.0)   # the colour-rim circle alone (before the chroma edge)

VIDEOS = ROOT.parent / "shared" / "realdata" / "ball_videos"
LABELS = ROOT / "tests" / "data" / "ball_labels" / "labels.csv"
PICK_FRAME = {"ball2.mp4": 660, "ball3.mp4": 179, "ball4.mp4": 208}
EDGE_FRACTION = 0.8


def pick_for(label):
    """Centre and edge pick (80 % of the labelled radius, to the left) of a labelled frame."""
    c = np.array([label.u_px, label.v_px])
    return c, c - np.array([EDGE_FRACTION * label.r_px, 0.0])


def fit_from_label(image, label):
    """The project's colour model fitted from a user-like pick on ``label``'s frame."""
    c, e = pick_for(label)
    return fit_color_model(image, np.round(c), np.round(e))


def peer_ranges_from_pick(image, label):
    """HSV ``inRange`` bounds set from the pick (a user tuning the tutorial to this ball)."""
    import cv2
    c, _ = pick_for(label)
    r = 0.8 * label.r_px
    hsv = cv2.cvtColor(cv2.GaussianBlur(image, (11, 11), 0), cv2.COLOR_BGR2HSV)
    yy, xx = np.mgrid[0:image.shape[0], 0:image.shape[1]]
    px = hsv[(xx - c[0]) ** 2 + (yy - c[1]) ** 2 <= r * r].astype(float)
    h, s, v = np.median(px, axis=0)
    return {"ball": [((max(h - 12, 0), max(s / 2, 20), max(v / 2, 20)), (min(h + 12, 179), 255, 255))]}


def score(labels, uv, r=None):
    """Found rate on clean frames, centre error stats (px), radius error stats, no-ball false positives."""
    clean = np.array([lab.clean for lab in labels])
    noball = np.array([not lab.has_circle for lab in labels])
    found = np.isfinite(uv[:, 0])
    truth = np.array([[lab.u_px, lab.v_px, lab.r_px] for lab in labels])
    m = clean & found
    err = np.hypot(*(uv[m] - truth[m, :2]).T)
    out = {"n_clean": int(clean.sum()), "found": int(m.sum()), "found_rate": m.sum() / max(clean.sum(), 1),
           "median": float(np.median(err)) if err.size else np.nan,
           "p90": float(np.percentile(err, 90)) if err.size else np.nan,
           "max": float(err.max()) if err.size else np.nan,
           "false_pos": int((found & noball).sum()), "n_noball": int(noball.sum()), "errors": err}
    if r is not None:
        dr = r[m] - truth[m, 2]
        out["r_median"] = float(np.median(dr)) if dr.size else np.nan
        out["r_abs_p90"] = float(np.percentile(np.abs(dr), 90)) if dr.size else np.nan
    return out


def run_video(name, labels, *, tracking=True):
    """Scores of ours (tracking, full frame) and the peers on one video's labelled frames."""
    seq = open_sequence(VIDEOS / name)
    by_frame = {lab.frame: lab for lab in labels}
    pick = by_frame[PICK_FRAME[name]]
    if not pick.clean:
        raise SystemExit(f"{name}: pick frame {pick.frame} is not a clean labelled frame")
    pick_img = np.asarray(seq[pick.frame].image)
    model = fit_from_label(pick_img, pick)
    peer_pick = peer_ranges_from_pick(pick_img, pick)
    frames = [lab.frame for lab in labels]
    res = {}
    for tag, params in (("", None), (", luma edge", LUMA)) if tracking else ():
        t0 = time.perf_counter()
        tr = track_mono(seq, model, params=None if params is None else TrackerParams(segment=params))
        dt = time.perf_counter() - t0
        pos = {int(f): i for i, f in enumerate(tr.frame)}
        uv = np.array([tr.uv[pos[f]] if f in pos else (np.nan, np.nan) for f in frames])
        rr = np.array([tr.detections[pos[f]].radius_px if f in pos and tr.detections[pos[f]].valid else np.nan
                       for f in frames])
        res[f"ours, tracking{tag}"] = score(labels, uv, rr) | {"s_per_frame": dt / len(seq)}
    uv_f, r_f, uv_l, r_l, uv_p, uv_q, uv_c = [], [], [], [], [], [], []
    t_ours = t_peer = 0.0
    for f in frames:
        img = np.asarray(seq[f].image)
        t0 = time.perf_counter()
        d = detect_sphere(img, model)
        t_ours += time.perf_counter() - t0
        uv_f.append(d.uv if d.valid else (np.nan, np.nan))
        r_f.append(d.radius_px if d.valid else np.nan)
        d = detect_sphere(img, model, params=COLOUR_RIM)
        uv_c.append(d.uv if d.valid else (np.nan, np.nan))
        d = detect_sphere(img, model, params=LUMA)
        uv_l.append(d.uv if d.valid else (np.nan, np.nan))
        r_l.append(d.radius_px if d.valid else np.nan)
        t0 = time.perf_counter()
        p = detect_peer(img, {"green": RANGES["green"]})["green"]
        t_peer += time.perf_counter() - t0
        uv_p.append(p if p is not None else (np.nan, np.nan))
        q = detect_peer(img, peer_pick)["ball"]
        uv_q.append(q if q is not None else (np.nan, np.nan))
    seq.close()
    n = len(frames)
    res["ours, full frame"] = score(labels, np.array(uv_f, float), np.array(r_f, float)) | {"s_per_frame": t_ours / n}
    res["ours, full frame, luma edge"] = score(labels, np.array(uv_l, float), np.array(r_l, float))
    res["ours, full frame, colour rim only"] = score(labels, np.array(uv_c, float))
    res["peer HSV, tutorial range"] = score(labels, np.array(uv_p, float)) | {"s_per_frame": t_peer / n}
    res["peer HSV, range from pick"] = score(labels, np.array(uv_q, float))
    return res


def _fmt(x, spec=".2f"):
    return "-" if x is None or (isinstance(x, float) and not np.isfinite(x)) else format(x, spec)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-tracking", action="store_true", help="skip track_mono over whole videos")
    args = ap.parse_args(argv)
    if not VIDEOS.is_dir():
        print(f"{VIDEOS}: not found (the real videos live beside the repository in ../shared/realdata)")
        return 2
    labels = read_ball_labels(LABELS)
    print("| video | method | clean found | median px | p90 px | max px | radius err median / |p90| px "
          "| false pos (no ball) | ms/frame |")
    print("|---|---|---|---|---|---|---|---|---|")
    allres = {}
    for name in PICK_FRAME:
        labs = [lab for lab in labels if lab.video == name]
        for method, s in run_video(name, labs, tracking=not args.no_tracking).items():
            allres.setdefault(method, []).append((name, s))
            rad = (f"{_fmt(s['r_median'], '+.2f')} / {_fmt(s['r_abs_p90'])}" if "r_median" in s else "-")
            ms = _fmt(1e3 * s["s_per_frame"], ".1f") if "s_per_frame" in s else "-"
            print(f"| {name} | {method} | {s['found']}/{s['n_clean']} ({100 * s['found_rate']:.1f} %) | "
                  f"{_fmt(s['median'])} | {_fmt(s['p90'])} | {_fmt(s['max'])} | {rad} | "
                  f"{s['false_pos']}/{s['n_noball']} | {ms} |", flush=True)
    print("\nall three videos, clean frames pooled:")
    for method in allres:
        found = sum(s["found"] for _, s in allres[method])
        n = sum(s["n_clean"] for _, s in allres[method])
        err = np.concatenate([s["errors"] for _, s in allres[method]])
        stats = (f", centre error median {np.median(err):.2f} px, p90 {np.percentile(err, 90):.2f} px"
                 if err.size else "")
        print(f"  {method}: found {found}/{n} ({100 * found / n:.1f} %){stats}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
