"""Visual servoing control laws for the translational camera DOF (section 9.1).

Signs follow :mod:`tudorvision.servo.interaction`: the hybrid law uses the
seed error ``e = s* - s`` with ``L_c = diag(f/z, f/z, 1)``::

    v_c = -lambda L_c^-1 e = lambda [z (u - u*) / f, z (v - v*) / f, z - z*]

and classical IBVS uses the standard stacked point matrix ``L`` (2N x 3)
with ``e = s - s*``::

    v_c = -lambda L^+ (s - s*),   L = L(s, Z) | L(s*, Z*) | (L(s, Z) + L(s*, Z*)) / 2

(the seed's ``-K J_c^+ (s* - s)`` is the same command). The gain may adapt to
the error as in ViSP's ``vpAdaptiveGain``::

    lambda(x) = (lambda_0 - lambda_inf) exp(-lambda'_0 x / (lambda_0 - lambda_inf)) + lambda_inf

with ``x`` the size of the estimated translation to the goal,
``||L^-1 e||`` in metres. A velocity limit scales the whole vector (the
direction is kept). Lost features or invalid depth give a zero command with
``ok=False``: never the previous one.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .features import SquareFeatures
from .interaction import stacked_interaction

__all__ = ["AdaptiveGain", "LawConfig", "ServoCommand", "adaptive_gain", "limit_velocity", "hybrid_law",
           "ibvs_law", "GoalFeatures", "servo_command", "LAWS", "INTERACTION_MODES"]

LAWS = ("hybrid", "ibvs")
INTERACTION_MODES = ("current", "desired", "mean")


def adaptive_gain(x, lambda_0: float, lambda_inf: float, slope_0: float):
    """Adaptive gain ``lambda(x)``: ``lambda_0`` at 0, ``lambda_inf`` far away, slope ``-slope_0`` at 0.

    Parameters
    ----------
    x : float or ndarray
        Error size (>= 0).
    lambda_0, lambda_inf : float
        Gains at zero and infinite error, 1/s.
    slope_0 : float
        ``-dlambda/dx`` at ``x = 0``.

    Examples
    --------
    >>> round(float(adaptive_gain(0.0, 4.0, 1.0, 30.0)), 6)
    4.0
    >>> round(float(adaptive_gain(1e3, 4.0, 1.0, 30.0)), 6)
    1.0
    """
    d = lambda_0 - lambda_inf
    if d == 0:
        return np.full(np.shape(x), float(lambda_0)) if np.ndim(x) else float(lambda_0)
    return d * np.exp(-slope_0 * np.asarray(x, dtype=np.float64) / d) + lambda_inf


@dataclass(frozen=True, kw_only=True)
class AdaptiveGain:
    """``lambda(x)`` parameters; equal ``lambda_0`` and ``lambda_inf`` give a constant gain.

    Parameters
    ----------
    lambda_0 : float
        Gain at zero distance (1/s), > 0.
    lambda_inf : float
        Gain far from the goal (1/s), > 0.
    slope_0 : float
        Slope of ``lambda(x)`` at ``x = 0`` (1/(s m)), >= 0.

    Raises
    ------
    ValueError
        If a gain is not positive or the slope negative.
    """

    lambda_0: float = 1.2
    lambda_inf: float = 0.6
    slope_0: float = 10.0

    def __post_init__(self):
        if not (self.lambda_0 > 0 and self.lambda_inf > 0 and self.slope_0 >= 0):
            raise ValueError(f"gain: expected lambda_0, lambda_inf > 0 and slope_0 >= 0, got {self}")

    def __call__(self, x: float) -> float:
        return float(adaptive_gain(x, self.lambda_0, self.lambda_inf, self.slope_0))


@dataclass(frozen=True, kw_only=True)
class LawConfig:
    """Options of :func:`servo_command`.

    Attributes
    ----------
    law : {"hybrid", "ibvs"}
        Hybrid centroid + depth law (9.1.5) or classical 4-point IBVS (9.1.2).
    interaction : {"current", "desired", "mean"}
        Which interaction matrix IBVS inverts.
    gain : AdaptiveGain
    v_max_m_s : float
        Largest commanded camera speed, m/s.
    feature : {"centroid", "center"}
        Hybrid law point: region centroid or diagonal intersection.
    """

    law: str = "hybrid"
    interaction: str = "current"
    gain: AdaptiveGain = AdaptiveGain()
    v_max_m_s: float = 0.12
    feature: str = "centroid"

    def __post_init__(self):
        if self.law not in LAWS:
            raise ValueError(f"law: expected one of {LAWS}, got {self.law!r}")
        if self.interaction not in INTERACTION_MODES:
            raise ValueError(f"interaction: expected one of {INTERACTION_MODES}, got {self.interaction!r}")
        if self.feature not in ("centroid", "center"):
            raise ValueError(f"feature: expected 'centroid' or 'center', got {self.feature!r}")
        if not self.v_max_m_s > 0:
            raise ValueError(f"v_max_m_s: expected > 0, got {self.v_max_m_s!r}")


@dataclass(frozen=True, kw_only=True, eq=False)
class ServoCommand:
    """One law output.

    Attributes
    ----------
    v_cam : ndarray, shape (3,)
        Camera translational velocity, m/s, camera frame (zero when not ok).
    ok : bool
    reason : str
    error : ndarray, shape (3,)
        Hybrid error ``s* - s`` ``[e_u px, e_v px, e_z m]`` (the centroid
        error for IBVS too), NaN when lost.
    error_m : float
        Estimated distance to the goal ``||L^-1 e||``, metres (NaN when lost).
    image_error_px : float
        RMS image error of the features used, pixels.
    gain : float
    """

    v_cam: np.ndarray
    ok: bool
    reason: str = ""
    error: np.ndarray = None
    error_m: float = float("nan")
    image_error_px: float = float("nan")
    gain: float = 0.0

    @classmethod
    def zero(cls, reason: str) -> "ServoCommand":
        """A zero camera velocity with ``ok=False``.

        Parameters
        ----------
        reason : str
            Why no command was computed.

        Returns
        -------
        ServoCommand
            Zero ``v_cam``, NaN error.
        """
        return cls(v_cam=np.zeros(3), ok=False, reason=reason, error=np.full(3, np.nan))


def limit_velocity(v, v_max: float) -> np.ndarray:
    """Scale ``v`` so that its norm is at most ``v_max`` (direction kept).

    Examples
    --------
    >>> limit_velocity([0.3, 0.4, 0.0], 0.1).round(3).tolist()
    [0.06, 0.08, 0.0]
    """
    v = np.asarray(v, dtype=np.float64)
    n = float(np.linalg.norm(v))
    return v * (v_max / n) if n > v_max else v.copy()


def hybrid_law(uvz, uvz_star, principal_uv, f_px: float, gain) -> tuple[np.ndarray, np.ndarray, float]:
    """Hybrid law (9.1.5): ``v_c = -lambda L_c^-1 (s* - s)``.

    Parameters
    ----------
    uvz, uvz_star : array_like, shape (3,)
        Current and goal feature ``[u px, v px, z m]``.
    principal_uv : array_like, shape (2,)
        Unused by the law itself (L_c has no off-axis terms); kept so the
        hybrid and IBVS laws take the same camera description.
    f_px : float
        Focal length in pixels.
    gain : callable or float
        ``lambda(x)`` of the estimated distance ``x`` (m) or a constant.

    Returns
    -------
    v_cam : ndarray, shape (3,)
        m/s, camera frame.
    e : ndarray, shape (3,)
        ``s* - s``.
    dist_m : float
        ``||L_c^-1 e||``.

    Examples
    --------
    >>> v, e, d = hybrid_law([330.0, 240.0, 0.8], [320.0, 240.0, 0.8], (320, 240), 500.0, 1.0)
    >>> (v.round(4) + 0.0).tolist()
    [0.016, 0.0, 0.0]
    """
    s = np.asarray(uvz, dtype=np.float64)
    s_star = np.asarray(uvz_star, dtype=np.float64)
    z = float(s[2])
    if not (np.isfinite(z) and z > 0) or not np.all(np.isfinite(s_star)):
        raise ValueError(f"uvz: expected a positive finite depth, got {s.tolist()}")
    e = s_star - s
    step = np.array([z / f_px * e[0], z / f_px * e[1], e[2]])      # L_c^-1 e
    dist = float(np.linalg.norm(step))
    lam = gain(dist) if callable(gain) else float(gain)
    return -lam * step, e, dist


def ibvs_law(uv, Z, uv_star, Z_star, principal_uv, f_px: float, gain, *,
             interaction: str = "current") -> tuple[np.ndarray, float]:
    """Classical IBVS (9.1.2) with N points: ``v_c = -lambda L^+ (s - s*)``.

    Parameters
    ----------
    uv, uv_star : array_like, shape (N, 2)
        Current and goal image points, pixels.
    Z, Z_star : array_like, shape (N,)
        Their depths, metres.
    principal_uv : array_like, shape (2,)
        Principal point ``(u0, v0)``, pixels (u right, v down).
    f_px : float
        Focal length in pixels.
    gain : callable or float
        ``lambda(x)`` of the estimated distance ``x`` (m) or a constant.
    interaction : {"current", "desired", "mean"}
        Depths and points the interaction matrix is evaluated at.

    Returns
    -------
    v_cam : ndarray, shape (3,)
    dist_m : float
        ``||L^+ (s - s*)||``.

    Examples
    --------
    >>> sq = np.array([[-10., -10.], [10., -10.], [10., 10.], [-10., 10.]]) + (320, 240)
    >>> v, d = ibvs_law(sq + [5, 0], np.ones(4), sq, np.ones(4), (320, 240), 500.0, 1.0)
    >>> (v.round(4) + 0.0).tolist()
    [0.01, 0.0, 0.0]
    """
    c = np.asarray(principal_uv, dtype=np.float64)
    xy = np.asarray(uv, dtype=np.float64).reshape(-1, 2) - c
    xy_star = np.asarray(uv_star, dtype=np.float64).reshape(-1, 2) - c
    if interaction == "current":
        L = stacked_interaction(xy, Z, f_px)
    elif interaction == "desired":
        L = stacked_interaction(xy_star, Z_star, f_px)
    elif interaction == "mean":
        L = 0.5 * (stacked_interaction(xy, Z, f_px) + stacked_interaction(xy_star, Z_star, f_px))
    else:
        raise ValueError(f"interaction: expected one of {INTERACTION_MODES}, got {interaction!r}")
    e = (xy - xy_star).reshape(-1)
    step = np.linalg.lstsq(L, e, rcond=None)[0]       # L^+ e for a full-column-rank L
    dist = float(np.linalg.norm(step))
    lam = gain(dist) if callable(gain) else float(gain)
    return -lam * step, dist


@dataclass(frozen=True, kw_only=True, eq=False)
class GoalFeatures:
    """The goal taught as an image: its features and the camera's intrinsics.

    Attributes
    ----------
    features : SquareFeatures
        Extracted from the goal image (depth required).
    f_px : float
    principal_uv : ndarray, shape (2,)
    """

    features: SquareFeatures
    f_px: float
    principal_uv: np.ndarray

    def __post_init__(self):
        if not self.features.all_depth_ok:
            raise ValueError("goal: the goal image needs a square with valid depth at its centroid and corners"
                             f" ({self.features.reason or 'invalid depth'})")


def servo_command(features: SquareFeatures, goal: GoalFeatures, config: LawConfig = LawConfig()) -> ServoCommand:
    """Camera velocity for one frame, or a zero command when features or depth are missing.

    Parameters
    ----------
    features : SquareFeatures
        Features of the current frame.
    goal : GoalFeatures
        Taught goal features and the camera's focal length and principal point.
    config : LawConfig
        Control law, interaction matrix choice, gain and velocity limit.

    Returns
    -------
    ServoCommand
        Camera velocity ``v_cam`` (m/s, camera frame), clipped to
        ``config.v_max_m_s``; zero with ``ok=False`` and a ``reason`` when
        features or depths are missing.

    Examples
    --------
    >>> lost = servo_command(SquareFeatures.lost("x"), None)
    >>> lost.ok, lost.v_cam.tolist()
    (False, [0.0, 0.0, 0.0])
    """
    if not features.found:
        return ServoCommand.zero(f"features lost: {features.reason}")
    g = goal.features
    pick = (lambda f: f.centroid_uv) if config.feature == "centroid" else (lambda f: f.center_uv)
    uv, uv_star = pick(features), pick(g)
    if config.law == "hybrid":
        if not features.centroid_depth_ok:
            return ServoCommand.zero("invalid depth at the feature")
        v, e, dist = hybrid_law([*uv, features.depth_m[0]], [*uv_star, g.depth_m[0]], goal.principal_uv,
                                goal.f_px, config.gain)
        img = float(np.hypot(e[0], e[1]))
    else:
        if not features.all_depth_ok:
            return ServoCommand.zero("invalid depth at a corner")
        v, dist = ibvs_law(features.corners_uv, features.depth_m[1:], g.corners_uv, g.depth_m[1:],
                           goal.principal_uv, goal.f_px, config.gain, interaction=config.interaction)
        e = np.array([uv_star[0] - uv[0], uv_star[1] - uv[1], g.depth_m[0] - features.depth_m[0]])
        img = float(np.sqrt(np.mean(np.sum((features.corners_uv - g.corners_uv) ** 2, axis=1))))
    if not np.all(np.isfinite(v)):
        return ServoCommand.zero("non-finite command")
    lam = config.gain(dist) if callable(config.gain) else float(config.gain)
    return ServoCommand(v_cam=limit_velocity(v, config.v_max_m_s), ok=True, error=e, error_m=dist,
                        image_error_px=img, gain=lam)
