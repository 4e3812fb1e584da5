"""What the sphere segmentation is told and what it finds: :class:`SegmentParams`, :class:`SphereDetection`;
what the stereo pipeline finds in a pair: :class:`StereoFrameResult`.

The segmentation itself is :mod:`tudorvision.stereo.segment`, the pipeline :mod:`tudorvision.stereo.pipeline`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from tudorvision._checks import TudorVisionError

__all__ = ["SegmentParams", "SphereDetection", "StereoFrameResult", "segment_params_for_radius"]

_NAN2 = (float("nan"), float("nan"))


@dataclass(frozen=True, kw_only=True)
class SegmentParams:
    """Thresholds and plausibility limits of the sphere segmentation.

    Parameters
    ----------
    p_seed : float
        Posterior probability a seed pixel needs (before erosion).
    p_grow : float
        Posterior probability a pixel needs to join a region grown from a
        seed; ``p_grow <= p_seed``.
    erode_radius_px : int
        Radius of the elliptic erosion element for the seeds (0: none).
    min_area_px, max_area_px : float
        Plausible region area in pixels.
    min_mean_prob : float
        Smallest mean posterior over the region.
    min_circularity : float
        Smallest ``sqrt(lam2 / lam1)`` without motion blur. A sphere whose colour model misses
        its shaded half (lit from one side, picked under other light) shows a half disc,
        ``sqrt(1/4 - 16/(9 pi^2)) / (1/2) = 0.53``: the default 0.5 keeps it.
    motion_blur : bool
        Blur is expected: use ``min_circularity_blur`` instead.
    min_circularity_blur : float
        Smallest circularity accepted when ``motion_blur`` is set.
    min_fill, max_fill : float
        Accepted range of ``area / (4 pi sqrt(lam1 lam2))``.
    weighting : {"probability", "binary"}
        Centroid weights, see the module docstring.
    reject_border : bool
        Reject regions touching the image border (the sphere is partly out of
        view and its centroid biased).
    centroid : {"shape", "moment", "rim_moment"}
        How the image position is measured (module docstring, step 4):
        ``"moment"``, the region's first moment; ``"shape"`` (default), the
        centre of a circle fitted robustly to the region's rim, robust to
        partial occlusion and to parts the colour model misses (falls back to
        the moment when the circle does not explain the rim; under motion
        blur the moment is always used); ``"rim_moment"``, the binary first
        moment of the region grown to ``rim_prob`` within 2 px (the tracker
        uses it for fast, smoothly moving spheres, see
        :class:`~tudorvision.stereo.tracker2d.TrackerParams`).
    rim_prob : float
        Probability level of the rim the circle is fitted to (the region
        grows to it within 2 px).
    lens_check : bool
        Use the moment when the rim points off the circle lie on a second
        circle of similar radius (the lens-shaped core of a blur streak)
        and the moment sits halfway between the two centres. Off by default:
        on the virtual lab it helps on blurred frames (step 3D error
        -0.2 mm on two of five seeds) but trips on partly hidden static
        spheres (static centroid RMS 0.13 -> 0.23 px).
    rim_tol_px : float
        Rim points within ``max(rim_tol_px, rim_tol_frac * r)`` of the fitted
        circle are inliers (``r``: the region's area radius, px).
    rim_tol_frac : float
        Inlier tolerance as a fraction of the sphere's radius: a real rim is
        blurred and JPEG-ringed over a width that grows with the sphere (on
        the labelled real videos, 0.06 cut the median centre error from
        4.7-12 px to 2.2-3.1 px; ``0`` gives the fixed ``rim_tol_px``).
    min_rim_fraction : float
        Smallest fraction of the rim points the circle must explain to be used
        (fingers holding a ball hide half of its rim).
    chroma_edge_below : float
        With ``centroid="shape"``: when the colour-rim circle explains less
        than this fraction of the rim points (or was not used), the rim is
        searched again on the sphere's chroma edge along rays
        (:func:`~tudorvision.stereo.rim_edge.refine_circle_on_chroma`;
        ``method="chroma"``): a washed-out highlight, a shaded limb or a
        light ring the colour model rejects then no longer cut into the rim
        (labelled real balls: median centre error 2.6 -> 1.2 px; their rim
        fractions are 0.26-0.76). Fully visible, evenly coloured spheres keep
        the colour rim and its speed (0.9 triggered it on a quarter of the
        virtual lab's blurred step frames and cost a third of the
        throughput; 0.8 on 6 %). 0 turns it off.
    chroma_edge_below_large, chroma_edge_large_px : float
        For spheres whose region's area radius is at least
        ``chroma_edge_large_px`` (20 px) the chroma edge is searched below
        ``max(chroma_edge_below, chroma_edge_below_large)`` of the rim
        explained; 1 (the default) searches it on every such sphere. On a
        large sphere a tenth of the rim is tens of pixels of highlight or
        shaded limb, not pixel noise (sphere family, 30-80 px bin: median
        centre error 0.50 -> 0.17 px with 0.9 at 25 px), and a colour region
        that stops short of a shaded limb all round still has a round rim
        that the circle explains in full, 1-4 px inside the silhouette and
        off its centre (seed 0, 20-80 px views: p90 centre error 1.05 ->
        0.48 px at 20-25 px with 1 at 20 px). The virtual lab's spheres
        (8-12 px) are not affected, nor is their throughput.
    edge_refine : bool
        With ``centroid="shape"``: refine the circle on the luma edge
        (module docstring, step 4c). Use it for JPEG frames and video
        (chroma subsampled): on the virtual lab it brings the centroid RMS
        from 0.43 to 0.13 px there; on lossless frames it changes little.
    edge_min_contrast : float
        Smallest sphere-to-background luma difference (grey levels) of a ray
        the luma refinement uses.
    coarse_step : int
        Full-frame search runs coarse to fine: candidate regions are found on
        the frame decimated by ``coarse_step`` (nearest neighbour, no
        erosion), then each of the ``max_candidates`` heaviest is segmented at
        full resolution in a window around it, widened until the region fits;
        the result equals a full-resolution search whenever the coarse pass
        sees the sphere (spheres of radius >= about ``coarse_step`` px).
        1 searches the full frame at full resolution.
    max_candidates : int
        Coarse candidates refined at full resolution (the heaviest first); while none of them is a
        valid sphere, up to three times as many more are tried (a large object of the sphere's
        colour, such as a box, must not hide it).
    """

    p_seed: float = 0.999
    p_grow: float = 0.99
    erode_radius_px: int = 1
    min_area_px: float = 8.0
    max_area_px: float = 40000.0
    min_mean_prob: float = 0.6
    min_circularity: float = 0.5
    motion_blur: bool = False
    min_circularity_blur: float = 0.12
    min_fill: float = 0.7
    max_fill: float = 1.3
    weighting: str = "probability"
    reject_border: bool = True
    centroid: str = "shape"
    rim_prob: float = 0.5
    lens_check: bool = False
    rim_tol_px: float = 0.75
    rim_tol_frac: float = 0.06
    min_rim_fraction: float = 0.3
    chroma_edge_below: float = 0.8
    chroma_edge_below_large: float = 1.0
    chroma_edge_large_px: float = 20.0
    edge_refine: bool = False
    edge_min_contrast: float = 8.0
    coarse_step: int = 2
    max_candidates: int = 4

    def __post_init__(self):
        if not (0.0 < self.p_grow <= self.p_seed < 1.0):
            raise TudorVisionError(
                f"p_grow, p_seed: need 0 < p_grow <= p_seed < 1, got {self.p_grow}, {self.p_seed}")
        if int(self.erode_radius_px) != self.erode_radius_px or self.erode_radius_px < 0:
            raise TudorVisionError(f"erode_radius_px: must be a non-negative integer, got {self.erode_radius_px}")
        if not (0 <= self.min_area_px <= self.max_area_px):
            raise TudorVisionError(
                f"min_area_px, max_area_px: need 0 <= min <= max, got {self.min_area_px}, {self.max_area_px}")
        if not (0.0 <= self.min_mean_prob <= 1.0):
            raise TudorVisionError(f"min_mean_prob: must lie in [0, 1], got {self.min_mean_prob}")
        if not (0.0 <= self.min_circularity_blur <= self.min_circularity <= 1.0):
            raise TudorVisionError("min_circularity_blur, min_circularity: need 0 <= blur <= plain <= 1")
        if not (0.0 <= self.min_fill <= self.max_fill):
            raise TudorVisionError(f"min_fill, max_fill: need 0 <= min <= max, got {self.min_fill}, {self.max_fill}")
        if int(self.coarse_step) != self.coarse_step or self.coarse_step < 1:
            raise TudorVisionError(f"coarse_step: must be a positive integer, got {self.coarse_step}")
        if int(self.max_candidates) != self.max_candidates or self.max_candidates < 1:
            raise TudorVisionError(f"max_candidates: must be a positive integer, got {self.max_candidates}")
        if self.centroid not in ("shape", "moment", "rim_moment"):
            raise TudorVisionError(
                f"centroid: must be 'shape', 'moment' or 'rim_moment', got {self.centroid!r}")
        if not (0.0 < self.rim_prob <= self.p_grow):
            raise TudorVisionError(f"rim_prob: need 0 < rim_prob <= p_grow, got {self.rim_prob}")
        if not (self.rim_tol_px > 0.0):
            raise TudorVisionError(f"rim_tol_px: must be positive, got {self.rim_tol_px}")
        if not (0.0 <= self.rim_tol_frac < 0.5):
            raise TudorVisionError(f"rim_tol_frac: must lie in [0, 0.5), got {self.rim_tol_frac}")
        if not (0.0 < self.min_rim_fraction <= 1.0):
            raise TudorVisionError(f"min_rim_fraction: must lie in (0, 1], got {self.min_rim_fraction}")
        if not (0.0 <= self.chroma_edge_below <= 1.0):
            raise TudorVisionError(f"chroma_edge_below: must lie in [0, 1], got {self.chroma_edge_below}")
        if not (0.0 <= self.chroma_edge_below_large <= 1.0):
            raise TudorVisionError(f"chroma_edge_below_large: must lie in [0, 1], got {self.chroma_edge_below_large}")
        if not (self.chroma_edge_large_px > 0.0):
            raise TudorVisionError(f"chroma_edge_large_px: must be positive, got {self.chroma_edge_large_px}")
        if not (self.edge_min_contrast >= 0.0):
            raise TudorVisionError(f"edge_min_contrast: must be >= 0 grey levels, got {self.edge_min_contrast}")
        if self.weighting not in ("probability", "binary"):
            raise TudorVisionError(f"weighting: must be 'probability' or 'binary', got {self.weighting!r}")


def segment_params_for_radius(params: SegmentParams | None, radius_px: float) -> SegmentParams:
    """Segmentation parameters scaled to a sphere of a given apparent radius.

    The fixed defaults of :class:`SegmentParams` suit spheres of about
    8-40 px radius. For a picked or tracked radius ``r`` this returns a copy
    in which the seed erosion is ``clamp(round(r / 8), 1, max(erode, 3))`` px
    for ``r >= 4`` and none below (a 1 px erosion erases a 3 px sphere's
    seeds), the area limits bracket the sphere (``min_area_px`` at most half
    the disc, ``max_area_px`` at least eight times it) and the full-frame
    search runs at full resolution below 4 px (the decimated coarse pass
    would miss the sphere).

    Parameters
    ----------
    params : SegmentParams or None
        Parameters to scale (``None``: ``SegmentParams()``).
    radius_px : float
        Apparent sphere radius in pixels (e.g. the distance from a picked
        centre to a picked rim pixel).

    Returns
    -------
    SegmentParams

    Raises
    ------
    TudorVisionError
        ``radius_px`` not a positive finite number.

    Examples
    --------
    >>> segment_params_for_radius(None, 3.0).erode_radius_px
    0
    >>> segment_params_for_radius(None, 80.0).erode_radius_px
    3
    """
    params = SegmentParams() if params is None else params
    r = float(radius_px)
    if not (math.isfinite(r) and r > 0.0):
        raise TudorVisionError(f"radius_px: must be a positive number of pixels, got {radius_px!r}")
    erode = 0 if r < 4.0 else min(max(int(round(r / 8.0)), 1), max(int(params.erode_radius_px), 3))
    disc = math.pi * r * r
    min_area = min(params.min_area_px, max(3.0, 0.5 * disc))
    max_area = max(params.max_area_px, 8.0 * disc)
    coarse = 1 if r < 4.0 else params.coarse_step
    return replace(params, erode_radius_px=erode, min_area_px=min_area, max_area_px=max_area, coarse_step=coarse)


@dataclass(frozen=True)
class SphereDetection:
    """One sphere detection in one image.

    Parameters
    ----------
    uv : tuple of float
        Sub-pixel centroid ``(u, v)`` in full-frame pixels (u right, v down,
        pixel centres at integers); ``(nan, nan)`` when no region was found.
    area_px : float
        Region area in pixels.
    mean_prob : float
        Mean posterior probability over the region.
    circularity : float
        ``sqrt(lam2 / lam1)`` of the region's second moments (1 = round).
    valid : bool
        Whether the region passed every plausibility check.
    reason : str
        Empty when valid, otherwise why the region was rejected (or that
        none was found).
    fill : float
        ``area / (4 pi sqrt(lam1 lam2))`` (1 for a filled ellipse).
    bbox : tuple of int
        ``(x, y, w, h)`` of the region in full-frame pixels.
    touches_window : bool
        The region touches the border of the searched window where that
        border is not the image border (the window was too small).
    uv_moment : tuple of float
        The region's first moment (``uv`` with ``centroid="moment"``).
    rim_fraction : float
        Fraction of the region's rim points on the fitted circle (NaN when
        no circle was fitted: motion blur, ``centroid="moment"``, too small).
    rim_rms_px : float
        RMS distance of those rim points from the circle (px).
    method : str
        How ``uv`` was measured: ``"moment"``, ``"shape"`` (the centre of the
        circle fitted to the colour rim), ``"chroma"`` (the circle fitted to
        the chroma edge along rays), ``"edge"`` (the circle fitted to
        the luma edge) or ``"rim_moment"`` (see :class:`SegmentParams`).
    circle_radius_px : float
        Radius of the circle whose centre is ``uv`` (px; NaN for
        ``"moment"`` and ``"rim_moment"``). Unlike :attr:`radius_px` (the
        region's area) it is the sphere's apparent radius even when part of
        the sphere is hidden or outside the colour model; the stereo
        pipeline compares it between the two cameras.
    blur : bool
        Segmented as a motion-blurred sphere (the blur-tolerant tables): its region may be larger than
        the sphere.
    uv_view : tuple of float
        This view's own centre when the stereo pipeline moved ``uv`` onto the epipolar plane of the other
        view's (``PipelineOptions(epipolar_centres=True)``); ``(nan, nan)`` otherwise.
    """

    uv: tuple
    area_px: float
    mean_prob: float
    circularity: float
    valid: bool
    reason: str = ""
    fill: float = float("nan")
    bbox: tuple = (0, 0, 0, 0)
    touches_window: bool = False
    uv_moment: tuple = (float("nan"), float("nan"))
    rim_fraction: float = float("nan")
    rim_rms_px: float = float("nan")
    method: str = "moment"
    circle_radius_px: float = float("nan")
    blur: bool = False
    uv_view: tuple = (float("nan"), float("nan"))

    @property
    def radius_px(self) -> float:
        """Radius of the disc with the region's area, ``sqrt(area / pi)``."""
        return math.sqrt(self.area_px / math.pi)


@dataclass(frozen=True, eq=False)
class StereoFrameResult:
    """What the pipeline found in one stereo pair.

    Attributes
    ----------
    index : int
        0-based frame index in the sequence.
    t : float
        Frame timestamp, seconds.
    detections : dict
        ``{"left": {sphere: SphereDetection}, "right": {...}}``.
    spheres : dict of str to ndarray, shape (3,)
        Sphere centres in metres, frame ``frame``, triangulated from this pair
        alone (no rolling-shutter compensation); NaN where the sphere is
        missing in either image.
    ee : ndarray, shape (3,)
        End effector (midpoint of the spheres), NaN unless ``valid``.
    valid : bool
        Every sphere was found in both images.
    frame : str
        ``"base"`` (robot base frame) or ``"left"`` (left camera optical frame).
    latency_s : float
        Live playback: wall time from the frame being due to its result
        (decode, segmentation and triangulation); NaN when not live.
    dropped : int
        Live playback: frames dropped just before this one.
    """

    index: int
    t: float
    detections: dict
    spheres: dict
    ee: np.ndarray
    valid: bool
    frame: str
    latency_s: float = float("nan")
    dropped: int = 0

    def uv(self, camera: str, sphere: str) -> tuple:
        """Centroid ``(u, v)`` of a valid detection, else ``(nan, nan)``.

        Parameters
        ----------
        camera : str
            ``"left"`` or ``"right"``.
        sphere : str
            Sphere name, e.g. ``"red"``.

        Returns
        -------
        tuple of float
            Centroid in pixels of that camera's image (u right, v down), or
            ``(nan, nan)`` when the sphere was not found there.

        Raises
        ------
        KeyError
            If ``camera`` or ``sphere`` is not in :attr:`detections`.
        """
        d = self.detections[camera][sphere]
        return d.uv if d.valid else _NAN2
