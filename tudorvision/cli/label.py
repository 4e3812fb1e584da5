"""``tudorvision label balls``: propose, review and write ball labels of real video frames.

The proposal is deliberately independent of the tracker under test
(:mod:`tudorvision.stereo.segment` / :mod:`tudorvision.stereo.colormodel`
are not used): pixels whose CIE Lab chroma (a*, b*) lies closer to a picked
ball colour than half way to neutral grey form a mask; the boundary of its
largest blob (holes filled) gives edge points; a RANSAC circle on those points,
refined by a least-squares fit to its inliers, is the candidate. A finger over
the ball or a washed-out highlight bends the blob's boundary, but not the
circle through the remaining rim.

A contact sheet of zoomed crops (nearest-neighbour upscaling, a grid every
5 px labelled every 10 px in full-frame coordinates, the candidate circle and
centre drawn one pixel thin) lets a reviewer check every frame, and
``--set FRAME=U,V,R`` / ``--unclean FRAME=NOTE`` / ``--none FRAME`` record
the corrections. Labels are written with :func:`tudorvision.io.labels.write_ball_labels`.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .._checks import TudorVisionError
from ..io.labels import BallLabel, read_ball_labels, write_ball_labels

__all__ = ["register", "ball_mask", "ransac_circle", "propose_ball_circle", "label_tile", "contact_sheet",
           "parse_frames"]


# ----------------------------------------------------------------------------- proposal
def _lab_ab(frame_bgr: np.ndarray) -> np.ndarray:
    import cv2
    lab = cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2LAB)
    return lab[..., 1:].astype(np.float32) - 128.0


def ball_mask(frame_bgr, ref_ab, *, blur: int = 5, min_chroma: float = 6.0, max_angle_deg: float = 40.0,
              min_fraction: float = 0.3) -> np.ndarray:
    """Pixels whose chroma points the ball's way from the background's.

    Chroma is CIE Lab (a*, b*). The background chroma is the frame's median
    (the wall fills most of the frame). A pixel is ball when its chroma offset
    from the background lies within ``max_angle_deg`` of the ball's offset and
    is at least ``min_fraction`` of its length: pale (highlighted) ball pixels
    pass, skin (another hue) and the wall do not.

    Parameters
    ----------
    frame_bgr : ndarray, shape (H, W, 3), uint8
        Frame, OpenCV BGR order.
    ref_ab : array_like, shape (2,)
        Ball chroma (CIE a*, b* as OpenCV stores them, minus 128).
    blur : int
        Odd Gaussian kernel size applied before the colour conversion (0: none).
    min_chroma : float
        Smallest offset of ``ref_ab`` from the background accepted.
    max_angle_deg, min_fraction : float
        See above.

    Returns
    -------
    ndarray of bool, shape (H, W)

    Raises
    ------
    TudorVisionError
        ``ref_ab`` too close to the background chroma to separate the ball.

    Examples
    --------
    >>> import cv2
    >>> img = np.full((40, 40, 3), 200, np.uint8)
    >>> _ = cv2.circle(img, (20, 20), 8, (80, 170, 90), -1)
    >>> m = ball_mask(img, _lab_ab(img)[20, 20], blur=0)
    >>> bool(m[20, 20]), bool(m[2, 2])
    (True, False)
    """
    along, across, chroma = _chroma_along(frame_bgr, ref_ab, blur, min_chroma)
    return (along >= min_fraction * chroma) & (across <= along * math.tan(math.radians(max_angle_deg)))


def _chroma_along(frame_bgr, ref_ab, blur: int, min_chroma: float):
    """Chroma offset from the wall, along and across the ball's direction; and the ball's offset length."""
    import cv2
    img = cv2.GaussianBlur(frame_bgr, (blur, blur), 0) if blur else frame_bgr
    ab = _lab_ab(img)
    bg = np.median(ab[::4, ::4].reshape(-1, 2), axis=0)
    ref = np.asarray(ref_ab, dtype=np.float32).reshape(2) - bg
    chroma = float(np.hypot(*ref))
    if chroma < min_chroma:
        raise TudorVisionError(f"ref_ab: the picked colour is nearly the wall's (chroma offset {chroma:.1f} "
                               f"< {min_chroma:g}); pick a pixel on the ball")
    d = ab - bg
    along = (d @ ref) / chroma
    across = np.abs(d[..., 0] * ref[1] - d[..., 1] * ref[0]) / chroma
    return along.astype(np.float32), across.astype(np.float32), chroma


def _refine_rim(along: np.ndarray, chroma: float, circle, pts: np.ndarray, *, reach: float = 5.0,
                min_contrast: float = 0.3):
    """Circle through the half-contrast crossings of ``along`` on rays through the rim points ``pts``.

    On each ray from the circle's centre through a rim point, the chroma
    profile is sampled from ``r - reach`` to ``r + reach`` (0.25 px steps);
    the crossing of the level half way between its inner and outer ends,
    nearest the circle, is the rim there (for a blurred step edge that is the
    edge itself). Rays with an inner-outer contrast below ``min_contrast *
    chroma`` are dropped; the circle is fitted by least squares with two
    passes trimming points more than 1 px off. None when fewer than 12 rays.
    """
    import cv2
    u, v, r = circle
    ang = np.arctan2(pts[:, 1] - v, pts[:, 0] - u)
    s = np.arange(r - reach, r + reach + 1e-9, 0.25, dtype=np.float64)
    mx = (u + np.cos(ang)[:, None] * s[None, :]).astype(np.float32)
    my = (v + np.sin(ang)[:, None] * s[None, :]).astype(np.float32)
    prof = cv2.remap(along, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).astype(np.float64)
    k2 = max(int(round(2.0 / 0.25)), 1)
    inner, outer = prof[:, :k2].mean(axis=1), prof[:, -k2:].mean(axis=1)
    ok = inner - outer >= min_contrast * chroma
    rim = []
    for i in np.flatnonzero(ok):
        f = prof[i] - 0.5 * (inner[i] + outer[i])
        cross = np.flatnonzero((f[:-1] >= 0) & (f[1:] < 0))
        if cross.size == 0:
            continue
        k = cross[np.argmin(np.abs(s[cross] - r))]
        sk = s[k] + 0.25 * f[k] / (f[k] - f[k + 1])
        rim.append((u + math.cos(ang[i]) * sk, v + math.sin(ang[i]) * sk))
    if len(rim) < 12:
        return None
    rim = np.array(rim)
    c = _lsq_circle(rim)
    for _ in range(2):
        keep = np.abs(np.hypot(rim[:, 0] - c[0], rim[:, 1] - c[1]) - c[2]) < 1.0
        if keep.sum() < 12:
            return None
        c = _lsq_circle(rim[keep])
    return c


def _circle_through(p: np.ndarray):
    """Circle through three points (rows of ``p``), or None when collinear."""
    (x1, y1), (x2, y2), (x3, y3) = p
    d = 2.0 * (x1 * (y2 - y3) + x2 * (y3 - y1) + x3 * (y1 - y2))
    if abs(d) < 1e-9:
        return None
    s1, s2, s3 = x1 * x1 + y1 * y1, x2 * x2 + y2 * y2, x3 * x3 + y3 * y3
    cx = (s1 * (y2 - y3) + s2 * (y3 - y1) + s3 * (y1 - y2)) / d
    cy = (s1 * (x3 - x2) + s2 * (x1 - x3) + s3 * (x2 - x1)) / d
    return cx, cy, math.hypot(x1 - cx, y1 - cy)


def _lsq_circle(p: np.ndarray):
    """Algebraic (Kasa) least-squares circle of points ``p`` (N, 2)."""
    a = np.column_stack([2 * p[:, 0], 2 * p[:, 1], np.ones(len(p))])
    b = (p ** 2).sum(axis=1)
    (cx, cy, c), *_ = np.linalg.lstsq(a, b, rcond=None)
    return float(cx), float(cy), float(math.sqrt(max(c + cx * cx + cy * cy, 0.0)))


def ransac_circle(points, *, tol: float = 1.2, iterations: int = 400, r_range=(2.0, 1e9), seed: int = 0):
    """Robust circle through 2D edge points.

    Parameters
    ----------
    points : array_like, shape (N, 2)
        Edge points (u, v) in pixels, N >= 3.
    tol : float
        Inlier distance from the circle, pixels.
    iterations : int
        Random three-point samples.
    r_range : tuple of float
        Accepted radii (min, max), pixels.
    seed : int
        Seed of the ``np.random.default_rng`` sampler.

    Returns
    -------
    (u, v, r, inlier_fraction) or None
        Circle refined by least squares on its inliers; None when no sample
        gives a circle within ``r_range``.

    Examples
    --------
    >>> t = np.linspace(0, 1.5 * np.pi, 60)
    >>> pts = np.column_stack([30 + 10 * np.cos(t), 20 + 10 * np.sin(t)])
    >>> pts = np.vstack([pts, [[30, 20], [31, 21], [29, 22]]])    # outliers
    >>> [round(x, 3) for x in ransac_circle(pts)[:3]]
    [30.0, 20.0, 10.0]
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(p) < 3:
        return None
    rng = np.random.default_rng(seed)
    best, best_n = None, 0
    for _ in range(iterations):
        c = _circle_through(p[rng.choice(len(p), 3, replace=False)])
        if c is None or not (r_range[0] <= c[2] <= r_range[1]):
            continue
        n = int((np.abs(np.hypot(p[:, 0] - c[0], p[:, 1] - c[1]) - c[2]) < tol).sum())
        if n > best_n:
            best, best_n = c, n
    if best is None:
        return None
    for _ in range(3):   # refine on the inliers of the current circle
        inl = np.abs(np.hypot(p[:, 0] - best[0], p[:, 1] - best[1]) - best[2]) < tol
        if inl.sum() < 3:
            break
        best = _lsq_circle(p[inl])
    inl = np.abs(np.hypot(p[:, 0] - best[0], p[:, 1] - best[1]) - best[2]) < tol
    return best[0], best[1], best[2], float(inl.mean())


