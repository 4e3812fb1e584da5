"""Point features of a black square on white ground, with depth (section 9.1).

Image convention: ``u`` to the right, ``v`` down, pixel centres at integer
coordinates. Two centre features are offered:

* ``centroid_uv``: the first moment of the square's *image region*, with
  sub-pixel accuracy from grey-level weights (anti-aliased edges count by
  their darkness). This is the seed's "centroid of the black square". Under
  perspective it is not the projection of the square's 3-D centre unless the
  square is fronto-parallel; it equals the area centroid of the projected
  quadrilateral.
* ``center_uv``: the intersection of the diagonals of the four corners, which
  *is* the projection of the 3-D centre of a planar square under perspective.

Corners are ordered TL, TR, BR, BL in the image (by angle about the centroid,
starting nearest to the upper-left direction), so that goal and current
views correspond while the image rotation stays below 45 degrees.

Depth at a feature comes from valid depth around it: a least-squares plane
``z = a u + b v + c`` fitted to the valid samples of a window (one pass of
MAD outlier rejection), evaluated at the feature; the window median if the
plane is ill-conditioned.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["FeatureConfig", "SquareFeatures", "extract_square", "depth_at", "depth_at_many", "order_corners",
           "polygon_centroid", "diagonal_intersection"]


@dataclass(frozen=True, kw_only=True)
class FeatureConfig:
    """Options of :func:`extract_square`.

    Attributes
    ----------
    min_area_px : float
        Smallest accepted square region, pixels.
    border_px : int
        A region touching this image margin is rejected (cut square).
    min_contrast : float
        Smallest grey-level difference between ground and square (0..255).
    max_corner_fit_px : float
        Largest mean distance of the contour from its 4-gon, pixels.
    depth_window_px : int
        Half size of the depth window around a feature.
    min_depth_samples : int
        Fewest valid depth samples for a depth estimate.
    """

    min_area_px: float = 150.0
    border_px: int = 2
    min_contrast: float = 40.0
    max_corner_fit_px: float = 2.5
    depth_window_px: int = 6
    min_depth_samples: int = 12


@dataclass(frozen=True, kw_only=True, eq=False)
class SquareFeatures:
    """Features of one frame.

    Attributes
    ----------
    found : bool
        A square was found (centroid and corners valid).
    centroid_uv : ndarray, shape (2,)
        Region centroid, pixels (NaN if not found).
    center_uv : ndarray, shape (2,)
        Diagonal intersection (projected 3-D centre), pixels.
    corners_uv : ndarray, shape (4, 2)
        Corners TL, TR, BR, BL, pixels.
    depth_m : ndarray, shape (5,)
        Depth (z along the optical axis) at the centroid and at the four
        corners, metres; NaN where no valid depth was around.
    area_px : float
        Region area (grey-weighted), pixels.
    reason : str
        Why ``found`` is False ("" otherwise).
    """

    found: bool
    centroid_uv: np.ndarray
    center_uv: np.ndarray
    corners_uv: np.ndarray
    depth_m: np.ndarray
    area_px: float = 0.0
    reason: str = ""

    @property
    def centroid_depth_ok(self) -> bool:
        """Found with a finite, positive depth at the centroid."""
        return bool(self.found and np.isfinite(self.depth_m[0]) and self.depth_m[0] > 0)

    @property
    def all_depth_ok(self) -> bool:
        """Found with finite, positive depth at all five features."""
        return bool(self.found and np.all(np.isfinite(self.depth_m)) and np.all(self.depth_m > 0))

    @classmethod
    def lost(cls, reason: str) -> "SquareFeatures":
        """Features of a frame without a usable square.

        Parameters
        ----------
        reason : str
            Why no square was found.

        Returns
        -------
        SquareFeatures
            ``found=False``, all coordinates and depths NaN.
        """
        nan2 = np.full(2, np.nan)
        return cls(found=False, centroid_uv=nan2, center_uv=nan2.copy(), corners_uv=np.full((4, 2), np.nan),
                   depth_m=np.full(5, np.nan), reason=reason)


def polygon_centroid(poly_uv) -> np.ndarray:
    """Area centroid of a simple polygon, shape (2,) (shoelace formula).

    Examples
    --------
    >>> polygon_centroid([[0, 0], [2, 0], [2, 2], [0, 2]]).tolist()
    [1.0, 1.0]
    """
    p = np.asarray(poly_uv, dtype=np.float64)
    x, y = p[:, 0], p[:, 1]
    x1, y1 = np.roll(x, -1), np.roll(y, -1)
    cr = x * y1 - x1 * y
    a = cr.sum() / 2.0
    return np.array([((x + x1) * cr).sum(), ((y + y1) * cr).sum()]) / (6.0 * a)


def diagonal_intersection(corners_uv) -> np.ndarray:
    """Intersection of the diagonals TL-BR and TR-BL of ordered corners, shape (2,).

    Examples
    --------
    >>> diagonal_intersection([[0, 0], [4, 0], [4, 4], [0, 4]]).tolist()
    [2.0, 2.0]
    """
    c = np.asarray(corners_uv, dtype=np.float64)
    h = np.hstack([c, np.ones((4, 1))])
    p = _cross3(_cross3(h[0], h[2]), _cross3(h[1], h[3]))
    return p[:2] / p[2]


def _cross3(a, b):
    """Cross product of 3-vectors along the last axis (np.cross costs more than the arithmetic here)."""
    a, b = np.asarray(a), np.asarray(b)
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1], a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def order_corners(corners_uv) -> np.ndarray:
    """Order four corners TL, TR, BR, BL (image u right, v down).

    Sorted by angle about their mean, starting with the corner nearest to the
    upper-left direction (-135 degrees).

    Examples
    --------
    >>> order_corners([[4, 4], [0, 0], [0, 4], [4, 0]]).tolist()
    [[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]]
    """
    c = np.asarray(corners_uv, dtype=np.float64).reshape(4, 2)
    d = c - c.mean(axis=0)
    ang = np.arctan2(d[:, 1], d[:, 0])           # v down: clockwise on screen is increasing angle
    rel = (ang + 0.75 * np.pi) % (2 * np.pi)      # 0 at -135 deg (upper left)
    rel = np.where(rel > 1.75 * np.pi, rel - 2 * np.pi, rel)
    return c[np.argsort(rel)]


def depth_at(depth_m, uv, *, window_px: int = 6, min_samples: int = 12) -> float:
    """Robust depth at a sub-pixel image position from the valid depth around it.

    Parameters
    ----------
    depth_m : ndarray, shape (H, W)
        Depth in metres, NaN (or <= 0) invalid.
    uv : array_like, shape (2,)
        Position, pixels.
    window_px : int
        Half size of the square window.
    min_samples : int
        Fewest valid samples; fewer give NaN.

    Returns
    -------
    float
        Depth in metres, NaN if not enough valid depth.

    Examples
    --------
    >>> d = np.full((20, 20), 1.25); d[10, 10] = np.nan
    >>> round(depth_at(d, (10.3, 9.6)), 6)
    1.25
    """
    u, v = float(uv[0]), float(uv[1])
    if not (np.isfinite(u) and np.isfinite(v)):
        return float("nan")
    h, w = depth_m.shape
    iu, iv = int(round(u)), int(round(v))
    u0, u1 = max(iu - window_px, 0), min(iu + window_px + 1, w)
    v0, v1 = max(iv - window_px, 0), min(iv + window_px + 1, h)
    if u0 >= u1 or v0 >= v1:
        return float("nan")
    win = depth_m[v0:v1, u0:u1]
    with np.errstate(invalid="ignore"):
        ok = win > 0                                   # NaN compares False
    z = win[ok].astype(np.float64)
    if z.size < min_samples:
        return float("nan")
    med = float(np.median(z))
    dev = np.abs(z - med)
    mad = float(np.median(dev)) * 1.4826
    keep = dev <= max(3.0 * mad, 1e-6)
    nk = int(np.count_nonzero(keep))
    if nk < min_samples or (v1 - v0) < 3 or (u1 - u0) < 3:
        return med
    vv, uu = np.nonzero(ok)
    du = uu[keep] + (u0 - u)
    dv = vv[keep] + (v0 - v)
    zk = z[keep]
    # least-squares plane z = a du + b dv + c through the normal equations (3 x 3)
    A = np.array([[du @ du, du @ dv, du.sum()], [du @ dv, dv @ dv, dv.sum()], [du.sum(), dv.sum(), nk]], float)
    rhs = np.array([du @ zk, dv @ zk, zk.sum()])
    try:
        coef = np.linalg.solve(A, rhs)
    except np.linalg.LinAlgError:
        return float(np.median(zk))
    if not np.isfinite(coef[2]):
        return float(np.median(zk))
    return float(coef[2])


_MOMENTS: dict = {}


def _window_moments(k: int) -> np.ndarray:
    """Columns 1, g_u, g_v, g_u^2, g_u g_v, g_v^2 over a (2k+1)^2 window in row-major order, (n, 6)."""
    G = _MOMENTS.get(k)
    if G is None:
        offs = np.arange(-k, k + 1, dtype=np.float64)
        gv, gu = (x.reshape(-1) for x in np.meshgrid(offs, offs, indexing="ij"))
        G = np.stack([np.ones_like(gu), gu, gv, gu * gu, gu * gv, gv * gv], axis=1)
        G.setflags(write=False)
        _MOMENTS[k] = G
    return G


def depth_at_many(depth_m, uvs, *, window_px: int = 6, min_samples: int = 12) -> np.ndarray:
    """:func:`depth_at` for several positions at once, shape (N,) (the same estimates, vectorised).

    Windows that reach the image border, and ill-conditioned plane fits,
    go through :func:`depth_at` itself.

    Examples
    --------
    >>> vv, uu = np.mgrid[0:30, 0:30]
    >>> d = 1.0 + 0.001 * uu
    >>> depth_at_many(d, [(10.2, 12.0), (20.0, 7.5)]).round(6).tolist()
    [1.0102, 1.02]
    """
    dm = np.asarray(depth_m)
    p = np.asarray(uvs, dtype=np.float64).reshape(-1, 2)
    out = np.full(len(p), np.nan)
    h, w = dm.shape
    k = int(window_px)
    n_side = 2 * k + 1
    finite = np.all(np.isfinite(p), axis=1)
    iu = np.rint(np.where(finite, p[:, 0], 0.0)).astype(int)
    iv = np.rint(np.where(finite, p[:, 1], 0.0)).astype(int)
    inner = finite & (iu - k >= 0) & (iu + k < w) & (iv - k >= 0) & (iv + k < h) & (n_side >= 3)
    for i in np.nonzero(finite & ~inner)[0]:
        out[i] = depth_at(dm, p[i], window_px=window_px, min_samples=min_samples)
    idx = np.nonzero(inner)[0]
    if idx.size == 0:
        return out
    offs = np.arange(-k, k + 1)
    win = dm[(iv[idx, None, None] + offs[None, :, None]), (iu[idx, None, None] + offs[None, None, :])]
    win = win.reshape(len(idx), -1).astype(np.float64)
    with np.errstate(invalid="ignore"):
        ok = win > 0                                            # NaN compares False
    nv = ok.sum(axis=1)

    def _median(values, mask, counts):
        srt = np.sort(np.where(mask, values, np.inf), axis=1)  # invalid last
        lo = np.take_along_axis(srt, np.maximum((counts - 1) // 2, 0)[:, None], axis=1)[:, 0]
        hi = np.take_along_axis(srt, np.maximum(counts // 2, 0)[:, None], axis=1)[:, 0]
        return 0.5 * (lo + hi)

    med = _median(win, ok, nv)
    dev = np.abs(win - med[:, None])
    mad = _median(dev, ok, nv) * 1.4826
    keep = ok & (dev <= np.maximum(3.0 * mad, 1e-6)[:, None])
    nk = keep.sum(axis=1)
    # plane-fit sums about the feature from grid moments of each window (one product for all windows):
    # with du = g_u + a, a = iu - u: sum w du = S_u + a S_0, sum w du^2 = S_uu + 2 a S_u + a^2 S_0, ...
    G = _window_moments(k)
    S0, Su, Sv, Suu, Suv, Svv = (keep.astype(np.float64) @ G).T
    Z0, Zu, Zv = (np.where(keep, win, 0.0) @ G[:, :3]).T
    a = iu[idx] - p[idx, 0]
    b = iv[idx] - p[idx, 1]
    su, sv = Su + a * S0, Sv + b * S0
    A = np.empty((len(idx), 3, 3))
    A[:, 0, 0] = Suu + 2 * a * Su + a * a * S0
    A[:, 0, 1] = A[:, 1, 0] = Suv + a * Sv + b * Su + a * b * S0
    A[:, 1, 1] = Svv + 2 * b * Sv + b * b * S0
    A[:, 0, 2] = A[:, 2, 0] = su
    A[:, 1, 2] = A[:, 2, 1] = sv
    A[:, 2, 2] = nk
    rhs = np.stack([Zu + a * Z0, Zv + b * Z0, Z0], axis=1)
    fit = nk >= min_samples
    det = np.linalg.det(A)
    well = fit & (np.abs(det) > 1e-9 * np.maximum(A[:, 0, 0] * A[:, 1, 1] * A[:, 2, 2], 1e-300))
    c = np.full(len(idx), np.nan)
    if well.any():
        c[well] = np.linalg.solve(A[well], rhs[well][..., None])[:, 2, 0]
    res = np.where(nv < min_samples, np.nan, np.where(fit, c, med))
    for j in np.nonzero((nv >= min_samples) & fit & ~(well & np.isfinite(c)))[0]:
        res[j] = depth_at(dm, p[idx[j]], window_px=window_px, min_samples=min_samples)
    out[idx] = res
    return out


def _largest_inner_component(mask: np.ndarray, border: int, min_area: float):
    """Bounding box ``(x, y, w, h)`` of the largest 8-connected blob of ``mask`` clear of a ``border`` margin.

    The same choice as ``cv2.connectedComponentsWithStats`` over the whole
    mask (largest pixel count among blobs with at least ``min_area`` pixels
    whose box keeps ``border`` pixels from the image edges), at a fraction of
    its cost: blobs are found as contours, and only candidates that
    could win are counted exactly (a labelling of their box alone).
    """
    import cv2
    H, W = mask.shape
    # all borders (outer and hole): a blob inside another blob's hole is found too; a hole border
    # lies on its enclosing blob, which it then stands for
    cnts, _ = cv2.findContours(mask, cv2.RETR_LIST, cv2.CHAIN_APPROX_SIMPLE)
    cands = []
    for c in cnts:
        x, y, w, h = cv2.boundingRect(c)
        if x < border or y < border or x + w > W - border or y + h > H - border:
            continue
        upper = int(np.count_nonzero(mask[y:y + h, x:x + w]))      # >= the blob's own pixel count
        if upper >= min_area:
            cands.append((upper, x, y, w, h, c[0, 0]))
    best, best_area = None, -1
    for upper, x, y, w, h, p0 in sorted(cands, key=lambda t: -t[0]):
        if upper <= best_area:
            break
        _, lab, st, _ = cv2.connectedComponentsWithStats(mask[y:y + h, x:x + w], connectivity=8)
        area = int(st[lab[p0[1] - y, p0[0] - x], 4])
        if area >= min_area and area > best_area:
            best, best_area = (x, y, w, h), area
    return best


_K5 = np.ones((5, 5), np.uint8)
_K3 = np.ones((3, 3), np.uint8)


def extract_square(bgr, depth_m=None, *, config: FeatureConfig = FeatureConfig()) -> SquareFeatures:
    """Find the black square: sub-pixel centroid, ordered corners, depth at each.

    Parameters
    ----------
    bgr : ndarray, shape (H, W, 3) uint8 or (H, W)
        Colour (BGR) or grey image.
    depth_m : ndarray, shape (H, W), optional
        Registered depth in metres, NaN invalid. Without it all depths are NaN.
    config : FeatureConfig
        Area, contrast, corner-fit and depth-window thresholds.

    Returns
    -------
    SquareFeatures
        ``found=False`` with a ``reason`` when no square-like dark region is
        fully inside the image (never raises for image content).

    Raises
    ------
    ValueError
        If the image has the wrong shape or the depth image another size.

    Examples
    --------
    >>> img = np.full((120, 160), 220, np.uint8); img[40:80, 60:100] = 20
    >>> f = extract_square(img)
    >>> f.found, np.round(f.centroid_uv, 2).tolist()
    (True, [79.5, 59.5])
    """
    import cv2
    img = np.asarray(bgr)
    if img.ndim == 3 and img.shape[2] == 3:
        gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    elif img.ndim == 2:
        gray = img
    else:
        raise ValueError(f"bgr: expected shape (H, W, 3) or (H, W), got {img.shape}")
    if gray.dtype != np.uint8:
        gray = np.clip(gray, 0, 255).astype(np.uint8)
    h, w = gray.shape
    if depth_m is not None and np.shape(depth_m) != (h, w):
        raise ValueError(f"depth_m: expected shape {(h, w)}, got {np.shape(depth_m)}")
    # detection at half resolution (4x fewer pixels), measurement at full resolution in a ROI
    small = cv2.resize(gray, (w // 2, h // 2), interpolation=cv2.INTER_AREA)
    thr, mask = cv2.threshold(small, 0, 255, cv2.THRESH_BINARY_INV | cv2.THRESH_OTSU)
    found = _largest_inner_component(mask, max(config.border_px // 2, 1), config.min_area_px / 4)
    if found is None:
        return SquareFeatures.lost("no dark region inside the image")
    xs, ys, ws, hs = found
    pad = 4
    x0, y0 = max(2 * xs - pad, 0), max(2 * ys - pad, 0)
    x1, y1 = min(2 * (xs + ws) + pad, w), min(2 * (ys + hs) + pad, h)
    roi8 = gray[y0:y1, x0:x1]
    m_roi = (roi8 <= thr).astype(np.uint8)
    nr, lab_r, st_r, _ = cv2.connectedComponentsWithStats(m_roi, connectivity=8)
    if nr < 2:
        return SquareFeatures.lost("no dark region inside the image")
    best = 1 + int(np.argmax(st_r[1:, 4]))
    labels = lab_r
    if (x0 + st_r[best, 0] < config.border_px or y0 + st_r[best, 1] < config.border_px
            or x0 + st_r[best, 0] + st_r[best, 2] > w - config.border_px
            or y0 + st_r[best, 1] + st_r[best, 3] > h - config.border_px):
        return SquareFeatures.lost("no dark region inside the image")
    region = labels == best
    region8 = region.view(np.uint8)
    dark = float(np.median(roi8[region]))
    # the region grown by 2 px (5x5 once); grown twice it bounds the ground ring
    near8 = cv2.dilate(region8, _K5)
    ring = cv2.dilate(near8, _K5).view(bool) & ~cv2.dilate(region8, _K3).view(bool)
    if not ring.any():
        return SquareFeatures.lost("no ground around the dark region")
    light = float(np.median(roi8[ring]))
    if light - dark < config.min_contrast:
        return SquareFeatures.lost(f"contrast {light - dark:.0f} below {config.min_contrast:.0f}")
    # grey-level weights: 1 inside, 0 on the ground, fractional on anti-aliased edges;
    # restricted to the region grown by 2 px so other dark things do not pull
    roi = roi8.astype(np.float64)
    wgt = np.clip((light - roi) / (light - dark), 0.0, 1.0) * near8
    m00 = wgt.sum()
    centroid = np.array([wgt.sum(axis=0) @ np.arange(x0, x1, dtype=np.float64),
                         wgt.sum(axis=1) @ np.arange(y0, y1, dtype=np.float64)]) / m00
    # corners: 4-gon of the contour, refined on the grey image
    cnts, _ = cv2.findContours(region8, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    cnt = max(cnts, key=cv2.contourArea)
    peri = cv2.arcLength(cnt, True)
    quad = None
    for eps in (0.02, 0.03, 0.045, 0.06):
        ap = cv2.approxPolyDP(cnt, eps * peri, True)
        if len(ap) == 4 and cv2.isContourConvex(ap):
            quad = ap.reshape(4, 2).astype(np.float32)
            break
    if quad is None:
        return SquareFeatures.lost("dark region is not a quadrilateral")
    pts = cnt.reshape(-1, 2).astype(np.float64)
    fit = _mean_distance_to_polygon(pts, quad.astype(np.float64))
    if fit > config.max_corner_fit_px:
        return SquareFeatures.lost(f"dark region deviates {fit:.1f} px from a quadrilateral")
    refined = _refine_corners(roi, quad.astype(np.float64), 0.5 * (light + dark))
    if refined is None:
        return SquareFeatures.lost("square edges not measurable")
    corners = order_corners(refined + [x0, y0])
    center = diagonal_intersection(corners)
    if depth_m is None:
        depth = np.full(5, np.nan)
    else:
        dm = np.asarray(depth_m)
        kw = dict(window_px=config.depth_window_px, min_samples=config.min_depth_samples)
        depth = depth_at_many(dm, np.vstack([centroid, corners]), **kw)
    return SquareFeatures(found=True, centroid_uv=centroid, center_uv=center, corners_uv=corners,
                          depth_m=depth, area_px=float(m00))


def _bilinear(img: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    h, w = img.shape
    u = np.clip(u, 0, w - 1.001)
    v = np.clip(v, 0, h - 1.001)
    u0, v0 = np.floor(u), np.floor(v)
    a, b = u - u0, v - v0
    i = v0.astype(np.intp) * w + u0.astype(np.intp)                 # flat index of the top-left neighbour
    flat = img.reshape(-1)
    top = (1 - a) * flat.take(i) + a * flat.take(i + 1)
    bottom = (1 - a) * flat.take(i + w) + a * flat.take(i + w + 1)
    return (1 - b) * top + b * bottom


def _refine_corners(gray: np.ndarray, quad: np.ndarray, level: float, *, search_px: float = 3.0):
    """Corners as intersections of lines fitted to sub-pixel edge points of the four sides.

    Edge points: along the normal of each side, where the bilinearly
    interpolated grey level crosses ``level`` (midway between ground and
    square); the 15 % of each side nearest to the corners are left out. The
    four sides are sampled in one pass; each line is the total-least-squares
    fit (principal axis) of its edge points.
    """
    c = quad.mean(axis=0)
    d = np.roll(quad, -1, axis=0) - quad                                       # side i: quad[i] -> quad[i+1]
    length = np.hypot(d[:, 0], d[:, 1])
    if np.any(length < 6):
        return None
    t_dir = d / length[:, None]
    n = np.stack([-t_dir[:, 1], t_dir[:, 0]], axis=1)
    mid = quad + 0.5 * d
    n *= np.where(np.sum(n * (mid - c), axis=1) < 0, -1.0, 1.0)[:, None]       # outward normals
    counts = np.maximum((length * 0.35).astype(int), 4)
    side = np.repeat(np.arange(4), counts)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    k = np.arange(side.size) - start[side]
    ts = 0.15 + 0.7 * k / (counts[side] - 1)                                   # linspace(0.15, 0.85, count)
    offs = np.linspace(-search_px, search_px, int(4 * search_px) + 1)
    base = quad[side] + ts[:, None] * d[side]                                  # (S, 2)
    pts = base[:, None, :] + offs[None, :, None] * n[side][:, None, :]         # (S, O, 2)
    prof = _bilinear(gray, pts[..., 0], pts[..., 1]) - level                    # dark inside: rises outward
    up = (prof[:, :-1] < 0) & (prof[:, 1:] >= 0)
    rows = np.nonzero(up.sum(axis=1) == 1)[0]
    j = np.argmax(up[rows], axis=1)
    p0, p1 = prof[rows, j], prof[rows, j + 1]
    off = offs[j] + (-p0 / (p1 - p0)) * (offs[1] - offs[0])
    edge = base[rows] + off[:, None] * n[side[rows]]
    sid = side[rows]
    cnt = np.bincount(sid, minlength=4)
    if np.any(cnt < 4):
        return None
    m = np.stack([np.bincount(sid, edge[:, 0], 4), np.bincount(sid, edge[:, 1], 4)], axis=1) / cnt[:, None]
    r = edge - m[sid]
    cov = np.empty((4, 2, 2))
    cov[:, 0, 0] = np.bincount(sid, r[:, 0] * r[:, 0], 4)
    cov[:, 0, 1] = cov[:, 1, 0] = np.bincount(sid, r[:, 0] * r[:, 1], 4)
    cov[:, 1, 1] = np.bincount(sid, r[:, 1] * r[:, 1], 4)
    normal = np.linalg.eigh(cov)[1][:, :, 0]                                   # smallest-eigenvalue axis
    lines = np.concatenate([normal, -np.sum(normal * m, axis=1, keepdims=True)], axis=1)   # (4, 3)
    prev = np.roll(lines, 1, axis=0)                                           # side i-1 meets side i at quad[i]
    p = _cross3(prev, lines)
    if np.any(np.abs(p[:, 2]) < 1e-12):
        return None
    return p[:, :2] / p[:, 2:]


def _mean_distance_to_polygon(pts: np.ndarray, poly: np.ndarray) -> float:
    """Mean distance of points (N, 2) to the closed polygon's edges (all edges at once)."""
    a = poly
    ab = np.roll(poly, -1, axis=0) - poly                                    # (E, 2)
    rel = pts[:, None, :] - a[None, :, :]                                    # (N, E, 2)
    t = np.clip((rel[..., 0] * ab[:, 0] + rel[..., 1] * ab[:, 1]) / np.maximum((ab * ab).sum(axis=1), 1e-12),
                0.0, 1.0)
    dx = rel[..., 0] - t * ab[:, 0]
    dy = rel[..., 1] - t * ab[:, 1]
    return float(np.sqrt(dx * dx + dy * dy).min(axis=1).mean())
