"""Circles fitted to rim points: the algebraic least-squares circle and a robust one (internal).

Used by the colour rim of :mod:`.segment` and the luma rim of
:mod:`.rim_edge`. Points are ``(n, 2)`` arrays of image coordinates
``(u, v)`` (u right, v down), in pixels.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["circle_lsq", "fit_rim_circle", "fit_rim_circle_multi"]

_TRIPLES: dict = {}


def _triples(n: int) -> np.ndarray:
    """Deterministic index triples into ``n`` rim points, each pair at least ``n / 8`` apart along the rim."""
    if n not in _TRIPLES:
        rng = np.random.default_rng(n)
        cand = np.sort(rng.integers(0, n, size=(256, 3)), axis=1)
        gaps = np.diff(np.c_[cand, cand[:, :1] + n], axis=1)
        _TRIPLES[n] = np.ascontiguousarray(cand[(gaps >= max(n // 8, 1)).all(axis=1)][:48])
    return _TRIPLES[n]


def circle_lsq(pts: np.ndarray):
    """Algebraic (Kasa) least-squares circle ``(cu, cv, r)`` through ``pts`` (n x 2, n >= 3).

    Closed form from the centred second and third moments (no general solver:
    this runs per detection).

    Examples
    --------
    >>> t = np.linspace(0, np.pi, 7)
    >>> [round(x, 6) for x in circle_lsq(np.c_[3 + 2 * np.cos(t), -1 + 2 * np.sin(t)])]
    [3.0, -1.0, 2.0]
    """
    n = len(pts)
    m = pts.sum(axis=0) / n
    q = pts - m
    s2 = q.T @ q                                     # [[suu, suv], [suv, svv]]
    r12 = 0.5 * ((q * q).sum(axis=1) @ q)            # [r1, r2]
    suu, suv, svv = float(s2[0, 0]), float(s2[0, 1]), float(s2[1, 1])
    r1, r2 = float(r12[0]), float(r12[1])
    mu, mv = float(m[0]), float(m[1])
    det = suu * svv - suv * suv
    if not det > 1e-12:
        return mu, mv, float("nan")
    uc, vc = (r1 * svv - r2 * suv) / det, (r2 * suu - r1 * suv) / det
    return uc + mu, vc + mv, math.sqrt(uc * uc + vc * vc + (suu + svv) / n)


def fit_rim_circle(pts: np.ndarray, tol: float):
    """Robust circle through the rim points ``pts`` (n x 2): ``(cu, cv, r, inliers)``.

    Candidate circles through triples of points spread along the rim are
    scored by the points within ``tol`` of them, minus twice those clearly
    outside (an occluder or a rejected highlight only removes parts of the
    silhouette, so rim points may lie inside the true circle, hardly
    outside); the best is refined by least squares on its inliers (twice).
    When the least-squares circle through all points explains every one of
    them, it is taken directly.
    """
    cu, cv_, r = circle_lsq(pts)                   # fast path: a fully visible rim
    if math.isfinite(r):
        inl = np.abs(np.hypot(pts[:, 0] - cu, pts[:, 1] - cv_) - r) < tol
        if inl.all():
            return cu, cv_, r, inl
        if np.count_nonzero(inl) >= 0.9 * len(pts):  # a few stray points: refit without them
            cu, cv_, r = circle_lsq(pts[inl])
            res = np.hypot(pts[:, 0] - cu, pts[:, 1] - cv_) - r
            inl2 = np.abs(res) < tol
            if math.isfinite(r) and (inl2 == inl).all() and not (res > 2.0 * tol).any():
                return cu, cv_, r, inl
    tri = _triples(len(pts))
    if len(tri) == 0:
        return None
    q = pts[tri]                                     # (k, 3, 2)
    a, b = q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]
    det = 2.0 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    det[np.abs(det) < 1e-9] = np.nan                 # collinear: no circle
    na, nb = (a * a).sum(axis=1), (b * b).sum(axis=1)
    du = (b[:, 1] * na - a[:, 1] * nb) / det
    dv = (a[:, 0] * nb - b[:, 0] * na) / det
    cu, cv_, r = du + q[:, 0, 0], dv + q[:, 0, 1], np.hypot(du, dv)
    d2 = np.square(pts[:, 0] - cu[:, None])        # squared distances (k, n): no square root per point
    d2 += np.square(pts[:, 1] - cv_[:, None])
    lo = r - tol
    lo2 = np.where(lo > 0.0, lo * lo, -1.0)[:, None]
    near = (d2 > lo2) & (d2 < np.square(r + tol)[:, None])              # |distance - r| < tol
    score = near.sum(axis=1) - 2 * (d2 > np.square(r + 2.0 * tol)[:, None]).sum(axis=1)
    inl = near[int(np.argmax(score))]
    for _ in range(2):
        if np.count_nonzero(inl) < 5:
            return None
        cu, cv_, r = circle_lsq(pts[inl])
        if not math.isfinite(r):
            return None
        inl = np.abs(np.hypot(pts[:, 0] - cu, pts[:, 1] - cv_) - r) < tol
    return cu, cv_, r, inl


_MANY: dict = {}


def _many_triples(n: int, m: int) -> np.ndarray:
    """Up to ``m`` deterministic index triples into ``n`` points, each pair at least ``n / 8`` apart."""
    if (n, m) not in _MANY:
        rng = np.random.default_rng(n)
        cand = np.sort(rng.integers(0, n, size=(4 * m, 3)), axis=1)
        gaps = np.diff(np.c_[cand, cand[:, :1] + n], axis=1)
        _MANY[(n, m)] = np.ascontiguousarray(cand[(gaps >= max(n // 8, 1)).all(axis=1)][:m])
    return _MANY[(n, m)]


def fit_rim_circle_multi(pts: np.ndarray, tol: float, *, n_hyp: int = 200, top: int = 3):
    """Robust circle through edge points ``pts`` (n x 2, ordered along the rim): ``(cu, cv, r, inliers)``.

    As :func:`fit_rim_circle` (score: points within ``tol`` minus twice those
    more than ``2 tol`` outside), with ``n_hyp`` candidate triples and the
    ``top`` best each refined by least squares on its inliers three times and
    re-scored; the best refined circle wins. For the sparser, noisier points
    of an edge search along rays, where a fixed 48 triples often miss the rim.
    None when no circle has five inliers.
    """
    tri = _many_triples(len(pts), n_hyp)
    if len(tri) == 0:
        return None
    q = pts[tri]
    a, b = q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]
    det = 2.0 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    det[np.abs(det) < 1e-9] = np.nan
    na, nb = (a * a).sum(axis=1), (b * b).sum(axis=1)
    du = (b[:, 1] * na - a[:, 1] * nb) / det
    dv = (a[:, 0] * nb - b[:, 0] * na) / det
    rr = np.hypot(du, dv)
    res = np.hypot(pts[:, 0] - (du + q[:, 0, 0])[:, None], pts[:, 1] - (dv + q[:, 0, 1])[:, None]) - rr[:, None]
    score = np.where(np.isfinite(rr), (np.abs(res) < tol).sum(axis=1) - 2 * (res > 2.0 * tol).sum(axis=1), -len(pts))
    best = None
    for i in np.argsort(-score, kind="stable")[:top]:
        inl = np.abs(res[i]) < tol
        fit = None
        for _ in range(3):
            if np.count_nonzero(inl) < 5:
                fit = None
                break
            cu, cv_, r = circle_lsq(pts[inl])
            if not math.isfinite(r):
                fit = None
                break
            d = np.hypot(pts[:, 0] - cu, pts[:, 1] - cv_) - r
            inl = np.abs(d) < tol
            fit = (int(np.count_nonzero(inl)) - 2 * int(np.count_nonzero(d > 2.0 * tol)), cu, cv_, r, inl)
        if fit is not None and (best is None or fit[0] > best[0]):
            best = fit
    return None if best is None else best[1:]
