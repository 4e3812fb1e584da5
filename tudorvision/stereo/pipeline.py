"""The stereo pipeline: one stereo pair in, the end effector out (section 2.4).

Running it over a recording (:func:`iter_stereo`, :func:`track_stereo`,
:func:`track_mono`) is :mod:`tudorvision.stereo.tracking`.

Per stereo pair, :class:`StereoPipeline` runs the colour segmentation of
every tracking sphere in both images (tracking mode, :class:`FrameTracker`,
or full-frame search), triangulates each sphere seen in *both* cameras and
takes the midpoint of the sphere centres as the end effector. A sphere
missing in either image gives NaN and ``valid = False``; there is never a 3D
point from one view.

:func:`~tudorvision.stereo.tracking.iter_stereo` feeds a recorded :class:`~tudorvision.io.Sequence` through
a pipeline, either as fast as possible or paced at the recorded rate
(``live=True``: :meth:`Sequence.play` delivers the newest due frame and drops
older ones when the tracker falls behind; each result carries its latency and
the number of frames dropped before it). Defective frames of lenient
sequences are skipped and counted.

:func:`~tudorvision.stereo.tracking.track_stereo` collects the per-frame results into a trajectory. The
per-frame 3D points are instantaneous; the trajectory is triangulated once
more from the whole pixel tracks so that, when the calibration gives the
cameras a rolling-shutter ``line_time_s``, every centroid is first moved
from its row's read-out time to the frame timestamp
(:func:`~tudorvision.stereo.rolling_shutter.compensate_rolling_shutter`).
Velocity and acceleration are central finite differences
(:func:`~tudorvision.stereo.trajectory.trajectory_from_points`).

The same segmentation on one camera gives a pixel track: :func:`~tudorvision.stereo.tracking.track_mono`.

Time convention: a sample's ``t`` is the frame timestamp of the recording
(for the virtual lab the start of the exposure of row 0); under motion blur
the centroid is the mean position over the exposure.

The pipeline never reads ground truth.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Mapping

import numpy as np

from .._checks import TudorVisionError, check_transform
from ._frame import FramePlanes
from .colormodel import ColorModelSet
from .remeasure import chroma_view_at_radius, luma_view_at_radius
from .detection import StereoFrameResult
from .segment import SphereDetection, detect_spheres, regions_in_window
from .stereo_radius import (MIN_GAP_PX, known_radius_verdict, predicted_radius_px, radius_ratio, region_is_larger,
                            region_is_part, view_radius_px)
from .tracker2d import FrameTracker, TrackerParams
from .epipolar import consistent_centres
from .triangulate import SphereTriangulation, StereoRig, triangulate_spheres

__all__ = ["PipelineOptions", "StereoFrameResult", "StereoPipeline"]

_NAN2 = (float("nan"), float("nan"))
#: Relative standard deviations of a centre on the luma rim and on the colour (``epipolar_centres``; family: 1 : 2)
SIGMA_LUMA_RIM, SIGMA_COLOUR = 1.0, 2.0

@dataclass(frozen=True, kw_only=True)
class PipelineOptions:
    """Options of the stereo tracking loop.

    Parameters
    ----------
    tracking : bool
        Search a window around each sphere's predicted position
        (:class:`~tudorvision.stereo.tracker2d.FrameTracker`, full frame
        when lost); False searches every full frame.
    tracker : TrackerParams
        Tracking-mode options, including the segmentation parameters
        (``tracker.segment`` is also used by the full-frame mode).
    method : {"normalized", "rectified"}
        Triangulation route (:func:`~tudorvision.stereo.triangulate.triangulate_stereo`).
    rolling_shutter : bool
        Compensate the rolling shutter in the trajectory when the calibration
        gives the cameras a ``line_time_s`` (False: triangulate the raw
        centroids, for comparison).
    max_gap_frames : float
        Velocity and acceleration are not differenced across gaps longer
        than this many nominal frame periods.
    max_epipolar_px : float or None
        Stereo consistency: a sphere's left and right centroids must lie
        within this distance (pixels, undistorted) of each other's epipolar
        line. When they do not (one camera locked onto a look-alike object),
        every valid candidate region of that sphere in both full frames is
        paired and the consistent pair nearest the previous 3D position (or
        with the smallest epipolar distance) is taken; failing that the
        sphere is flagged missing. A sphere found in one camera only is
        looked for among the other camera's candidate regions the same way. None disables the check. The default
        leaves room for rolling-shutter skew of fast motion.
    max_radius_mismatch : float or None
        Stereo consistency of the apparent radii (issue 15): once a sphere's centre is triangulated, its
        fitted circle radii must agree between the cameras up to their ``f / Z``
        (:func:`~tudorvision.stereo.stereo_radius.radius_ratio`), within this log ratio (0.12: 13 %) or
        1.5 px. When they do not (one view took part of the sphere: a link across it, a background of its
        colour), the view with the smaller radius is measured again on the sphere's chroma edge from the
        radius the other view predicts (:func:`~tudorvision.stereo.remeasure.chroma_view_at_radius`); if the
        two still disagree the sphere is flagged missing in that frame ("stereo-inconsistent (radius)")
        rather than triangulated wrong. A view without a circle (its centre is the region's moment) counts by its area
        radius on spheres of 8 px or more: short of the other view's prediction
        (:func:`~tudorvision.stereo.stereo_radius.region_is_part`) as above; larger and not motion-blurred
        (:func:`~tudorvision.stereo.stereo_radius.region_is_larger`) it is measured again, else kept; two
        such views are not compared. With the luma edge on (``SegmentParams(edge_refine=True)``), a view
        measured on its colour beside one measured on its luma rim is first measured on its own luma rim from
        the radius that view predicts (:func:`~tudorvision.stereo.remeasure.luma_view_at_radius`), kept when
        the pair then agrees; two views measured on their colour whose radii agree are each measured so from
        the other's. None disables it.
    sphere_radius_m : float or dict or None
        Known metric radius of the spheres (one value, or ``{sphere: radius}``), metres. A sphere whose
        two views imply another radius (``r Z / f`` per camera, averaged) by more than
        :data:`~tudorvision.stereo.stereo_radius.KNOWN_RADIUS_TOL` in log ratio and 1.5 px is flagged
        missing in that frame ("radius ... mm, the sphere's is ... mm";
        :func:`~tudorvision.stereo.stereo_radius.known_radius_verdict`): both views took part of the
        sphere, or background of its colour, in the same way, which the two-view check above cannot see.
        A view without a circle (its centre is the region's moment) counts with its area radius, and alone
        when that is short on a sphere of 8 px or more ("the ... view's region is part of the sphere").
        None (default) disables it.
    epipolar_centres : bool
        A sphere seen in both views gets its two centres moved onto one epipolar plane, each by the least
        that its standard deviation allows (:func:`~tudorvision.stereo.epipolar.consistent_centres`; a centre
        on the luma rim counts twice as certain as one on the colour: ``SIGMA_LUMA_RIM``,
        ``SIGMA_COLOUR``), after the checks above; the view's own centre stays in ``uv_view``. The
        triangulated point is then the weighted least-squares one. Only pairs within ``max_epipolar_px``
        (none when that is None); not with rolling-shutter compensation (a moving sphere's views are not
        simultaneous there).
    sphere_separation_m : float or None
        Known distance between the sphere centres (two spheres); a frame
        whose triangulated distance differs by more than
        ``separation_tol_m`` is flagged invalid. None disables the check.
    separation_tol_m : float
        Tolerance of that check, metres.
    """

    tracking: bool = True
    tracker: TrackerParams = field(default_factory=TrackerParams)
    method: str = "normalized"
    rolling_shutter: bool = True
    max_gap_frames: float = 2.5
    max_epipolar_px: float | None = 6.0
    max_radius_mismatch: float | None = 0.12
    sphere_radius_m: float | dict | None = None
    epipolar_centres: bool = True
    sphere_separation_m: float | None = None
    separation_tol_m: float = 0.03

    def __post_init__(self):
        if not isinstance(self.tracker, TrackerParams):
            raise TudorVisionError(f"tracker: expected TrackerParams, got {type(self.tracker).__name__}")
        if self.method not in ("normalized", "rectified"):
            raise TudorVisionError(f"method: expected 'normalized' or 'rectified', got {self.method!r}")
        if not (self.max_gap_frames > 1.0):
            raise TudorVisionError(f"max_gap_frames: must exceed 1, got {self.max_gap_frames}")
        if self.max_epipolar_px is not None and not (self.max_epipolar_px > 0):
            raise TudorVisionError(f"max_epipolar_px: must be positive or None, got {self.max_epipolar_px}")
        if self.max_radius_mismatch is not None and not (self.max_radius_mismatch > 0):
            raise TudorVisionError(f"max_radius_mismatch: must be positive or None, got {self.max_radius_mismatch}")
        radii = self.sphere_radius_m.values() if isinstance(self.sphere_radius_m, dict) else \
            ([] if self.sphere_radius_m is None else [self.sphere_radius_m])
        if not all(isinstance(r, (int, float)) and math.isfinite(r) and r > 0 for r in radii):
            raise TudorVisionError(f"sphere_radius_m: must be positive metres (one or per sphere), "
                                   f"got {self.sphere_radius_m!r}")
        if self.sphere_separation_m is not None and not (self.sphere_separation_m > 0):
            raise TudorVisionError(f"sphere_separation_m: must be positive or None, got {self.sphere_separation_m}")
        if not (self.separation_tol_m > 0):
            raise TudorVisionError(f"separation_tol_m: must be positive, got {self.separation_tol_m}")


def _check_models(color_models, calibration, stereo_names) -> tuple:
    if not isinstance(color_models, ColorModelSet):
        raise TudorVisionError(f"color_models: expected a ColorModelSet, got {type(color_models).__name__}")
    for cam in ("left", "right"):
        if cam not in color_models.cameras:
            raise TudorVisionError(f"colour models: no models for the {cam} camera "
                                   f"(have {', '.join(color_models.cameras)}); pick both cameras")
    names = [s for s in color_models.spheres("left") if s in color_models.spheres("right")]
    if not names:
        raise TudorVisionError("colour models: no sphere is modelled in both cameras")
    for cam, cname in zip(("left", "right"), stereo_names):
        cm = calibration.camera(cname)
        for s in names:
            w, h = color_models.get(cam, s).image_size
            if (w, h) != (0, 0) and (w, h) != (cm.width, cm.height):
                raise TudorVisionError(
                    f"colour models: {cam}/{s} was picked on a {w}x{h} image, but the calibration's "
                    f"{cam} camera is {cm.width}x{cm.height}")
    return tuple(names)


class StereoPipeline:
    """Per-frame stereo tracking: segmentation in both images, triangulation, midpoint.

    State between frames: the per-camera trackers and each sphere's last
    consistent 3D position (for re-pairing look-alikes); ``n_inconsistent``
    and ``n_repaired`` count the epipolar failures and the repaired ones.

    Parameters
    ----------
    calibration : tudorvision.io.Calibration
        Stereo calibration (two cameras and ``stereo`` extrinsics).
    color_models : ColorModelSet
        Models for cameras ``left`` and ``right``; spheres modelled in both
        are tracked.
    T_base_left : array_like, shape (4, 4), optional
        ``p_base = T_base_left @ p_left``; results are then in the base frame,
        otherwise in the left camera optical frame (x right, y down, z
        forward).
    options : PipelineOptions, optional
        Tracking, triangulation and consistency options; default
        ``PipelineOptions()``.

    Raises
    ------
    TudorVisionError
        No stereo part in the calibration, colour models missing a camera or
        picked on images of another size than the calibration's.

    Examples
    --------
    Two parallel cameras 0.2 m apart see a red and a green disc 2 m ahead:

    >>> import cv2
    >>> from tudorvision.io import Calibration, CameraModel, StereoExtrinsics
    >>> from tudorvision.io.frames import StereoFrame
    >>> from tudorvision.stereo.colormodel import fit_color_model
    >>> cam = CameraModel(K=[[500, 0, 160], [0, 500, 120], [0, 0, 1]], width=320, height=240)
    >>> cal = Calibration(cameras={"left": cam, "right": cam},
    ...                   stereo=StereoExtrinsics(R=np.eye(3), T=[-0.2, 0.0, 0.0]))
    >>> imgs, models = {}, {}
    >>> for name, du in (("left", 0), ("right", -50)):          # disparity 500 * 0.2 / 2 = 50 px
    ...     img = np.full((240, 320, 3), 90, np.uint8)
    ...     _ = cv2.circle(img, (140 + du, 120), 8, (40, 40, 200), -1)   # red, x = -0.08 m
    ...     _ = cv2.circle(img, (180 + du, 120), 8, (50, 190, 40), -1)   # green, x = +0.08 m
    ...     imgs[name] = img
    ...     models[name] = {"red": fit_color_model(img, (140 + du, 120), (147 + du, 120)),
    ...                     "green": fit_color_model(img, (180 + du, 120), (187 + du, 120))}
    >>> pipe = StereoPipeline(cal, ColorModelSet(models))
    >>> res = pipe.process(StereoFrame(t=0.0, index=0, left=imgs["left"], right=imgs["right"]))
    >>> res.valid, res.frame, (np.round(res.ee, 6) + 0.0).tolist(), (np.round(res.spheres["red"], 6) + 0.0).tolist()
    (True, 'left', [0.0, 0.0, 2.0], [-0.08, 0.0, 2.0])
    """

    def __init__(self, calibration, color_models: ColorModelSet, *, T_base_left=None,
                 options: PipelineOptions | None = None):
        self.options = PipelineOptions() if options is None else options
        if not isinstance(self.options, PipelineOptions):
            raise TudorVisionError(f"options: expected PipelineOptions, got {type(self.options).__name__}")
        stereo = getattr(calibration, "stereo", None)
        if stereo is None:
            raise TudorVisionError("calibration: has no stereo extrinsics (run 'tudorvision calib stereo')")
        self.calibration = calibration
        self.cameras = {"left": calibration.camera(stereo.left), "right": calibration.camera(stereo.right)}
        self.spheres = _check_models(color_models, calibration, (stereo.left, stereo.right))
        self.color_models = color_models
        self.T_base_left = None if T_base_left is None else check_transform(T_base_left, "T_base_left")
        self.frame = "left" if self.T_base_left is None else "base"
        self._models = {cam: {s: color_models.get(cam, s) for s in self.spheres} for cam in ("left", "right")}
        self._trackers = {cam: FrameTracker(m, params=self.options.tracker) for cam, m in self._models.items()}
        self._rig = StereoRig(calibration, method=self.options.method)   # checked once, used per frame
        self._f = {"left": self._rig.f_left_px, "right": self._rig.f_right_px}     # mean focal lengths, px
        self._last_left = {s: None for s in self.spheres}   # last consistent sphere centre, left frame
        self.n_repaired = 0
        self.n_inconsistent = 0
        self.n_radius_repaired = 0
        self.n_radius_refused = 0
        self.n_luma_repaired = 0

    @property
    def rolling_shutter(self) -> bool:
        """Whether the trajectory is rolling-shutter compensated."""
        return bool(self.options.rolling_shutter and self.cameras["left"].line_time_s
                    and self.cameras["right"].line_time_s)

    def reset(self) -> None:
        """Forget the tracks (the next pair is searched in full)."""
        for trk in self._trackers.values():
            trk.reset()
        self._last_left = {s: None for s in self.spheres}

    def check_counts(self) -> dict:
        """What the consistency checks did since the pipeline was made (sphere views or spheres).

        Returns
        -------
        dict of str to int
            Keyed by what was done, in words, e.g. ``"views measured again on their luma rim"``.
        """
        return {"pairs off the epipolar line": self.n_inconsistent,
                "of them re-paired from other regions": self.n_repaired,
                "views measured again on their luma rim": self.n_luma_repaired,
                "views measured again for their radius": self.n_radius_repaired,
                "spheres refused for their radius": self.n_radius_refused}

    def epipolar_px(self, uv_left, uv_right) -> np.ndarray:
        """Distance of right centroids from the epipolar lines of left ones, pixels.

        Parameters
        ----------
        uv_left, uv_right : array_like, shape (N, 2)
            Raw (distorted) centroids; NaN rows give NaN.

        Returns
        -------
        ndarray, shape (N,)
            Distance in the right image, undistorted, in pixels of its mean focal length.
        """
        return self._rig.epipolar_px(uv_left, uv_right)

    def _candidates(self, img, cam: str, sphere: str, anywhere: bool = False) -> list:
        """Valid regions of one sphere in a full frame (full resolution), heaviest first.

        A local model: only in its window around the last position, unless ``anywhere`` (the other view's
        detection then pins it to the epipolar line, and only a single region on the line is taken).
        """
        h, w = img.shape[:2]
        model = self._models[cam][sphere]
        roi = None if anywhere else model.local_roi(self._trackers[cam].trackers[sphere].anchor, w, h)
        roi = roi or (0, 0, w, h)
        found = regions_in_window(FramePlanes(img), model, self.options.tracker.segment, roi, False)
        return [d for d in found if d.valid][:6]

    def _make_consistent(self, dets: dict, images: dict) -> dict:
        """Check each sphere's stereo pair against the epipolar geometry; re-pair when it fails."""
        tol = self.options.max_epipolar_px
        if tol is None:
            return dets
        both = [s for s in self.spheres if dets["left"][s].valid and dets["right"][s].valid]
        epi_both = dict(zip(both, self.epipolar_px([dets["left"][s].uv for s in both],
                                                   [dets["right"][s].uv for s in both]).tolist()))
        for s in self.spheres:
            dl, dr = dets["left"][s], dets["right"][s]
            if not (dl.valid or dr.valid):
                continue
            if dl.valid and dr.valid:
                if epi_both[s] <= tol:
                    continue
                self.n_inconsistent += 1
                cands = {cam: self._candidates(images[cam], cam, s) for cam in ("left", "right")}
            else:   # found in one camera only: look for a region on its epipolar line in the other
                have, miss = ("left", "right") if dl.valid else ("right", "left")
                cands = {have: [dets[have][s]], miss: self._candidates(images[miss], miss, s, anywhere=True)}
                if not cands[miss]:
                    continue
            pairs = [(a, b) for a in cands["left"] for b in cands["right"]]
            best = None
            if pairs:
                ua = np.array([a.uv for a, _ in pairs])
                ub = np.array([b.uv for _, b in pairs])
                epi = self.epipolar_px(ua, ub)
                ok = epi <= tol
                if ok.sum() > 1 and any(self._models[c][s].is_local for c in ("left", "right")):
                    ok[:] = False   # a local model's look-alikes: more than one pair fits, none is taken
                if ok.any():
                    prev = self._last_left[s]
                    if prev is not None:
                        pts = self._rig.triangulate(ua, ub)
                        score = np.where(ok, np.linalg.norm(pts - prev, axis=1), np.inf)
                    else:
                        score = np.where(ok, epi, np.inf)
                    best = pairs[int(np.argmin(score))]
            if best is not None:
                new = {"left": best[0], "right": best[1]}
            elif dl.valid and dr.valid:
                new = {"left": _invalid(dl, "stereo-inconsistent (epipolar)"),
                       "right": _invalid(dr, "stereo-inconsistent (epipolar)")}
            else:
                continue
            for cam in ("left", "right"):
                if new[cam] is not dets[cam][s]:
                    dets[cam] = {**dets[cam], s: new[cam]}
                    if self.options.tracking:   # do not predict from the look-alike next frame
                        self._trackers[cam].trackers[s].reset(anchor_uv=new[cam].uv if new[cam].valid else None)
            self.n_repaired += best is not None
        return dets

    def _triangulate(self, dets: dict) -> SphereTriangulation:
        """The valid detections' sphere centres in the left camera frame (NaN where a view is missing)."""
        uv = {c: [dets[c][s].uv if dets[c][s].valid else _NAN2 for s in self.spheres] for c in ("left", "right")}
        p = self._rig.triangulate(uv["left"], uv["right"])
        ok = np.isfinite(p).all(axis=1)
        ee = p.mean(axis=0) if ok.all() else np.full(3, np.nan)
        return SphereTriangulation(spheres={s: p[i:i + 1] for i, s in enumerate(self.spheres)},
                                   sphere_valid={s: ok[i:i + 1] for i, s in enumerate(self.spheres)},
                                   ee=ee[None], ee_valid=np.array([ok.all()]), frame="left")

    def _check_radii(self, dets: dict, images: dict, tri: SphereTriangulation) -> dict:
        """Compare each sphere's radii between the cameras; re-measure or refuse a view that disagrees.

        A view without a circle (a moment view) counts by its area: too small (``region_is_part`` of what the
        other view's circle predicts), it is re-measured or refused; too large and not blurred
        (``region_is_larger``: it took an object of its colour beside it), re-measured or kept as it is.
        ``tri``: the detections triangulated (left camera frame). Returns ``dets`` itself when nothing changed.
        """
        tol = self.options.max_radius_mismatch
        if tol is None:
            return dets
        stereo, f = self.calibration.stereo, self._f
        for s in self.spheres:
            if not all(dets[c][s].valid for c in ("left", "right")):
                continue
            if self.options.tracker.segment.edge_refine:
                dets = self._luma_views(s, dets, tri.spheres[s][0], images)
            views = {c: dets[c][s] for c in ("left", "right")}
            shown = {c: view_radius_px(d.circle_radius_px, d.area_px) for c, d in views.items()}
            r, p = {c: shown[c][0] for c in shown}, tri.spheres[s][0]
            moment = [c for c in shown if shown[c][1]]
            if len(moment) == 2:
                continue
            refuse = True
            if moment:                  # only the moment view can be the bad one
                bad, other = moment[0], "right" if moment[0] == "left" else "left"
                want = predicted_radius_px(p, r[other], f[other], f[bad], stereo.R, stereo.T, this=bad)
                refuse = region_is_part(r[bad], want, tol)
                if not (refuse or (not views[bad].blur and region_is_larger(r[bad], want, tol))):
                    continue
                tries = ((bad, other),)
            else:
                rho = radius_ratio(p, r["left"], r["right"], f["left"], f["right"], stereo.R, stereo.T)
                if not abs(math.log(rho)) > tol:    # NaN (no depth) passes: nothing to compare
                    continue
                small = "left" if rho < 1.0 else "right"
                big = "right" if small == "left" else "left"
                want = predicted_radius_px(p, r[big], f[big], f[small], stereo.R, stereo.T, this=small)
                if abs(want - r[small]) <= MIN_GAP_PX:
                    continue
                # most often the smaller view took part of the sphere; else the larger one took some background
                tries = ((small, big), (big, small))
            for bad, other in tries:
                want = predicted_radius_px(p, r[other], f[other], f[bad], stereo.R, stereo.T, this=bad)
                new = chroma_view_at_radius(images[bad], self._models[bad][s], dets[bad][s], want,
                                            self._agree(s, bad, other, dets, r[other]))
                if new is not None:
                    dets = {**dets, bad: {**dets[bad], s: new}}     # a new dict: the caller sees the change
                    self.n_radius_repaired += 1
                    break
            else:
                if not refuse:
                    continue
                why = (f"stereo-inconsistent (radius: {r['left']:.1f} px left, {r['right']:.1f} px right"
                       f"{', ' + moment[0] + ' by its area' if moment else ''})")
                dets = {c: {**dets[c], s: _invalid(dets[c][s], why)} for c in dets}
                self.n_radius_refused += 1
        return dets

    def _check_known_radius(self, dets: dict, tri: SphereTriangulation) -> dict:
        """Refuse a sphere whose views imply another metric radius than the known one (``sphere_radius_m``)."""
        known = self.options.sphere_radius_m
        if known is None:
            return dets
        stereo = self.calibration.stereo
        for s in self.spheres:
            R_s = known.get(s) if isinstance(known, dict) else known
            views = [dets[c][s] for c in ("left", "right")]
            if R_s is None or not all(d.valid for d in views):
                continue
            why = known_radius_verdict(tri.spheres[s][0], [(d.circle_radius_px, d.area_px) for d in views], R_s,
                                       self._f["left"], self._f["right"], stereo.R, stereo.T)
            if why:
                dets = {c: {**dets[c], s: _invalid(dets[c][s], why)} for c in dets}
                self.n_radius_refused += 1
        return dets

    def _agree(self, s: str, bad: str, other: str, dets: dict, r_other: float):
        """``agree(uv, r)`` of :mod:`~tudorvision.stereo.remeasure` for view ``bad`` of sphere ``s`` against ``other``.
        """
        stereo, f, tol = self.calibration.stereo, self._f, self.options.max_radius_mismatch

        def agree(uv_bad, r_bad):
            uv, rr = {other: dets[other][s].uv, bad: uv_bad}, {other: r_other, bad: r_bad}
            p2 = self._rig.triangulate([uv["left"]], [uv["right"]])[0]
            mis = abs(math.log(radius_ratio(p2, rr["left"], rr["right"], f["left"], f["right"], stereo.R, stereo.T)))
            ok = mis <= tol and self.epipolar_px([uv["left"]], [uv["right"]])[0] <= \
                (self.options.max_epipolar_px or math.inf)
            return mis if ok else None
        return agree

    def _luma_views(self, s: str, dets: dict, p, images: dict) -> dict:
        """Sphere ``s``'s views not on their luma rim measured again on it at the radius the other view predicts
        (:func:`~tudorvision.stereo.remeasure.luma_view_at_radius`): beside a luma view; or, neither on its luma
        rim, both when their colour circles agree in radius (a pair the radius check would refuse is left to it).
        """
        views = {c: dets[c][s] for c in ("left", "right")}
        edge = [c for c in views if views[c].method == "edge"]
        stereo, f = self.calibration.stereo, self._f
        if len(edge) == 1:
            tries = (("right" if edge[0] == "left" else "left", edge[0]),)
        elif edge or any(v.blur or not math.isfinite(v.circle_radius_px) for v in views.values()):
            return dets
        else:
            rho = radius_ratio(p, views["left"].circle_radius_px, views["right"].circle_radius_px, f["left"],
                               f["right"], stereo.R, stereo.T)
            if not abs(math.log(rho)) <= self.options.max_radius_mismatch:
                return dets
            tries = (("left", "right"), ("right", "left"))
        out = dets
        for bad, good in tries:
            r_good = views[good].circle_radius_px
            want = predicted_radius_px(p, r_good, f[good], f[bad], stereo.R, stereo.T, this=bad)
            if views[bad].blur or not want >= 3.0:
                continue
            new = luma_view_at_radius(images[bad], self._models[bad][s], views[bad], want,
                                      self._agree(s, bad, good, dets, r_good),
                                      min_contrast=self.options.tracker.segment.edge_min_contrast,
                                      relax=views[good].method == "edge")
            if new is not None:
                self.n_luma_repaired += 1
                out = {**out, bad: {**out[bad], s: new}}
        return out

    def _epipolar_centres(self, dets: dict) -> dict:
        """Each sphere seen in both views with its centres moved onto one epipolar plane (``epipolar_centres``)."""
        both = [s for s in self.spheres if dets["left"][s].valid and dets["right"][s].valid]
        tol = self.options.max_epipolar_px
        if not both or tol is None:     # no epipolar check, no correction; the check's pairs only (below)
            return dets
        sig = {c: [SIGMA_LUMA_RIM if dets[c][s].method == "edge" else SIGMA_COLOUR for s in both] for c in dets}
        uvl, uvr, moved = consistent_centres(self._rig, [dets["left"][s].uv for s in both],
                                             [dets["right"][s].uv for s in both], sig["left"], sig["right"],
                                             max_epipolar_px=tol)
        if not moved.any():
            return dets
        uv = {"left": uvl.tolist(), "right": uvr.tolist()}
        return {c: {**dets[c], **{s: replace(dets[c][s], uv=tuple(uv[c][i]), uv_view=dets[c][s].uv)
                                  for i, s in enumerate(both) if moved[i]}} for c in dets}

    def _check_image(self, img, cam: str, index: int) -> np.ndarray:
        arr = np.asarray(img)
        if arr.dtype != np.uint8 or arr.ndim != 3 or arr.shape[2] != 3:
            raise TudorVisionError(f"frame {index}: the {cam} image is {arr.dtype} {arr.shape}; colour "
                                   "tracking needs 8-bit BGR images")
        cm = self.cameras[cam]
        if arr.shape[1] != cm.width or arr.shape[0] != cm.height:
            raise TudorVisionError(f"frame {index}: the {cam} image is {arr.shape[1]}x{arr.shape[0]}, but the "
                                   f"calibration's {cam} camera is {cm.width}x{cm.height}; wrong calibration file?")
        return arr

    def detect(self, left_bgr, right_bgr, *, index: int = 0) -> dict:
        """Sphere detections ``{"left": {sphere: SphereDetection}, "right": {...}}`` in one pair.

        With ``options.tracking`` the per-camera trackers are updated (state
        carries to the next call); otherwise each image is searched in full.
        No epipolar check or triangulation (see :meth:`process`).

        Parameters
        ----------
        left_bgr, right_bgr : ndarray, shape (H, W, 3), uint8
            Left and right BGR images of one pair, of the calibrated sizes.
        index : int
            Frame index, used in error messages.

        Returns
        -------
        dict
            ``{"left": {sphere: SphereDetection}, "right": {...}}``; centres
            and radii in pixels (u right, v down), invalid detections say why
            in ``reason``.

        Raises
        ------
        TudorVisionError
            An image that is not 8-bit BGR or not of the calibrated size.
        """
        out = {}
        for cam, img in (("left", left_bgr), ("right", right_bgr)):
            arr = self._check_image(img, cam, index)
            if self.options.tracking:
                out[cam] = self._trackers[cam].update(arr)
            else:
                out[cam] = detect_spheres(arr, self._models[cam], params=self.options.tracker.segment)
        return out

    def process(self, frame, *, latency_s: float = float("nan"), dropped: int = 0) -> StereoFrameResult:
        """Track one stereo frame.

        Parameters
        ----------
        frame : StereoFrame
            ``t``, ``index``, ``left`` and ``right`` BGR images.
        latency_s, dropped : float, int
            Passed through to the result (live playback).

        Returns
        -------
        StereoFrameResult

        Raises
        ------
        TudorVisionError
            An image that is not 8-bit BGR or not of the calibrated size.
        """
        index = int(getattr(frame, "index", 0))
        dets = self.detect(frame.left, frame.right, index=index)
        dets = self._make_consistent(dets, {"left": frame.left, "right": frame.right})
        opt = self.options
        if opt.sphere_separation_m is not None and len(self.spheres) == 2 and \
                all(dets[c][s].valid for c in ("left", "right") for s in self.spheres):
            a, b = self.spheres
            pts = self._rig.triangulate([dets["left"][a].uv, dets["left"][b].uv],
                                        [dets["right"][a].uv, dets["right"][b].uv])
            sep = float(np.linalg.norm(pts[0] - pts[1]))
            if not abs(sep - opt.sphere_separation_m) <= opt.separation_tol_m:
                why = f"sphere separation {sep:.3f} m, expected {opt.sphere_separation_m:.3f} m"
                dets = {c: {s: _invalid(d, why) for s, d in dets[c].items()} for c in dets}
        tri = self._triangulate(dets)
        checked = self._check_known_radius(self._check_radii(dets, {"left": frame.left, "right": frame.right}, tri),
                                           tri)
        if opt.epipolar_centres and not self.rolling_shutter:
            checked = self._epipolar_centres(checked)
        if checked is not dets:     # a view re-measured or moved, or a sphere refused
            dets, tri = checked, self._triangulate(checked)
        for s in self.spheres:
            if tri.sphere_valid[s][0]:
                self._last_left[s] = tri.spheres[s][0]
        spheres = {s: tri.spheres[s][0] for s in self.spheres}
        ee = tri.ee[0]
        if self.T_base_left is not None:
            R, o = self.T_base_left[:3, :3], self.T_base_left[:3, 3]
            spheres = {s: R @ p + o for s, p in spheres.items()}
            ee = R @ ee + o
        return StereoFrameResult(index=index, t=float(frame.t), detections=dets, spheres=spheres, ee=ee,
                                 valid=bool(tri.ee_valid[0]), frame=self.frame, latency_s=float(latency_s),
                                 dropped=int(dropped))

    def triangulate_tracks(self, t, uv_left: Mapping, uv_right: Mapping) -> SphereTriangulation:
        """Triangulate whole pixel tracks, rolling-shutter compensated when configured.

        Parameters
        ----------
        t : array_like, shape (N,)
            Frame timestamps, increasing; both images of a pair share it.
        uv_left, uv_right : mapping of str to array_like, shape (N, 2)
            Raw centroids per sphere, NaN rows where missing.

        Returns
        -------
        SphereTriangulation
            At the frame timestamps ``t``.
        """
        t = np.asarray(t, dtype=np.float64)
        kw = dict(t_left=t, t_right=t, t_target=t) if self.rolling_shutter and len(t) else {}
        return triangulate_spheres(uv_left, uv_right, self.calibration, T_base_left=self.T_base_left,
                                   method=self.options.method, **kw)


def _invalid(det: SphereDetection, reason: str) -> SphereDetection:
    """``det`` marked invalid with ``reason`` (the region is kept for diagnostics)."""
    return replace(det, valid=False, reason=reason)