def propose_ball_circle(frame_bgr, ref_ab, *, min_area: int = 30, near_uv=None, seed: int = 0,
                        refine: bool = True):
    """Candidate ball circle of one frame (independent of :mod:`tudorvision.stereo`).

    Parameters
    ----------
    frame_bgr : ndarray, shape (H, W, 3), uint8
        Frame, OpenCV BGR order.
    ref_ab : array_like, shape (2,)
        Ball chroma, see :func:`ball_mask`.
    min_area : int
        Smallest blob (pixels) taken for a ball.
    near_uv : array_like, shape (2,), optional
        Take the blob nearest this pixel instead of the largest.
    seed : int
        RANSAC seed.
    refine : bool
        Move the RANSAC circle's rim points to the half-contrast crossing of
        the chroma profile across the rim and refit (sub-pixel edge);
        otherwise the circle through the blob's boundary pixels plus 0.5 px.

    Returns
    -------
    (u, v, r, inlier_fraction) or None
        Centre (u right, v down) and radius in pixels, and the fraction of
        the blob's boundary points on the circle; None when no blob.

    Examples
    --------
    >>> import cv2
    >>> img = np.full((80, 80, 3), 200, np.uint8)
    >>> _ = cv2.circle(img, (40, 36), 15, (80, 170, 90), -1)
    >>> _ = cv2.rectangle(img, (20, 40), (60, 60), (150, 170, 220), -1)   # a "finger"
    >>> u, v, r, f = propose_ball_circle(img, _lab_ab(img)[30, 40])
    >>> abs(u - 40) < 0.7, abs(v - 36) < 0.7, abs(r - 15) < 1.0
    (True, True, True)
    """
    import cv2
    along, across, chroma = _chroma_along(frame_bgr, ref_ab, 5, 6.0)
    mask = ((along >= 0.3 * chroma) & (across <= along * math.tan(math.radians(40.0)))).astype(np.uint8)
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    n, lab, stats, cents = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n <= 1:
        return None
    areas = stats[1:, cv2.CC_STAT_AREA]
    ok = np.flatnonzero(areas >= min_area) + 1
    if ok.size == 0:
        return None
    if near_uv is not None:
        k = ok[np.argmin(np.hypot(*(cents[ok] - np.asarray(near_uv, float)).T))]
    else:
        k = ok[np.argmax(stats[ok, cv2.CC_STAT_AREA])]
    blob = (lab == k).astype(np.uint8)
    contours, _ = cv2.findContours(blob, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    blob = cv2.drawContours(np.zeros_like(blob), contours, -1, 1, -1)   # holes (highlights) filled
    contours, _ = cv2.findContours(blob, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    pts = np.vstack([c.reshape(-1, 2) for c in contours]).astype(np.float64)
    h, w = blob.shape
    # points on the image border are not the ball's rim
    pts = pts[(pts[:, 0] > 0) & (pts[:, 1] > 0) & (pts[:, 0] < w - 1) & (pts[:, 1] < h - 1)]
    r_area = math.sqrt(float(blob.sum()) / math.pi)
    # occlusion only hides ball: the circle is at least as large as the blob's area-equivalent circle
    res = ransac_circle(pts, tol=1.5, r_range=(0.97 * r_area, 1.6 * r_area), seed=seed)
    if res is None:
        return None
    u, v, r, frac = res
    inl = np.abs(np.hypot(pts[:, 0] - u, pts[:, 1] - v) - r) < 1.5
    fine = _refine_rim(along, chroma, (u, v, r), pts[inl]) if refine else None
    if fine is None:
        # boundary pixels are the outermost ball pixels: the rim lies about half a pixel beyond them
        return u, v, r + 0.5, frac
    return fine[0], fine[1], fine[2], frac


# ----------------------------------------------------------------------------- sheets
def label_tile(frame_bgr, circle, *, text: str = "", scale: int | None = None, half: int | None = None,
               tile_px: int = 400, draw: bool = True) -> np.ndarray:
    """A zoomed crop around a circle, with a coordinate grid and the circle drawn thin.

    Parameters
    ----------
    frame_bgr : ndarray, shape (H, W, 3), uint8
        Frame.
    circle : tuple (u, v, r) or None
        Circle in full-frame pixels (drawn red, centre cross red); None: the
        whole frame scaled to ``tile_px`` (to check that no ball is visible).
    text : str
        Caption written at the top left.
    scale : int, optional
        Nearest-neighbour upscaling factor; default: the largest that keeps
        the tile within ``tile_px`` (at least 2).
    half : int, optional
        Crop half-size in pixels (default ``1.6 r + 6``).
    tile_px : int
        Tile size aimed at when ``scale`` is not given.
    draw : bool
        Draw the circle; False gives a blind crop (the grid only) for an
        independent reading of the rim.

    Returns
    -------
    ndarray, shape (S, S, 3), uint8
        ``S = (2 half + 1) scale`` (the scaled frame's shape when ``circle``
        is None). Grid lines every 5 px (brighter every
        10 px, with the full-frame coordinate written at the top and left).

    Examples
    --------
    >>> label_tile(np.zeros((50, 60, 3), np.uint8), (30, 25, 5), half=10, scale=4).shape
    (84, 84, 3)
    """
    import cv2
    h_img, w_img = frame_bgr.shape[:2]
    if circle is None:   # nothing to zoom on: the whole frame, to check that no ball is visible
        k = tile_px / max(w_img, h_img)
        tile = cv2.resize(frame_bgr, (max(int(w_img * k), 1), max(int(h_img * k), 1)), interpolation=cv2.INTER_AREA)
        if text:
            cv2.putText(tile, text, (3, 14), cv2.FONT_HERSHEY_PLAIN, 1.0, (0, 0, 0), 3)
            cv2.putText(tile, text, (3, 14), cv2.FONT_HERSHEY_PLAIN, 1.0, (255, 255, 255), 1)
        return tile
    u, v, r = circle
    half = int(half if half is not None else math.ceil(1.6 * r + 6))
    u0, v0 = int(round(u)) - half, int(round(v)) - half
    size = 2 * half + 1
    scale = int(scale) if scale else max(2, tile_px // size)
    crop = np.zeros((size, size, 3), np.uint8)
    xs0, ys0 = max(u0, 0), max(v0, 0)
    xs1, ys1 = min(u0 + size, w_img), min(v0 + size, h_img)
    if xs1 > xs0 and ys1 > ys0:
        crop[ys0 - v0:ys1 - v0, xs0 - u0:xs1 - u0] = frame_bgr[ys0:ys1, xs0:xs1]
    tile = cv2.resize(crop, (size * scale, size * scale), interpolation=cv2.INTER_NEAREST)
    overlay = tile.copy()
    for k in range(size):   # pixel k spans [k*scale, (k+1)*scale); its centre is at (k + 0.5) * scale
        for axis, coord0 in ((0, u0), (1, v0)):
            c = coord0 + k
            if c % 5:
                continue
            pos = int((k + 0.5) * scale)
            colour = (255, 200, 0) if c % 10 == 0 else (160, 120, 0)
            if axis == 0:
                cv2.line(overlay, (pos, 0), (pos, tile.shape[0] - 1), colour, 1)
            else:
                cv2.line(overlay, (0, pos), (tile.shape[1] - 1, pos), colour, 1)
    tile = cv2.addWeighted(overlay, 0.45, tile, 0.55, 0)
    for k in range(size):
        pos = int((k + 0.5) * scale)
        if (u0 + k) % 10 == 0:
            cv2.putText(tile, str(u0 + k), (pos + 2, tile.shape[0] - 4), cv2.FONT_HERSHEY_PLAIN, 0.8,
                        (255, 255, 0), 1)
        if (v0 + k) % 10 == 0:
            cv2.putText(tile, str(v0 + k), (2, pos - 2), cv2.FONT_HERSHEY_PLAIN, 0.8, (255, 255, 0), 1)
    if draw:
        sh = 4   # fixed-point bits for sub-pixel drawing
        cu, cv_ = (u - u0 + 0.5) * scale, (v - v0 + 0.5) * scale
        ctr = (int(round(cu * 2 ** sh)), int(round(cv_ * 2 ** sh)))
        cv2.circle(tile, ctr, int(round(r * scale * 2 ** sh)), (0, 0, 255), 1, cv2.LINE_AA, sh)
        cv2.drawMarker(tile, (int(round(cu)), int(round(cv_))), (0, 0, 255), cv2.MARKER_CROSS, 2 * scale, 1)
    if text:
        cv2.putText(tile, text, (3, 14), cv2.FONT_HERSHEY_PLAIN, 1.0, (0, 0, 0), 3)
        cv2.putText(tile, text, (3, 14), cv2.FONT_HERSHEY_PLAIN, 1.0, (255, 255, 255), 1)
    return tile


def contact_sheet(tiles, *, columns: int = 4) -> np.ndarray:
    """Tiles (any sizes) in a grid, each padded to the largest, on black.

    Parameters
    ----------
    tiles : list of ndarray, shape (h, w, 3), uint8
    columns : int

    Returns
    -------
    ndarray, uint8

    Examples
    --------
    >>> contact_sheet([np.zeros((4, 5, 3), np.uint8)] * 3, columns=2).shape
    (12, 14, 3)
    """
    if not tiles:
        raise TudorVisionError("tiles: nothing to put on a sheet")
    th = max(t.shape[0] for t in tiles) + 2
    tw = max(t.shape[1] for t in tiles) + 2
    rows = math.ceil(len(tiles) / columns)
    sheet = np.zeros((rows * th, min(columns, len(tiles)) * tw, 3), np.uint8)
    for i, t in enumerate(tiles):
        y, x = (i // columns) * th, (i % columns) * tw
        sheet[y:y + t.shape[0], x:x + t.shape[1]] = t
    return sheet


# ----------------------------------------------------------------------------- command line
def parse_frames(text: str, n_frames: int) -> list[int]:
    """Frame list from ``"A:B:STEP"`` (B exclusive, may be empty) and/or comma-separated indices.

    Parameters
    ----------
    text : str
    n_frames : int
        Frames in the video; indices must lie in ``[0, n_frames)``.

    Returns
    -------
    list of int
        Sorted, without duplicates.

    Raises
    ------
    TudorVisionError
        Malformed text or an index outside the video.

    Examples
    --------
    >>> parse_frames("10:40:10,5", 100)
    [5, 10, 20, 30]
    """
    out = set()
    for part in text.split(","):
        part = part.strip()
        try:
            if ":" in part:
                a, b, *s = part.split(":")
                step = int(s[0]) if s else 1
                out.update(range(int(a), int(b) if b else n_frames, step))
            elif part:
                out.add(int(part))
        except (ValueError, IndexError):
            raise TudorVisionError(f"--frames: expected A:B:STEP or comma-separated indices, got {part!r}") from None
    bad = [i for i in out if not 0 <= i < n_frames]
    if bad:
        raise TudorVisionError(f"--frames: frame {min(bad)} outside the video's {n_frames} frames")
    return sorted(out)


def _kv(items, what: str, nvals: int | None):
    out = {}
    for item in items:
        key, _, val = item.partition("=")
        try:
            frame = int(key)
            vals = [float(x) for x in val.split(",")] if nvals else val
        except ValueError:
            raise TudorVisionError(f"{what}: expected FRAME=... got {item!r}") from None
        if nvals and len(vals) != nvals:
            raise TudorVisionError(f"{what}: expected FRAME={','.join(['X'] * nvals)}, got {item!r}")
        out[frame] = vals
    return out


def _run_balls(args) -> int:
    import cv2
    from ..io import open_sequence
    video = Path(args.video)
    seq = open_sequence(video)
    frames = parse_frames(args.frames, len(seq))
    pick = _kv([args.pick], "--pick", 2)
    (pf, (pu, pv)), = pick.items()
    if not 0 <= pf < len(seq):
        raise TudorVisionError(f"--pick: frame {pf} outside the video's {len(seq)} frames")
    img = np.asarray(seq[pf].image)
    h, w = img.shape[:2]
    if not (0 <= pu < w and 0 <= pv < h):
        raise TudorVisionError(f"--pick: ({pu:g}, {pv:g}) outside the {w}x{h} frame")
    ref_ab = _lab_ab(cv2.GaussianBlur(img, (5, 5), 0))[int(pv) - 2:int(pv) + 3, int(pu) - 2:int(pu) + 3]
    ref_ab = np.median(ref_ab.reshape(-1, 2), axis=0)
    sets = _kv(args.set, "--set", 3)
    unclean = _kv(args.unclean, "--unclean", None)
    none = {int(x) for x in args.none}
    notes = _kv(args.note, "--note", None)
    extra = (set(sets) | set(unclean) | none | set(notes)) - set(frames)
    if extra:
        raise TudorVisionError(f"--set/--unclean/--none/--note: frame {min(extra)} is not in --frames")
    labels, tiles = [], []
    for i in frames:
        img = np.asarray(seq[i].image)
        note = notes.get(i, "")
        if i in none:
            circle, method = None, "none"
        elif i in sets:
            circle, method = tuple(sets[i]), "hand-corrected"
        else:
            res = propose_ball_circle(img, ref_ab, min_area=args.min_area)
            circle = None if res is None else res[:3]
            method = "none" if circle is None else "auto-checked"
        clean = circle is not None and i not in unclean
        if i in unclean:
            note = "; ".join(x for x in (unclean[i], note) if x)
        u, v, r = circle if circle is not None else (math.nan,) * 3
        labels.append(BallLabel(video=video.name, frame=i, u_px=u, v_px=v, r_px=r, clean=clean, method=method,
                                note=note))
        if args.sheet:
            tag = {"auto-checked": "A", "hand-corrected": "H", "none": "-"}[method] + ("" if clean else " NC")
            cap = f"{i} {tag}" + ("" if circle is None else f" {u:.1f},{v:.1f} r{r:.1f}")
            tiles.append(label_tile(img, circle, text=cap, scale=args.scale))
    if args.sheet:
        from ..io.atomic import write_bytes_atomic
        per = args.per_sheet
        for k in range(0, len(tiles), per):
            ok, png = cv2.imencode(".png", contact_sheet(tiles[k:k + per], columns=args.columns))
            name = Path(args.sheet)
            out = name.with_name(f"{name.stem}_{k // per + 1:02d}{name.suffix or '.png'}")
            write_bytes_atomic(out, png.tobytes())
            print(f"sheet {out}")
    out = Path(args.out)
    keep = [lab for lab in read_ball_labels(out) if not (lab.video == video.name and lab.frame in set(frames))] \
        if out.exists() else []
    write_ball_labels(out, keep + labels, comment=args.comment)
    n_clean = sum(lab.clean for lab in labels)
    n_hand = sum(lab.method == "hand-corrected" for lab in labels)
    print(f"{video.name}: {len(labels)} frames labelled ({n_clean} clean, {n_hand} hand-corrected) -> {out}")
    return 0


def register(subparsers) -> None:
    """Add ``label balls`` to the top-level command."""
    p = subparsers.add_parser("label", help="label real frames by hand (with proposals) for accuracy tests",
                              description="Make reviewed ground-truth labels of real recordings.")
    sub = p.add_subparsers(dest="label_command", metavar="KIND")
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])
    b = sub.add_parser(
        "balls", help="ball centre and radius per frame of a video -> label CSV (+ contact sheets to review)",
        description="Propose a circle per frame (Lab chroma mask, RANSAC circle on its boundary; independent "
                    "of the stereo segmentation), write zoomed contact sheets to review, and write the labels; "
                    "rows of the same video and frames already in --out are replaced, others kept.")
    b.add_argument("video", help="video file")
    b.add_argument("--frames", required=True, help="frames to label: A:B:STEP and/or comma-separated indices")
    b.add_argument("--pick", required=True, metavar="FRAME=U,V", help="a pixel on the ball in one frame (its colour)")
    b.add_argument("--out", required=True, help="label CSV to write or update")
    b.add_argument("--sheet", help="contact sheet PNG (written as NAME_01.png, NAME_02.png, ...)")
    b.add_argument("--per-sheet", type=int, default=12, help="tiles per sheet (default 12)")
    b.add_argument("--columns", type=int, default=4, help="tiles per sheet row (default 4)")
    b.add_argument("--scale", type=int, default=None, help="zoom of the crops (default: fit ~400 px tiles, >= 2)")
    b.add_argument("--min-area", type=int, default=30, help="smallest ball blob in pixels (default 30)")
    b.add_argument("--set", action="append", default=[], metavar="FRAME=U,V,R",
                   help="hand-corrected circle of a frame (method hand-corrected)")
    b.add_argument("--unclean", action="append", default=[], metavar="FRAME=NOTE",
                   help="frame is not clean (occluded, partly out of frame, blurred); NOTE says why")
    b.add_argument("--none", action="append", default=[], metavar="FRAME", help="no ball visible in this frame")
    b.add_argument("--note", action="append", default=[], metavar="FRAME=NOTE", help="free note for a frame")
    b.add_argument("--comment", help="comment written at the top of the CSV")
    b.set_defaults(func=_run_balls)
