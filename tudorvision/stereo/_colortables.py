"""The colour model of one sphere in one camera: per-channel log-likelihood-ratio tables (internal module).

:class:`ColorModel` is re-exported by :mod:`tudorvision.stereo.colormodel` (the
fitting, model sets and files) and :mod:`tudorvision.stereo`; import it from
there. It lives here, below :mod:`.segment`, because segmentation reads its
tables while :func:`~tudorvision.stereo.colormodel.fit_color_model` verifies a
new model with :func:`~tudorvision.stereo.segment.detect_sphere`: the imports
go colormodel -> segment -> this module.

Channel order is ``R, G, B, H, S, V``; H is OpenCV's 8-bit hue, 0..179,
circular.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from tudorvision._checks import TudorVisionError

__all__ = ["CHANNELS", "HUE_LEVELS", "CHANNEL_LEVELS", "HUE_INDEX", "LOG_ODDS_Q", "ColorModel"]

#: Channel order of every model array.
CHANNELS = ("R", "G", "B", "H", "S", "V")
#: Number of levels of OpenCV's 8-bit hue.
HUE_LEVELS = 180
#: Number of levels of each channel, in :data:`CHANNELS` order.
CHANNEL_LEVELS = (256, 256, 256, HUE_LEVELS, 256, 256)
#: Index of the (circular) hue channel in :data:`CHANNELS`.
HUE_INDEX = 3
#: quantisation of the 16-bit log-odds tables (``plane_tables_q``): units of 1 / LOG_ODDS_Q
LOG_ODDS_Q = 16


def _gauss_log_pmf(mean: float, std: float, levels: int, circular: bool) -> np.ndarray:
    x = np.arange(levels, dtype=np.float64)
    d = x - mean
    if circular:
        d = (d + levels / 2.0) % levels - levels / 2.0
    logp = -0.5 * (d / std) ** 2
    # normalise over the discrete levels (a proper pmf, comparable with the histogram)
    mx = logp.max()
    return logp - (mx + math.log(np.exp(logp - mx).sum()))


def _readonly(arr: np.ndarray) -> np.ndarray:
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, kw_only=True, eq=False)
class ColorModel:
    """Colour model of one sphere seen by one camera.

    Parameters
    ----------
    mean, std : ndarray, shape (6,)
        Per-channel Gaussian of the sphere pixels, order ``R, G, B, H, S, V``;
        8-bit levels, hue in OpenCV levels 0..179 (circular mean and std).
    background : ndarray, shape (6, 256)
        Per-channel probability of each level among background pixels (rows
        sum to 1; the hue row uses the first 180 entries, the rest are 0).
    prior : float
        Prior probability that a pixel belongs to the sphere, in (0, 1).
    use_hue : bool
        Whether the hue channel takes part (False for unsaturated spheres,
        whose hue is noise).
    llr_clip : float
        Each channel's log-likelihood ratio is clipped to ``[-llr_clip,
        llr_clip]`` so that one outlying channel cannot veto the others alone.
    blur_min_std, blur_min_hue_std : float
        Smallest standard deviation (8-bit levels; hue levels) of the
        blur-tolerant tables used when motion blur is expected: a blur streak
        mixes the sphere's colour with the background's, which mostly moves
        R, G, B, S and V and much less the hue.
    center_uv : tuple of float
        Picked centre pixel (u right, v down), for reference and start-up.
    radius_px : float
        Picked radius in pixels.
    n_pixels : int
        Number of pixels the Gaussians were fitted from.
    image_size : tuple of int
        ``(width, height)`` of the frame the model was picked on.
    local_radius_px : float or None
        ``None`` (default): a global model, whose background was sampled over
        the whole frame; it singles the sphere out anywhere in the frame. A
        number: a *local* model, whose background was sampled only in the
        square window of this half size (pixels) around the pick (the whole
        frame holds the sphere's colour elsewhere). It singles the sphere out
        only in such a neighbourhood, so a search with it that would cover
        the full frame covers :meth:`local_roi` instead.

    Attributes
    ----------
    log_ratio : ndarray, shape (6, 256), float32
        Per-channel log-likelihood ratio tables ``log p(x|sphere) -
        log p(x|background)``, clipped (hue entries 180..255 repeat the circle
        and are never used by OpenCV's hue).
    log_prior_odds : float
        ``log(prior / (1 - prior))``.
    plane_tables : ndarray, shape (6, 256), float32
        ``log_ratio`` rows reordered to the image planes B, G, R, H, S, V, for
        ``cv2.LUT``.
    log_ratio_blur, plane_tables_blur : ndarray, shape (6, 256), float32
        The same with the blur-tolerant spreads.
    plane_tables_q, plane_tables_blur_q : ndarray, shape (6, 256), int16
        ``plane_tables`` and ``plane_tables_blur`` in units of
        ``1 / LOG_ODDS_Q``, rounded: the coarse pass of the full-frame search
        sums them in 16 bits (error at most 0.16 over six planes).

    Notes
    -----
    Instances compare by identity (``eq=False``: they hold arrays); compare
    fields with ``numpy.testing`` where needed.
    """

    mean: np.ndarray
    std: np.ndarray
    background: np.ndarray
    prior: float
    use_hue: bool = True
    llr_clip: float = 8.0
    blur_min_std: float = 40.0
    blur_min_hue_std: float = 4.0
    center_uv: tuple = (float("nan"), float("nan"))
    radius_px: float = float("nan")
    n_pixels: int = 0
    image_size: tuple = (0, 0)
    local_radius_px: float | None = None
    log_ratio: np.ndarray = field(init=False, repr=False)
    log_prior_odds: float = field(init=False, repr=False)
    plane_tables: np.ndarray = field(init=False, repr=False)
    log_ratio_blur: np.ndarray = field(init=False, repr=False)
    plane_tables_blur: np.ndarray = field(init=False, repr=False)
    plane_tables_q: np.ndarray = field(init=False, repr=False)
    plane_tables_blur_q: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        mean = np.array(self.mean, dtype=np.float64).reshape(-1)
        std = np.array(self.std, dtype=np.float64).reshape(-1)
        bg = np.array(self.background, dtype=np.float64)
        if mean.shape != (6,) or not np.all(np.isfinite(mean)):
            raise TudorVisionError(f"mean: expected 6 finite values (R, G, B, H, S, V), got {mean.shape}")
        if std.shape != (6,) or not np.all(np.isfinite(std)) or np.any(std <= 0):
            raise TudorVisionError("std: expected 6 finite positive values (R, G, B, H, S, V)")
        if bg.shape != (6, 256) or not np.all(np.isfinite(bg)) or np.any(bg < 0):
            raise TudorVisionError(f"background: expected 6 x 256 non-negative values, got {bg.shape}")
        if not (0.0 < float(self.prior) < 1.0):
            raise TudorVisionError(f"prior: must lie in (0, 1), got {self.prior}")
        if not (float(self.llr_clip) > 0):
            raise TudorVisionError(f"llr_clip: must be positive, got {self.llr_clip}")
        if not (float(self.blur_min_std) > 0 and float(self.blur_min_hue_std) > 0):
            raise TudorVisionError(
                f"blur_min_std, blur_min_hue_std: must be positive, got {self.blur_min_std}, {self.blur_min_hue_std}")
        bg = bg.copy()
        bg[HUE_INDEX, HUE_LEVELS:] = 0.0
        for c in range(6):
            s = bg[c, :CHANNEL_LEVELS[c]].sum()
            if s <= 0:
                raise TudorVisionError(f"background: channel {CHANNELS[c]} has no mass")
            bg[c] /= s
        mean[HUE_INDEX] %= HUE_LEVELS
        for name, arr in (("mean", mean), ("std", std), ("background", bg)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "prior", float(self.prior))
        object.__setattr__(self, "use_hue", bool(self.use_hue))
        object.__setattr__(self, "center_uv", tuple(float(x) for x in self.center_uv))
        object.__setattr__(self, "image_size", tuple(int(x) for x in self.image_size))
        if self.local_radius_px is not None:
            if not (math.isfinite(float(self.local_radius_px)) and float(self.local_radius_px) >= 1.0):
                raise TudorVisionError(f"local_radius_px: must be None or at least 1 px, got {self.local_radius_px}")
            object.__setattr__(self, "local_radius_px", float(self.local_radius_px))

        table = self._tables(std)
        object.__setattr__(self, "log_ratio", table)
        object.__setattr__(self, "log_prior_odds", math.log(self.prior / (1.0 - self.prior)))
        # one contiguous float32 row per image plane, plane order B, G, R, H, S, V
        order = [2, 1, 0, 3, 4, 5]
        object.__setattr__(self, "plane_tables", _readonly(np.ascontiguousarray(table[order])))
        std_blur = np.maximum(std, self.blur_min_std)
        std_blur[HUE_INDEX] = max(std[HUE_INDEX], self.blur_min_hue_std)
        blur = self._tables(std_blur)
        object.__setattr__(self, "log_ratio_blur", blur)
        object.__setattr__(self, "plane_tables_blur", _readonly(np.ascontiguousarray(blur[order])))
        for name in ("plane_tables", "plane_tables_blur"):
            quantised = np.round(getattr(self, name).astype(np.float64) * LOG_ODDS_Q).astype(np.int16)
            object.__setattr__(self, name + "_q", _readonly(quantised))

    @property
    def is_local(self) -> bool:
        """Whether the model singles its sphere out only near the pick (``local_radius_px`` set)."""
        return self.local_radius_px is not None

    def local_roi(self, anchor_uv, width: int, height: int):
        """The window a local model searches instead of a full frame.

        Parameters
        ----------
        anchor_uv : array_like, shape (2,), or None
            Where the sphere was last seen (u right, v down, pixels); None or
            not finite: the picked centre ``center_uv``.
        width, height : int
            Frame size in pixels.

        Returns
        -------
        tuple of int or None
            ``(x, y, w, h)``: the square of half size ``local_radius_px``
            around the anchor, clipped to the frame; None for a global model
            (search the full frame) or when the window leaves the frame.

        Examples
        --------
        >>> bg = np.ones((6, 256))
        >>> m = ColorModel(mean=[200, 40, 40, 0, 200, 200], std=[9] * 6, background=bg, prior=0.01,
        ...                center_uv=(50, 40), local_radius_px=20)
        >>> m.local_roi(None, 640, 480), m.local_roi((10, 10), 640, 480)
        ((30, 20, 41, 41), (0, 0, 31, 31))
        """
        if self.local_radius_px is None:
            return None
        uv = np.asarray(self.center_uv if anchor_uv is None else anchor_uv, dtype=np.float64).reshape(-1)
        if uv.shape != (2,) or not np.all(np.isfinite(uv)):
            uv = np.asarray(self.center_uv, dtype=np.float64)
        if not np.all(np.isfinite(uv)):
            return None
        h = int(math.ceil(self.local_radius_px))
        u, v = int(round(uv[0])), int(round(uv[1]))
        x0, y0, x1, y1 = max(u - h, 0), max(v - h, 0), min(u + h + 1, int(width)), min(v + h + 1, int(height))
        if x1 - x0 < 3 or y1 - y0 < 3:
            return None
        return x0, y0, x1 - x0, y1 - y0

    def _tables(self, std: np.ndarray) -> np.ndarray:
        clip = float(self.llr_clip)
        table = np.zeros((6, 256), dtype=np.float64)
        for c in range(6):
            n = CHANNEL_LEVELS[c]
            if c == HUE_INDEX and not self.use_hue:
                continue
            # the background pmf already carries a uniform floor, so log is finite
            log_bg = np.log(np.maximum(self.background[c, :n], 1e-300))
            llr = _gauss_log_pmf(self.mean[c], std[c], n, circular=(c == HUE_INDEX)) - log_bg
            table[c, :n] = np.clip(llr, -clip, clip)
            if n < 256:  # never produced by cvtColor; keep the circle going
                table[c, n:] = table[c, np.arange(n, 256) % n]
        return _readonly(table.astype(np.float32))

    def to_dict(self) -> dict:
        """Plain-data form used by :func:`~tudorvision.stereo.colormodel.save_color_models`.

        Returns
        -------
        dict
            Lists and numbers only (JSON and YAML safe); the derived tables
            are left out and rebuilt by :meth:`from_dict`.
        """
        return {
            "channels": list(CHANNELS),
            "mean": [round(float(x), 6) for x in self.mean],
            "std": [round(float(x), 6) for x in self.std],
            "prior": float(self.prior),
            "use_hue": bool(self.use_hue),
            "llr_clip": float(self.llr_clip),
            "blur_min_std": float(self.blur_min_std),
            "blur_min_hue_std": float(self.blur_min_hue_std),
            "center_uv": [float(x) for x in self.center_uv],
            "radius_px": float(self.radius_px),
            "n_pixels": int(self.n_pixels),
            "image_size": [int(x) for x in self.image_size],
            "local_radius_px": None if self.local_radius_px is None else float(self.local_radius_px),
            "background": [[float(f"{x:.6g}") for x in row[:n]] for row, n in zip(self.background, CHANNEL_LEVELS)],
        }

    @classmethod
    def from_dict(cls, data: Mapping) -> "ColorModel":
        """Inverse of :meth:`to_dict`.

        Parameters
        ----------
        data : mapping
            As written by :meth:`to_dict`; ``mean``, ``std``, ``background``
            and ``prior`` are required, the other fields take their defaults.

        Returns
        -------
        ColorModel

        Raises
        ------
        TudorVisionError
            Malformed data (missing keys, wrong channel order or row lengths,
            values the constructor rejects).
        """
        if not isinstance(data, Mapping):
            raise TudorVisionError(f"expected a mapping, got {type(data).__name__}")
        missing = [k for k in ("mean", "std", "background", "prior") if k not in data]
        if missing:
            raise TudorVisionError(f"missing key(s) {', '.join(missing)}")
        if list(data.get("channels", CHANNELS)) != list(CHANNELS):
            raise TudorVisionError(f"channels must be {list(CHANNELS)}, got {data.get('channels')}")
        bg_rows = data["background"]
        if not isinstance(bg_rows, (list, tuple)) or len(bg_rows) != 6:
            raise TudorVisionError("background: expected 6 rows (R, G, B, H, S, V)")
        bg = np.zeros((6, 256))
        for c, (row, n) in enumerate(zip(bg_rows, CHANNEL_LEVELS)):
            try:
                r = np.asarray(row, dtype=np.float64)
            except (TypeError, ValueError):
                raise TudorVisionError(f"background: row {CHANNELS[c]} is not numeric") from None
            if r.shape != (n,):
                raise TudorVisionError(f"background: row {CHANNELS[c]} needs {n} values, got {r.shape}")
            bg[c, :n] = r
        try:
            return cls(
                mean=np.asarray(data["mean"], dtype=np.float64),
                std=np.asarray(data["std"], dtype=np.float64),
                background=bg,
                prior=float(data["prior"]),
                use_hue=bool(data.get("use_hue", True)),
                llr_clip=float(data.get("llr_clip", 8.0)),
                blur_min_std=float(data.get("blur_min_std", 40.0)),
                blur_min_hue_std=float(data.get("blur_min_hue_std", 4.0)),
                center_uv=tuple(data.get("center_uv", (float("nan"), float("nan")))),
                radius_px=float(data.get("radius_px", float("nan"))),
                n_pixels=int(data.get("n_pixels", 0)),
                image_size=tuple(data.get("image_size", (0, 0))),
                local_radius_px=(None if data.get("local_radius_px") is None
                                 else float(data["local_radius_px"])),
            )
        except (TypeError, ValueError) as exc:
            if isinstance(exc, TudorVisionError):
                raise
            raise TudorVisionError(str(exc)) from None
