"""Per-sphere colour models: a Gaussian per channel of RGB and HSV (section 2.4).

A colour model is fitted once per sequence, camera and sphere from one frame:
a picked centre pixel and a picked edge pixel define a circle on the sphere
image; the pixels inside (shrunk a little, so that the rim and the background
stay out) give one Gaussian per channel of R, G, B, H, S, V. Pixels far
outside the circle give a per-channel background histogram. Together they
define the naive Bayes log-likelihood ratio per channel, tabulated once per
model so that segmenting a frame costs table look-ups and additions
(:mod:`tudorvision.stereo.segment`).

Conventions
-----------
- Frames are OpenCV BGR ``uint8`` arrays of shape (H, W, 3); image
  coordinates are ``u`` right (column) and ``v`` down (row) with pixel centres
  at integer coordinates.
- Channel order in a model is always ``R, G, B, H, S, V``. H is OpenCV's
  8-bit hue, 0..179 (two degrees per level); it is circular, so its mean and
  standard deviation are the circular ones and hue differences are taken on
  the circle (179 and 0 are one level apart).
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from types import MappingProxyType
from typing import Mapping

import cv2
import numpy as np

from tudorvision._checks import TudorVisionError
from tudorvision.io.atomic import atomic_write
from tudorvision.stereo._colortables import CHANNELS, HUE_INDEX, HUE_LEVELS, ColorModel
from tudorvision.stereo._frame import check_frame
from tudorvision.stereo._localmodel import background_pmf, fit_local_model
from tudorvision.stereo.detection import segment_params_for_radius
from tudorvision.stereo.rim_edge import sphere_chroma
from tudorvision.stereo.segment import detect_sphere
from tudorvision.stereo._pick import (calibrated_prior, circular_hue_stats, fits_pick, part_of_pick, pick_stats,
                                     reject_outlier_rows, trim_highlights_rows)

__all__ = [
    "CHANNELS",
    "HUE_LEVELS",
    "ColorModel",
    "ColorModelSet",
    "fit_color_model",
    "fit_color_model_set",
    "parse_pick",
    "save_color_models",
    "load_color_models",
    "circular_hue_stats",
]

_CAMERAS = ("left", "right", "mono")
_FORMAT = "tudorvision.colormodel"
_VERSION = 1


def _check_uv(value, name: str, width: int, height: int) -> np.ndarray:
    try:
        uv = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise TudorVisionError(f"{name}: expected a pixel (u, v), got {value!r}") from None
    if uv.shape != (2,) or not np.all(np.isfinite(uv)):
        raise TudorVisionError(f"{name}: expected a finite pixel (u, v), got {value!r}")
    if not (-0.5 <= uv[0] < width - 0.5 and -0.5 <= uv[1] < height - 0.5):
        raise TudorVisionError(
            f"{name}: pixel ({uv[0]:g}, {uv[1]:g}) lies outside the {width}x{height} image")
    return uv


def fit_color_model(frame_bgr, center_uv, edge_uv, *, shrink: float = 0.8, min_pixels: int = 12,
                    max_std: float = 45.0, max_hue_std: float = 20.0, min_saturation: float = 30.0,
                    background_margin: float = 1.5, llr_clip: float = 8.0, prior: float | None = None,
                    min_std=(6.0, 6.0, 6.0, 2.0, 8.0, 6.0), verify: bool = True,
                    verify_params=None, trim_highlights: bool = False, reject_outliers: bool = True,
                    calibrate_prior: bool = True, local_fallback: bool = True,
                    capped_spread: bool = True, check_pick_circle: bool = True) -> ColorModel:
    """Fit a sphere's colour model from a picked centre and edge pixel.

    Parameters
    ----------
    frame_bgr : ndarray, shape (H, W, 3), uint8
        One frame, OpenCV BGR order.
    center_uv, edge_uv : array_like, shape (2,)
        Picked pixel at the sphere's centre and on its rim (u right, v down).
        Their distance is the sphere's radius in pixels.
    shrink : float
        Only pixels within ``shrink * radius`` of the centre are used, which
        keeps the rim (mixed with background) out of the fit.
    min_pixels : int
        Fewest pixels a usable circle must hold.
    max_std, max_hue_std : float
        Largest per-channel standard deviation (8-bit levels; hue levels for
        the circular hue std) accepted; a larger one means the circle is not
        one colour, typically because the pick missed the sphere.
    min_saturation : float
        Below this mean saturation the hue is noise and is left out.
    background_margin : float
        Background pixels are those farther than ``background_margin *
        radius`` from the centre (every second row and column of the frame).
    llr_clip : float
        Per-channel log-likelihood-ratio clip, see :class:`ColorModel`.
    min_std : array_like, shape (6,)
        Floor of the fitted standard deviations (R, G, B, H, S, V levels): a
        small, evenly lit pick would otherwise give a model too narrow for
        sensor noise and lighting changes over the sequence.
    prior : float, optional
        Prior sphere probability per pixel; default: circle area over frame
        area, limited to [1e-4, 0.2].
    verify : bool
        Segment the pick frame with the new model and require a valid
        detection at the pick (a model that cannot find its own sphere is
        useless).
    verify_params : SegmentParams, optional
        Segmentation parameters for that check (default ``SegmentParams()``);
        pass the ones the sequence will be tracked with.
    trim_highlights : bool
        Leave bright, desaturated pixels (a washed-out highlight) out of the
        statistics. Off by default: on the real ball video of
        ``tests/test_stereo_cli.py`` the narrower model finds a false ball
        before the ball enters the view.
    reject_outliers : bool
        When the picked circle is not one colour, try again without the
        pixels farther than 3 robust standard deviations (1.4826 MAD, at
        least ``min_std``) from the median in any channel: a specular
        highlight or a speck of texture in the circle. Only while at least
        60 % of the pixels and half of the central ones remain; picks that
        pass as they are keep all their pixels (a narrower model finds
        false spheres sooner).
    calibrate_prior : bool
        When the picked core's median log-odds falls short of the seed
        threshold (``verify_params.p_seed``, the sphere's colour close to the
        background's), raise the prior until it passes by one logit, as far
        as the background's 99.9th percentile stays one logit below the
        growing threshold ``p_grow``. The model then finds its sphere on the
        pick frame without admitting the background; ``verify`` still checks
        it.
    local_fallback : bool
        With ``verify``, when the model fails its check because the frame
        holds the sphere's colour elsewhere, fit a *local* model instead: its
        background is sampled only in a window of about four picked radii
        around the pick (``ColorModel.local_radius_px``), and it is accepted
        when, in that window, the pick's region is the heaviest valid one,
        does not reach the window's edge, has about the picked radius and no
        other region has a quarter of its mass (failing that, once more with
        the prior raised past the window's scattered look-alike pixels, the
        region then centred within 0.3 picked radii of the pick and its area
        radius 0.7-1.6 of them). Searches with a local model
        cover that window around the sphere's last position instead of the
        full frame (``ColorModel.local_roi``), so look-alikes elsewhere are
        not examined; a sphere that leaves the window while unseen is not
        found again (the stereo pipeline's one exception: a view lost while
        the other camera sees the sphere is searched along the epipolar
        line, taking only a single fitting region).

    capped_spread : bool
        With ``verify``, a circle that is not one colour even without its
        outliers (a hard-lit sphere's shading, a small sphere's blurred rim,
        a link across it) is not refused at once: the model is fitted with
        each channel's spread capped at ``max_std`` / ``max_hue_std`` and
        accepted only when its detection on the pick frame (or its local
        model's) is the picked circle: centre within 0.3 picked radii of the
        pick, radius 0.85-1.6 picked radii (the edge is picked at about 80 %
        of the rim). Otherwise the "not one colour" error stands. On the
        randomised sphere family this accepts 12-14 of 600 picks more
        (seeds 0 / 3; docs/benchmarks.md).
    check_pick_circle : bool
        With ``verify``, a pick of 6 px radius or more whose model finds only part of it on the pick frame
        (a circle under 0.8 picked radii, or centred over 4 px and a fifth of the picked radius away:
        :func:`~tudorvision.stereo._pick.part_of_pick`; the lit cap of a sphere of the background's
        colour) is refused unless its local model finds the whole pick. False: the former check only.

    Returns
    -------
    ColorModel
        ``model.is_local`` tells a local model (see ``local_fallback``).

    Raises
    ------
    TudorVisionError
        ``frame_bgr`` not a BGR uint8 image; ``center_uv`` or ``edge_uv``
        outside the image; ``edge_uv`` equal to ``center_uv``; a circle with
        fewer than ``min_pixels`` pixels; a circle that is not one colour
        (with ``capped_spread``: whose capped model does not find the picked
        circle); with ``verify``, a model that does not single out the picked sphere.

    Examples
    --------
    >>> img = np.full((60, 80, 3), 90, np.uint8)
    >>> _ = cv2.circle(img, (40, 30), 10, (40, 40, 200), -1)
    >>> m = fit_color_model(img, (40, 30), (50, 30))
    >>> [round(x) for x in m.mean[:3]]   # R, G, B
    [200, 40, 40]
    """
    img = check_frame(frame_bgr)
    h, w = img.shape[:2]
    c = _check_uv(center_uv, "center_uv", w, h)
    e = _check_uv(edge_uv, "edge_uv", w, h)
    if not (0 < shrink <= 1):
        raise TudorVisionError(f"shrink: must lie in (0, 1], got {shrink}")
    min_std = np.asarray(min_std, dtype=np.float64).reshape(-1)
    if min_std.shape != (6,) or not np.all(min_std > 0):
        raise TudorVisionError(f"min_std: expected 6 positive values (R, G, B, H, S, V), got {min_std.tolist()}")
    radius = float(np.hypot(*(e - c)))
    if radius < 1.5:
        raise TudorVisionError(
            f"edge_uv: ({e[0]:g}, {e[1]:g}) is {radius:.2f} px from center_uv: the picked circle is "
            f"{2 * radius:.0f} px across, too small to fit; pick the edge pixel on the sphere's rim")
    # small picks: keep at least a 2.5 px core (a 3 px sphere picked at 80 % has r_in 1.6 px otherwise)
    r_in = max(shrink * radius, min(radius, 2.5))
    # pixels inside the shrunken circle (clipped to the image)
    x0, x1 = max(int(math.floor(c[0] - r_in)), 0), min(int(math.ceil(c[0] + r_in)), w - 1)
    y0, y1 = max(int(math.floor(c[1] - r_in)), 0), min(int(math.ceil(c[1] + r_in)), h - 1)
    yy, xx = np.mgrid[y0:y1 + 1, x0:x1 + 1]
    inside = (xx - c[0]) ** 2 + (yy - c[1]) ** 2 <= r_in ** 2
    patch = img[y0:y1 + 1, x0:x1 + 1]
    n = int(inside.sum())
    if n < min_pixels:
        raise TudorVisionError(
            f"center_uv, edge_uv: the circle (radius {radius:.1f} px, shrunk to {r_in:.1f}) holds {n} "
            f"pixels, fewer than min_pixels={min_pixels}; the picked circle is {2 * radius:.0f} px across: "
            f"pick the edge pixel on the rim (or a larger sphere image)")
    hsv_patch = cv2.cvtColor(np.ascontiguousarray(patch), cv2.COLOR_BGR2HSV)
    fg = np.concatenate([patch[inside][:, ::-1], hsv_patch[inside]], axis=1).astype(np.float64)  # R G B H S V
    d2_in = ((xx - c[0]) ** 2 + (yy - c[1]) ** 2)[inside]
    if trim_highlights:
        keep = trim_highlights_rows(fg, d2_in <= max(0.25 * r_in ** 2, 1.0), min_pixels)
        fg, d2_in = fg[keep], d2_in[keep]      # the core below is taken from the pixels kept
    core = d2_in <= max(0.25 * r_in ** 2, 1.0)
    mean, std, use_hue, bad = pick_stats(fg, min_saturation, max_std, max_hue_std)
    if bad and reject_outliers:
        # only to rescue a pick: a narrower model finds false spheres (a real video's background) sooner
        kept = reject_outlier_rows(fg, core, min_std, min_pixels)
        if len(kept) < len(fg):
            mean, std, use_hue, bad = pick_stats(kept, min_saturation, max_std, max_hue_std)
    spread_error = ""
    if bad:
        spread_error = (f"center_uv, edge_uv: the picked circle is not one colour (std {', '.join(bad)} exceeds "
                        f"max_std={max_std:g}/max_hue_std={max_hue_std:g}); is the pick on the sphere?")
        if not (verify and capped_spread):
            raise TudorVisionError(spread_error)
        std = np.minimum(std, [max_std, max_std, max_std, max_hue_std, max_std, max_std])
    # floor the spread: sensor noise and lighting changes over the sequence
    std = np.maximum(std, min_std)
    if not use_hue:
        std[HUE_INDEX] = HUE_LEVELS  # unused, but a valid number

    # background: every second pixel farther than background_margin * radius
    sub = img[::2, ::2]
    hsv_sub = cv2.cvtColor(np.ascontiguousarray(sub), cv2.COLOR_BGR2HSV)
    vv, uu = np.mgrid[0:h:2, 0:w:2]
    outside = (uu - c[0]) ** 2 + (vv - c[1]) ** 2 > (background_margin * radius) ** 2
    if outside.sum() < 100:
        raise TudorVisionError(
            f"center_uv, edge_uv: the circle (radius {radius:.1f} px) leaves too little background in "
            f"the {w}x{h} frame to fit a background model")
    background = background_pmf(np.concatenate([sub[outside][:, ::-1], hsv_sub[outside]], axis=1))
    if prior is None:
        prior = float(np.clip(math.pi * radius ** 2 / (w * h), 1e-4, 0.2))
    model = ColorModel(mean=mean, std=std, background=background, prior=prior, use_hue=use_hue,
                       llr_clip=llr_clip, center_uv=(float(c[0]), float(c[1])), radius_px=radius,
                       n_pixels=n, image_size=(w, h))
    vparams = segment_params_for_radius(verify_params, radius)
    if calibrate_prior:
        model = calibrated_prior(model, img, c, r_in, background_margin * radius, vparams)
    if verify:
        det = detect_sphere(img, model, params=vparams)
        if not det.valid or np.hypot(det.uv[0] - c[0], det.uv[1] - c[1]) > radius:
            why = det.reason if not det.valid else (
                f"the best region lies at ({det.uv[0]:.1f}, {det.uv[1]:.1f}), not at the pick")
            local, why_local = (fit_local_model(model, img, c, radius, r_in, background_margin * radius, vparams)
                                if local_fallback else (None, ""))
            if local is not None and (not spread_error
                                      or fits_pick(detect_sphere(img, local, params=vparams), c, radius)):
                return local
            if spread_error:
                raise TudorVisionError(spread_error)
            hint = (f"is the pick on the sphere, and the edge pixel on its rim ({radius:.1f} px from the centre)?"
                    + (" If so, the sphere's colour is too common in this frame: pick it in a frame with a plainer "
                       "background, or use a sphere of another colour" if why_local.startswith("its colour is")
                       else ""))
            raise TudorVisionError(
                f"center_uv, edge_uv: the colour model does not single out the picked sphere ({why}"
                f"{'; nor in its neighbourhood: ' + why_local if why_local else ''}); {hint}")
        if spread_error and not fits_pick(det, c, radius):
            raise TudorVisionError(spread_error)
        part = part_of_pick(det, c, radius) if check_pick_circle else ""
        if part:
            local = (fit_local_model(model, img, c, radius, r_in, background_margin * radius, vparams)[0]
                     if local_fallback else None)
            det_local = detect_sphere(img, local, params=vparams) if local is not None else det
            if local is not None and det_local.valid and not part_of_pick(det_local, c, radius):
                return local
            raise TudorVisionError(
                f"center_uv, edge_uv: the colour model finds only part of the picked sphere ({part}): its colour "
                f"is close to the background's there (or the edge pixel is off the rim); pick it in a frame where "
                f"it stands out, or use a sphere of another colour")
    return model


@dataclass(frozen=True)
class ColorModelSet:
    """Colour models per camera and sphere.

    Parameters
    ----------
    models : mapping
        ``{camera: {sphere: ColorModel}}`` with camera ``"left"``,
        ``"right"`` or ``"mono"`` and free sphere names (``"red"``,
        ``"green"``).

    Examples
    --------
    >>> img = np.full((60, 80, 3), 90, np.uint8)
    >>> _ = cv2.circle(img, (40, 30), 10, (40, 40, 200), -1)
    >>> s = ColorModelSet({"mono": {"red": fit_color_model(img, (40, 30), (50, 30))}})
    >>> s.cameras, s.spheres("mono")
    (('mono',), ('red',))
    """

    models: Mapping[str, Mapping[str, ColorModel]]

    def __post_init__(self):
        if not isinstance(self.models, Mapping):
            raise TudorVisionError("models: expected a mapping {camera: {sphere: ColorModel}}")
        frozen = {}
        for cam, spheres in self.models.items():
            if cam not in _CAMERAS:
                raise TudorVisionError(f"models: camera must be one of {', '.join(_CAMERAS)}, got {cam!r}")
            if not isinstance(spheres, Mapping) or not spheres:
                raise TudorVisionError(f"models: camera {cam!r} needs a non-empty mapping {{sphere: ColorModel}}")
            for name, m in spheres.items():
                if not isinstance(name, str) or not name:
                    raise TudorVisionError(f"models: sphere names must be non-empty strings, got {name!r}")
                if not isinstance(m, ColorModel):
                    raise TudorVisionError(f"models: {cam}/{name} is a {type(m).__name__}, not a ColorModel")
            frozen[cam] = MappingProxyType(dict(spheres))
        object.__setattr__(self, "models", MappingProxyType(frozen))

    @property
    def cameras(self) -> tuple:
        """Camera names in the set."""
        return tuple(self.models)

    def spheres(self, camera: str) -> tuple:
        """Sphere names modelled for ``camera``.

        Parameters
        ----------
        camera : str
            Camera name (``"left"``, ``"right"`` or ``"mono"``).

        Returns
        -------
        tuple of str
            Sphere names, in the order they were given.

        Raises
        ------
        TudorVisionError
            If the set has no model for ``camera``.
        """
        return tuple(self._camera(camera))

    def _camera(self, camera: str):
        if camera not in self.models:
            raise TudorVisionError(
                f"camera: the colour model set has no camera {camera!r} (has {', '.join(self.models)})")
        return self.models[camera]

    def for_camera(self, camera: str) -> Mapping[str, ColorModel]:
        """``{sphere: ColorModel}`` of one camera.

        Parameters
        ----------
        camera : str
            Camera name (``"left"``, ``"right"`` or ``"mono"``).

        Returns
        -------
        Mapping of str to ColorModel
            Read-only mapping from sphere name to its colour model.

        Raises
        ------
        TudorVisionError
            If the set has no model for ``camera``.
        """
        return self._camera(camera)

    def get(self, camera: str, sphere: str) -> ColorModel:
        """The model of one camera and sphere (TudorVisionError naming what is missing).

        Parameters
        ----------
        camera : str
            Camera name (``"left"``, ``"right"`` or ``"mono"``).
        sphere : str
            Sphere name, e.g. ``"red"``.

        Returns
        -------
        ColorModel
            The colour model of ``sphere`` seen by ``camera``.

        Raises
        ------
        TudorVisionError
            If the set has no model for ``camera`` or no ``sphere`` for it.
        """
        cam = self._camera(camera)
        if sphere not in cam:
            raise TudorVisionError(
                f"sphere: the colour model set has no sphere {sphere!r} for camera {camera!r} "
                f"(has {', '.join(cam)})")
        return cam[sphere]

    def colour_mismatches(self, max_deg: float = 40.0) -> list:
        """Spheres whose left and right models differ in hue: one pick likely landed on something else.

        The models' mean colours are compared as CIE a*, b* directions (white balance and shading change
        their length, not much their direction); spheres below a chroma of 10 in either camera (grey,
        unsaturated) are not compared.

        Parameters
        ----------
        max_deg : float
            Largest angle between the two a*, b* directions, degrees.

        Returns
        -------
        list of str
            One line per sphere that differs (empty when they agree or the set is not a stereo pair).
        """
        if not {"left", "right"} <= set(self.models):
            return []
        out = []
        for name in self.models["left"]:
            if name not in self.models["right"]:
                continue
            ab = [sphere_chroma(self.models[c][name].mean[:3]) for c in ("left", "right")]
            n = [float(np.hypot(*x)) for x in ab]
            if min(n) < 10.0:
                continue
            deg = math.degrees(math.acos(float(np.clip(ab[0] @ ab[1] / (n[0] * n[1]), -1.0, 1.0))))
            if deg > max_deg:
                out.append(f"{name}: the left and right picks differ in colour (hue {deg:.0f} deg apart, mean RGB "
                           f"{tuple(round(x) for x in self.models['left'][name].mean[:3])} / "
                           f"{tuple(round(x) for x in self.models['right'][name].mean[:3])}); did one land on "
                           f"another object (the other sphere in front of it)?")
        return out


def parse_pick(text: str) -> tuple:
    """Parse a ``CAMERA:SPHERE:CU,CV:EU,EV`` pick (the CLI's ``--pick``).

    Parameters
    ----------
    text : str
        Camera (``left``, ``right`` or ``mono``), sphere name, centre pixel
        and edge pixel, e.g. ``"left:red:320,240:331,240"``.

    Returns
    -------
    camera : str
    sphere : str
    center_uv, edge_uv : tuple of float

    Raises
    ------
    TudorVisionError
        Naming ``--pick`` and the text when it does not parse.

    Examples
    --------
    >>> parse_pick("left:red:320,240:331.5,240")
    ('left', 'red', (320.0, 240.0), (331.5, 240.0))
    """
    parts = str(text).split(":")
    usage = f"--pick {text!r}: expected CAMERA:SPHERE:CU,CV:EU,EV (e.g. left:red:320,240:331,240)"
    if len(parts) != 4:
        raise TudorVisionError(usage)
    cam, sphere = parts[0].strip(), parts[1].strip()
    if cam not in _CAMERAS:
        raise TudorVisionError(f"--pick {text!r}: camera must be one of {', '.join(_CAMERAS)}, got {cam!r}")
    if not sphere:
        raise TudorVisionError(f"--pick {text!r}: empty sphere name")
    pts = []
    for part in parts[2:]:
        try:
            u, v = (float(x) for x in part.split(","))
        except ValueError:
            raise TudorVisionError(usage) from None
        if not (math.isfinite(u) and math.isfinite(v)):
            raise TudorVisionError(usage)
        pts.append((u, v))
    return cam, sphere, pts[0], pts[1]


def fit_color_model_set(frames: Mapping, picks, **options) -> "ColorModelSet":
    """Fit one colour model per pick and collect them per camera and sphere.

    Parameters
    ----------
    frames : mapping of str to ndarray
        ``{camera: BGR uint8 frame}`` (the frame the picks were made on).
    picks : iterable
        ``"CAMERA:SPHERE:CU,CV:EU,EV"`` strings (see :func:`parse_pick`) or
        ``(camera, sphere, center_uv, edge_uv)`` tuples.
    **options
        Passed to :func:`fit_color_model`.

    Returns
    -------
    ColorModelSet

    Raises
    ------
    TudorVisionError
        A pick that does not parse, names a camera without a frame or is given
        twice, or whose fit fails; the message starts with the pick.
    """
    models: dict = {}
    for pick in picks:
        cam, sphere, c, e = parse_pick(pick) if isinstance(pick, str) else pick
        label = pick if isinstance(pick, str) else f"{cam}:{sphere}"
        if cam not in frames:
            raise TudorVisionError(f"--pick {label!r}: no frame for camera {cam!r} (have {', '.join(frames)})")
        if sphere in models.get(cam, {}):
            raise TudorVisionError(f"--pick {label!r}: sphere {sphere!r} picked twice for camera {cam!r}")
        try:
            model = fit_color_model(frames[cam], c, e, **options)
        except TudorVisionError as exc:
            raise TudorVisionError(f"--pick {label!r}: {exc}") from None
        models.setdefault(cam, {})[sphere] = model
    if not models:
        raise TudorVisionError("picks: at least one --pick is needed")
    return ColorModelSet(models)


def save_color_models(model_set: ColorModelSet, path) -> None:
    """Write a :class:`ColorModelSet` to a YAML (``.yaml``/``.yml``) or JSON file.

    The file holds ``format: tudorvision.colormodel``, ``version: 1`` and
    ``cameras: {camera: {sphere: {channels, mean, std, prior, use_hue,
    llr_clip, center_uv, radius_px, n_pixels, image_size, background}}}``.
    Hue is in OpenCV levels (0..179), all other channels in 8-bit levels.

    Parameters
    ----------
    model_set : ColorModelSet
        Colour models per camera and sphere.
    path : str or Path
        Output file; a ``.json`` suffix (any case) writes JSON, anything
        else YAML. Missing parent folders are created. Written atomically: a
        failed write leaves a previous file intact.

    Raises
    ------
    TudorVisionError
        If ``model_set`` is not a :class:`ColorModelSet`, or the file cannot
        be written (disk full, read-only folder).
    """
    if not isinstance(model_set, ColorModelSet):
        raise TudorVisionError(f"model_set: expected a ColorModelSet, got {type(model_set).__name__}")
    doc = {
        "format": _FORMAT,
        "version": _VERSION,
        "cameras": {cam: {name: m.to_dict() for name, m in spheres.items()}
                    for cam, spheres in model_set.models.items()},
    }
    path = os.fspath(path)
    with atomic_write(path, "w") as fh:
        if path.lower().endswith(".json"):
            json.dump(doc, fh, indent=1)
        else:
            import yaml

            # flow style for the long number lists keeps the file readable
            yaml.safe_dump(doc, fh, sort_keys=False, default_flow_style=None, width=120)


def load_color_models(path) -> ColorModelSet:
    """Read a file written by :func:`save_color_models`.

    Parameters
    ----------
    path : str or Path
        Colour model file; ``.json`` (any case) is read as JSON, anything
        else as YAML.

    Returns
    -------
    ColorModelSet
        The colour models per camera and sphere.

    Raises
    ------
    TudorVisionError
        The file is missing, not YAML/JSON, or malformed; the message starts
        with the file name.
    """
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
    except OSError as exc:
        raise TudorVisionError(f"{path}: cannot read colour model file ({exc.strerror})") from None
    try:
        if path.lower().endswith(".json"):
            doc = json.loads(text)
        else:
            import yaml

            doc = yaml.safe_load(text)
    except Exception as exc:  # yaml.YAMLError / json.JSONDecodeError
        raise TudorVisionError(f"{path}: not a valid YAML/JSON colour model file ({exc.__class__.__name__})") from None
    if not isinstance(doc, dict) or doc.get("format") != _FORMAT:
        raise TudorVisionError(f"{path}: not a colour model file (expected format: {_FORMAT})")
    if doc.get("version") != _VERSION:
        raise TudorVisionError(f"{path}: unsupported colour model version {doc.get('version')!r}")
    cams = doc.get("cameras")
    if not isinstance(cams, dict) or not cams:
        raise TudorVisionError(f"{path}: 'cameras' must map camera names to spheres")
    models = {}
    for cam, spheres in cams.items():
        if not isinstance(spheres, dict):
            raise TudorVisionError(f"{path}: cameras/{cam} must map sphere names to models")
        models[cam] = {}
        for name, data in spheres.items():
            try:
                models[cam][name] = ColorModel.from_dict(data)
            except TudorVisionError as exc:
                raise TudorVisionError(f"{path}: cameras/{cam}/{name}: {exc}") from None
    try:
        return ColorModelSet(models)
    except TudorVisionError as exc:
        raise TudorVisionError(f"{path}: {exc}") from None
