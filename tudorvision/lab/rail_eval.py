"""Appendix B.5 evaluated: the rail recording through the stereo tracker, deviations from a fitted line.

:func:`render_rail` records (or reuses) a rail sequence of
:func:`tudorvision.lab.rail.record_rail`; :func:`evaluate_rail` runs the normal
stereo pipeline on it as ``tudorvision track stereo`` does (colour models from a
simulated user's pick, tracking mode, the luma edge on for JPEG frames, the
sphere-separation check) for three methods:

* ``ours``: the circle (rim) centre of the segmented sphere;
* ``moment``: the seed's centroid (``SegmentParams(centroid="moment")``);
* ``oracle``: the exact silhouette centroids through the same triangulation.

Only the evaluation reads the truth. The deviations are those of the seed's
figure B.3: each triangulated midpoint minus its foot on the line fitted to
the run's points, per axis of the left camera frame and height.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..io import open_sequence
from ..robot import load_robot_params
from .rail import RAIL_POSITIONS_M, RailOptions, rail_deviation, record_rail, truth_transform, user_pick_models

__all__ = ["RAIL_METHODS", "workspace_top_m", "render_rail", "rail_points", "evaluate_rail"]

#: Methods :func:`evaluate_rail` compares.
RAIL_METHODS = ("ours", "moment", "oracle")
_SPHERES = ("red", "green")


def workspace_top_m(params=None) -> float:
    """Highest point of the workspace above the floor, link 1 + link 2 + link 3, m.

    Parameters
    ----------
    params : RobotParams, optional
        Default the packaged robot.

    Returns
    -------
    float
        Height, m (1.19 m for TUDOR).
    """
    p = params or load_robot_params()
    return p.link1_height_m + p.link2_length_m + p.link3_length_m


def render_rail(workdir, seed: int, place: str, frames: int, heights, ext: str = ".jpg", distractors: int = 4,
                log=None) -> Path:
    """Record the rail sequence for (seed, place, frames, heights, ext) into ``workdir`` unless it is there.

    Parameters
    ----------
    workdir : str or Path
        Cache folder; the sequence's folder name encodes its settings.
    seed : int
        Seed of the room, clutter, lighting, tilt and noise.
    place : str
        A key of :data:`~tudorvision.lab.rail.RAIL_POSITIONS_M`.
    frames : int
        Images per height.
    heights : sequence of float
        Slider heights, m.
    ext : {".jpg", ".png"}
        Image format.
    distractors : int
        Look-alike objects in the room.
    log : callable, optional
        ``log(str)`` after rendering.

    Returns
    -------
    Path
        The sequence folder.
    """
    if place not in RAIL_POSITIONS_M:
        raise ValueError(f"place: expected one of {', '.join(RAIL_POSITIONS_M)}, got {place!r}")
    out = Path(workdir) / (f"rail_{place}_seed{seed}_f{frames}_h{len(heights)}{ext.replace('.', '_')}"
                           + ("" if distractors == 4 else f"_d{distractors}"))
    if not (out / "sequence.yaml").is_file():
        t0 = time.perf_counter()
        record_rail(out, RailOptions(seed=seed, rail_xy_m=RAIL_POSITIONS_M[place], heights_m=tuple(heights),
                                     frames_per_height=frames, image_ext=ext, n_distractors=distractors,
                                     force=True))
        if log:
            skipped = open_sequence(out).meta.get("rail_heights_out_of_view_m") or []
            log(f"  rendered {out.name} in {time.perf_counter() - t0:.0f} s"
                + (f"; out of view, left out: {skipped} m" if skipped else ""))
    return out


def _tracker(path, method: str):
    from ..stereo.rim_edge import chroma_subsampled_source
    from ..stereo.segment import SegmentParams
    from ..stereo.tracker2d import TrackerParams
    return TrackerParams(segment=SegmentParams(edge_refine=chroma_subsampled_source(path),
                                               centroid="shape" if method == "ours" else "moment"))


def rail_points(seq, path, method: str, pick_at=None):
    """End-effector points of a rail sequence in the left camera frame by one method.

    Parameters
    ----------
    seq : Sequence
        The open rail sequence.
    path : str or Path
        Its folder (decides the luma edge, on for JPEG frames).
    method : {"ours", "moment", "oracle"}
        The centre method.
    pick_at : float, optional
        Height, m, of the frame the simulated user picks on (default the first frame).

    Returns
    -------
    points : ndarray, shape (N, 3)
        Midpoints, left camera frame, m (NaN where not tracked).
    seconds : float
        Wall time.
    note : str
        Where the pick was made, or why it was refused.
    """
    from .._checks import TudorVisionError
    from ..stereo import PipelineOptions, track_stereo, triangulate_spheres
    t0 = time.perf_counter()
    if method == "oracle":
        gt = seq.groundtruth("ee")
        uv = {cam: {s: np.column_stack([gt[f"{cam}_{s}_u_px"], gt[f"{cam}_{s}_v_px"]]) for s in _SPHERES}
              for cam in ("left", "right")}
        tri = triangulate_spheres(uv["left"], uv["right"], seq.calibration)
        return np.asarray(tri.ee, float), time.perf_counter() - t0, "exact centroids"
    if method not in RAIL_METHODS:
        raise ValueError(f"method: expected one of {', '.join(RAIL_METHODS)}, got {method!r}")
    tracker = _tracker(path, method)
    try:
        models, k, picks = user_pick_models(seq, verify_params=tracker.segment, start_height_m=pick_at)
    except TudorVisionError as exc:
        return np.full((len(seq), 3), np.nan), time.perf_counter() - t0, f"pick refused: {exc}"
    note = f"picked on frame {k}" + (f" ({' '.join(picks)})" if k and pick_at is None else "")
    off = load_robot_params().sphere_offsets_ee_m
    sep = float(np.linalg.norm(np.subtract(off["red"], off["green"])))
    res = track_stereo(seq, seq.calibration, models, options=PipelineOptions(tracker=tracker, sphere_separation_m=sep))
    p = np.full((len(seq), 3), np.nan)
    p[res.index] = np.where(res.trajectory.valid[:, None], res.trajectory.p, np.nan)
    return p, time.perf_counter() - t0, note


def evaluate_rail(path, pick_at=None, methods=RAIL_METHODS) -> dict:
    """Deviations of each method's points from the fitted and the true rail line (figure B.3).

    Parameters
    ----------
    path : str or Path
        A rail sequence (:func:`render_rail`).
    pick_at : float, optional
        Height of the pick frame, m.
    methods : sequence of str
        Methods to run.

    Returns
    -------
    dict
        ``frames``, ``heights_m`` and per method: ``valid`` (fraction of frames), ``fit_band_mm``
        (per axis x/y/z of the left camera, max - min of the per-height mean residual from the fitted
        line), ``fit_band_inside_mm`` (heights inside the workspace), ``fit_band_inside_good_mm`` (and
        at least half the frames valid), ``fit_band_std_mm``, ``fit_rms_mm``, ``true_band_mm``,
        ``true_rms_mm``, ``err_rms_mm`` (against the true midpoint), per-height means and stds,
        ``tilt_vs_true_deg``, ``seconds``, ``note``.

    Raises
    ------
    ValueError
        When a method yields no point at all.
    """
    seq = open_sequence(path)
    try:
        rail = seq.groundtruth("rail")
        h = np.asarray(rail["height_m"], float)
        gt = seq.groundtruth("ee")
        T_left_base = np.linalg.inv(truth_transform(seq, 0))
        R, o = T_left_base[:3, :3], T_left_base[:3, 3]
        p_true = np.column_stack([gt["ee_x_m"], gt["ee_y_m"], gt["ee_z_m"]]) @ R.T + o
        ax = seq.groundtruth("rail_axis")
        line_true = (R @ [ax["p0_x_m"][0], ax["p0_y_m"][0], ax["p0_z_m"][0]] + o,
                     R @ [ax["d_x"][0], ax["d_y"][0], ax["d_z"][0]])
        top = workspace_top_m()
        out = {"frames": len(seq), "heights_m": sorted(set(h.tolist()))}
        for m in methods:
            p, dt, note = rail_points(seq, path, m, pick_at)
            if not np.isfinite(p).any():
                raise ValueError(f"{Path(path).name} {m}: {note}")
            out[m] = _method_stats(p, h, p_true, line_true, top, dt, note)
    finally:
        seq.close()
    return out


def _method_stats(p, h, p_true, line_true, top, dt, note) -> dict:
    fit = rail_deviation(p, h)
    tru = rail_deviation(p, h, line=line_true)
    err = p - p_true
    hs = fit.heights_m
    err_mean = np.array([np.nanmean(err[h == v], axis=0) for v in hs])
    inside = hs <= top + 1e-9
    all_h = np.unique(h)
    valid_h = [float(np.mean(np.all(np.isfinite(p[h == v]), axis=1))) for v in all_h]
    vh = dict(zip(all_h.tolist(), valid_h))
    good = np.array([vh[v] >= 0.5 for v in hs.tolist()])
    mean_in, mean_good = fit.mean_m[inside], fit.mean_m[good & inside]

    def band(m):
        return (1e3 * (m.max(0) - m.min(0))).tolist() if len(m) else [float("nan")] * 3

    return {
        "valid_per_height": vh,
        "heights_without_points_m": [float(v) for v, f in zip(all_h, valid_h) if f == 0.0],
        "seconds": dt, "note": note, "valid": float(np.mean(np.all(np.isfinite(p), axis=1))),
        "position_mm": (1e3 * fit.position_m).tolist(), "n": fit.n.tolist(), "heights_m": hs.tolist(),
        "fit_mean_mm": (1e3 * fit.mean_m).tolist(), "fit_std_mm": (1e3 * fit.std_m).tolist(),
        "fit_band_mm": (1e3 * fit.band_m).tolist(), "fit_band_std_mm": (1e3 * fit.band_std_m).tolist(),
        "fit_band_inside_mm": band(mean_in), "fit_band_inside_good_mm": band(mean_good),
        "fit_rms_mm": 1e3 * fit.rms_m,
        "true_mean_mm": (1e3 * tru.mean_m).tolist(), "true_band_mm": (1e3 * tru.band_m).tolist(),
        "true_rms_mm": 1e3 * tru.rms_m,
        "err_mean_mm": (1e3 * err_mean).tolist(),
        "err_rms_mm": float(1e3 * np.sqrt(np.nanmean(np.sum(err ** 2, axis=1)))),
        "tilt_vs_true_deg": float(np.degrees(np.arccos(min(1.0, abs(fit.direction @ line_true[1]))))),
    }
