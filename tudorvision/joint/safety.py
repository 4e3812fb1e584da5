"""Safety checks of the joint-control layer as pure functions.

The server applies these to every command before it reaches the core:

* :func:`check_velocity_command` - refuse NaN, scale or refuse over-speed,
  always refuse absurd speeds (beyond ``clamp_factor`` x the limit);
* :func:`check_setpoint` - clamp or refuse setpoints outside the joint ranges,
  clamp or refuse profile speed/acceleration above the limits, always refuse
  profile limits below the sane minima or beyond ``clamp_factor`` x the
  limits, and profiles whose planned duration is not finite or too long;
* :func:`brake_velocity` - reduce a velocity reference so every joint can still
  stop before its range limit at its acceleration limit;
* :func:`ramp_velocity` - rate-limit the velocity reference to the
  acceleration limits (this is also the controlled stop of the watchdog).

All angles in rad, speeds in rad/s, accelerations in rad/s², joint order
θ1, θ2, θ3.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import check_array
from .messages import Reason

__all__ = ["SafetyLimits", "SafetyPolicy", "Verdict", "SetpointVerdict",
           "check_velocity_command", "check_setpoint", "brake_velocity", "ramp_velocity",
           "stopping_time", "within_range", "profile_duration"]


@dataclass(frozen=True, kw_only=True, eq=False)
class SafetyLimits:
    """Joint ranges and motion limits enforced by the layer.

    Attributes
    ----------
    joint_limits_rad : ndarray, shape (3, 2)
        Hard range ``[lower, upper]`` per joint.
    max_speed_rad_s, max_accel_rad_s2 : ndarray, shape (3,)
        Positive per-joint limits.
    margin_rad : float
        Commands keep this distance inside the hard range (soft limits), to
        absorb tracking lag of the real joint controller.
    default_speed_rad_s, default_accel_rad_s2 : float
        Profile limits used for setpoints that give none (chapter 8: 60 °/s, 200 °/s²).
    min_speed_rad_s, min_accel_rad_s2 : float
        Smallest profile speed and acceleration a setpoint may request
        (0.5 °/s, 1 °/s²): below them planners lose precision (5e-324 once
        crashed one), so smaller requests are refused.
    max_duration_s : float
        Longest planned point-to-point motion accepted (over a whole joint range).
    """

    joint_limits_rad: np.ndarray
    max_speed_rad_s: np.ndarray
    max_accel_rad_s2: np.ndarray
    margin_rad: float = np.deg2rad(0.5)
    default_speed_rad_s: float = np.deg2rad(60.0)
    default_accel_rad_s2: float = np.deg2rad(200.0)
    min_speed_rad_s: float = np.deg2rad(0.5)
    min_accel_rad_s2: float = np.deg2rad(1.0)
    max_duration_s: float = 3600.0

    def __post_init__(self):
        lim = check_array(self.joint_limits_rad, "joint_limits_rad", (3, 2))
        if not np.all(lim[:, 1] - lim[:, 0] > 2 * self.margin_rad):
            raise ValueError("joint_limits_rad: each upper limit must exceed the lower one "
                             "by more than twice margin_rad")
        for name in ("max_speed_rad_s", "max_accel_rad_s2"):
            v = check_array(getattr(self, name), name, (3,))
            if not np.all(v > 0):
                raise ValueError(f"{name}: limits must be positive, got {v.tolist()}")
            v.setflags(write=False)
            object.__setattr__(self, name, v)
        lim.setflags(write=False)
        object.__setattr__(self, "joint_limits_rad", lim)
        if not self.margin_rad >= 0:
            raise ValueError(f"margin_rad: must be >= 0, got {self.margin_rad}")
        for name in ("default_speed_rad_s", "default_accel_rad_s2", "min_speed_rad_s",
                     "min_accel_rad_s2", "max_duration_s"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name}: must be positive and finite, got {v}")
        if not (self.min_speed_rad_s <= self.default_speed_rad_s
                and self.min_accel_rad_s2 <= self.default_accel_rad_s2):
            raise ValueError("min_speed_rad_s/min_accel_rad_s2: must not exceed the defaults")

    @classmethod
    def from_params(cls, params=None, **options) -> "SafetyLimits":
        """Limits from :class:`tudorvision.robot.RobotParams` (default: the packaged file).

        Examples
        --------
        >>> lim = SafetyLimits.from_params()
        >>> np.rad2deg(lim.max_speed_rad_s).round().tolist()
        [184.0, 125.0, 146.0]
        """
        if params is None:
            from ..robot import load_robot_params
            params = load_robot_params()
        options.setdefault("default_speed_rad_s", params.experiment_speed_rad_s)
        options.setdefault("default_accel_rad_s2", params.experiment_accel_rad_s2)
        return cls(joint_limits_rad=params.joint_limits_rad,
                   max_speed_rad_s=params.max_speed_rad_s,
                   max_accel_rad_s2=params.max_accel_rad_s2, **options)

    @property
    def soft_limits_rad(self) -> np.ndarray:
        """``joint_limits_rad`` shrunk by ``margin_rad``, shape (3, 2)."""
        return self.joint_limits_rad + np.array([self.margin_rad, -self.margin_rad])


@dataclass(frozen=True, kw_only=True)
class SafetyPolicy:
    """What to do with commands beyond the limits: ``"clamp"`` or ``"refuse"``.

    ``velocity_over_speed="clamp"`` scales the whole velocity vector down so the
    direction of motion in joint space is kept. A clamp is never silent: the
    answer carries a ``CLAMPED_*`` code and text. Requests beyond
    ``clamp_factor`` times a limit are not a slightly eager command but
    nonsense (1e300 rad/s), and are refused whatever the policy.
    """

    velocity_over_speed: str = "clamp"
    setpoint_out_of_range: str = "refuse"
    setpoint_over_limits: str = "clamp"
    clamp_factor: float = 10.0

    def __post_init__(self):
        if not (np.isfinite(self.clamp_factor) and self.clamp_factor >= 1.0):
            raise ValueError(f"clamp_factor: expected a finite number >= 1, got {self.clamp_factor}")
        for name in ("velocity_over_speed", "setpoint_out_of_range", "setpoint_over_limits"):
            if getattr(self, name) not in ("clamp", "refuse"):
                raise ValueError(f"{name}: expected 'clamp' or 'refuse', "
                                 f"got {getattr(self, name)!r}")


@dataclass(frozen=True, kw_only=True, eq=False)
class Verdict:
    """Outcome of a velocity check: ``value`` is None when refused."""

    value: np.ndarray | None
    code: Reason
    text: str = ""

    @property
    def accepted(self) -> bool:
        return self.value is not None

    @property
    def clamped(self) -> bool:
        return self.value is not None and self.code != Reason.OK


@dataclass(frozen=True, kw_only=True, eq=False)
class SetpointVerdict(Verdict):
    """Outcome of a setpoint check, with the per-joint profile limits to use (shape (3,))."""

    max_speed_rad_s: np.ndarray | None = None
    max_accel_rad_s2: np.ndarray | None = None


def _fmt(v) -> str:
    return "[" + ", ".join(f"{x:.4g}" for x in np.atleast_1d(v)) + "]"


def check_velocity_command(theta_dot, limits: SafetyLimits, *,
                           policy: SafetyPolicy = SafetyPolicy()) -> Verdict:
    """Check a joint velocity command against the speed limits.

    Parameters
    ----------
    theta_dot : array_like, shape (3,)
        Commanded joint speeds in rad/s.
    limits : SafetyLimits
    policy : SafetyPolicy
        ``velocity_over_speed`` decides between scaling and refusing.

    Returns
    -------
    Verdict
        ``NON_FINITE`` refusal for NaN/inf; ``CLAMPED_SPEED`` with the scaled
        vector (same direction, every joint within its limit) or
        ``OVER_SPEED`` refusal; else ``OK`` with the command unchanged.

    Examples
    --------
    >>> lim = SafetyLimits.from_params()
    >>> v = check_velocity_command([10.0, 0.0, 0.0], lim)
    >>> v.code.name, round(float(v.value[0]), 4) == round(float(lim.max_speed_rad_s[0]), 4)
    ('CLAMPED_SPEED', True)
    """
    v = check_array(theta_dot, "theta_dot", (3,), finite=False)
    if not np.all(np.isfinite(v)):
        return Verdict(value=None, code=Reason.NON_FINITE,
                       text=f"theta_dot {_fmt(v)}: NaN or infinite value")
    ratio = np.abs(v) / limits.max_speed_rad_s
    worst = float(ratio.max())
    if worst <= 1.0:
        return Verdict(value=v, code=Reason.OK)
    j = int(ratio.argmax())
    text = (f"joint {j + 1} speed {abs(v[j]):.4g} rad/s exceeds the limit "
            f"{limits.max_speed_rad_s[j]:.4g} rad/s")
    if policy.velocity_over_speed == "refuse" or worst > policy.clamp_factor:
        return Verdict(value=None, code=Reason.OVER_SPEED, text=text)
    scaled = v / worst
    scaled = np.clip(scaled, -limits.max_speed_rad_s, limits.max_speed_rad_s)  # rounding
    return Verdict(value=scaled, code=Reason.CLAMPED_SPEED,
                   text=text + f"; scaled by {1 / worst:.4g}")


def check_setpoint(theta, limits: SafetyLimits, *, max_speed: float | None = None,
                   max_accel: float | None = None,
                   policy: SafetyPolicy = SafetyPolicy()) -> SetpointVerdict:
    """Check a joint setpoint and its profile limits.

    Parameters
    ----------
    theta : array_like, shape (3,)
        Target joint angles in rad.
    limits : SafetyLimits
    max_speed, max_accel : float or None
        Requested scalar profile speed (rad/s) and acceleration (rad/s²);
        ``None`` takes the defaults of ``limits``.
    policy : SafetyPolicy

    Returns
    -------
    SetpointVerdict
        ``value`` is the target to execute (clamped into the soft limits when the
        policy says so); ``max_speed_rad_s`` / ``max_accel_rad_s2`` are per-joint
        profile limits, each ``min(requested, joint limit)``. Refusal codes:
        ``NON_FINITE``, ``OUT_OF_RANGE``, ``OVER_SPEED``, ``OVER_ACCEL`` (the last
        two also for requests below ``limits.min_*``, beyond ``policy.clamp_factor``
        times the joint limits, or giving a planned duration over
        ``limits.max_duration_s``).

    Examples
    --------
    >>> lim = SafetyLimits.from_params()
    >>> check_setpoint([0.0, 4.0, 0.0], lim).code.name
    'OUT_OF_RANGE'
    >>> check_setpoint([0.0, 1.0, 0.0], lim, max_speed=0.5).max_speed_rad_s.tolist()
    [0.5, 0.5, 0.5]
    """
    th = check_array(theta, "theta", (3,), finite=False)
    extras = [x for x in (max_speed, max_accel) if x is not None]
    if not (np.all(np.isfinite(th)) and np.all(np.isfinite(extras))):
        return SetpointVerdict(value=None, code=Reason.NON_FINITE,
                               text="setpoint: NaN or infinite value")
    code, notes = Reason.OK, []

    soft = limits.soft_limits_rad
    inside = th.clip(soft[:, 0], soft[:, 1])
    if not np.array_equal(inside, th):
        j = int(np.argmax(np.abs(inside - th)))
        text = (f"joint {j + 1} setpoint {np.rad2deg(th[j]):.2f} deg outside the range "
                f"[{np.rad2deg(soft[j, 0]):.2f}, {np.rad2deg(soft[j, 1]):.2f}] deg")
        if policy.setpoint_out_of_range == "refuse":
            return SetpointVerdict(value=None, code=Reason.OUT_OF_RANGE, text=text)
        code, notes, th = Reason.CLAMPED_RANGE, [text + "; clamped"], inside

    profile = []
    for req, default, lim, low, over, clamped, what in (
            (max_speed, limits.default_speed_rad_s, limits.max_speed_rad_s, limits.min_speed_rad_s,
             Reason.OVER_SPEED, Reason.CLAMPED_SPEED, "speed"),
            (max_accel, limits.default_accel_rad_s2, limits.max_accel_rad_s2, limits.min_accel_rad_s2,
             Reason.OVER_ACCEL, Reason.CLAMPED_ACCEL, "acceleration")):
        if req is not None and not req >= low:
            return SetpointVerdict(value=None, code=over,
                                   text=f"profile {what} {req:.4g} below the minimum {low:.4g}")
        want = float(default if req is None else req)
        per_joint = np.minimum(want, lim)
        if req is not None and np.any(want > lim):
            text = f"profile {what} {want:.4g} exceeds the joint limits {_fmt(lim)}"
            if policy.setpoint_over_limits == "refuse" or np.any(want > policy.clamp_factor * lim):
                return SetpointVerdict(value=None, code=over, text=text)
            if code == Reason.OK:
                code = clamped
            notes.append(text + "; clamped per joint")
        profile.append(per_joint)
    span = limits.soft_limits_rad[:, 1] - limits.soft_limits_rad[:, 0]
    worst = float(np.max(profile_duration(span, profile[0], profile[1])))
    if not (np.isfinite(worst) and worst <= limits.max_duration_s):
        return SetpointVerdict(value=None, code=Reason.OVER_SPEED,
                               text=f"profile would take up to {worst:.4g} s over a joint range "
                                    f"(limit {limits.max_duration_s:g} s)")
    return SetpointVerdict(value=th, code=code, text="; ".join(notes),
                           max_speed_rad_s=profile[0], max_accel_rad_s2=profile[1])


def profile_duration(distance, max_speed, max_accel) -> np.ndarray:
    """Duration in s of a rest-to-rest trapezoidal (or triangular) profile per joint.

    Parameters
    ----------
    distance : array_like, shape (3,)
        Travel per joint in rad (sign ignored).
    max_speed, max_accel : array_like, shape (3,)
        Positive profile limits in rad/s and rad/s².

    Examples
    --------
    >>> profile_duration([1.0, 4.0, 0.0], [1.0, 1.0, 1.0], [1.0, 1.0, 1.0]).tolist()
    [2.0, 5.0, 0.0]
    """
    d = np.abs(np.asarray(distance, dtype=np.float64))
    v = np.asarray(max_speed, dtype=np.float64)
    a = np.asarray(max_accel, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        cruise = d > v * v / a
        return np.where(cruise, d / v + v / a, 2.0 * np.sqrt(d / a))


def brake_velocity(theta, theta_dot, limits: SafetyLimits, dt: float, *,
                   theta_dot_now=None) -> np.ndarray:
    """Limit a velocity reference so each joint can stop inside its soft range.

    A joint moving toward a limit at distance ``d`` keeps at most
    ``sqrt(2 a max(d - 2 |v| dt, 0))``: decelerating at its limit ``a`` from
    there, it stops before the limit despite a control period or two of lag.
    Motion away from the limits is untouched.

    Parameters
    ----------
    theta : array_like, shape (3,)
        Current joint angles in rad.
    theta_dot : array_like, shape (3,)
        Velocity reference in rad/s.
    limits : SafetyLimits
    dt : float
        Control period in s.
    theta_dot_now : array_like, shape (3,), optional
        Velocity the joint has now (e.g. the ramped reference), for the lag
        term ``v``; default ``theta_dot``.

    Returns
    -------
    ndarray, shape (3,)

    Examples
    --------
    >>> lim = SafetyLimits.from_params(margin_rad=0.0)
    >>> upper = lim.joint_limits_rad[2, 1]
    >>> brake_velocity([0.0, 1.0, upper], [0.0, 0.0, 1.0], lim, 1e-3).tolist()
    [0.0, 0.0, 0.0]
    """
    th = check_array(theta, "theta", (3,))
    v = check_array(theta_dot, "theta_dot", (3,)).copy()
    soft = limits.soft_limits_rad
    a = limits.max_accel_rad_s2
    v_now = v if theta_dot_now is None else check_array(theta_dot_now, "theta_dot_now", (3,))
    slack = 2.0 * np.maximum(np.abs(v), np.abs(v_now)) * dt
    d_up = np.maximum(soft[:, 1] - th - slack, 0.0)
    d_lo = np.maximum(th - soft[:, 0] - slack, 0.0)
    v = np.minimum(v, np.sqrt(2 * a * d_up))
    v = np.maximum(v, -np.sqrt(2 * a * d_lo))
    # beyond the soft range: never move further out
    v = np.where(th >= soft[:, 1], np.minimum(v, 0.0), v)
    v = np.where(th <= soft[:, 0], np.maximum(v, 0.0), v)
    return v


def ramp_velocity(theta_dot_ref, theta_dot_target, max_accel, dt: float) -> np.ndarray:
    """Move a velocity reference toward a target by at most ``max_accel * dt`` per joint.

    Examples
    --------
    >>> ramp_velocity([0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [2.0, 2.0, 2.0], 0.1).tolist()
    [0.2, 0.8, 0.0]
    """
    ref = check_array(theta_dot_ref, "theta_dot_ref", (3,))
    tgt = check_array(theta_dot_target, "theta_dot_target", (3,))
    step = np.asarray(max_accel, dtype=np.float64) * float(dt)
    return ref + np.clip(tgt - ref, -step, step)


def stopping_time(theta_dot, max_accel) -> float:
    """Time in s to stop every joint at its acceleration limit (the slowest joint).

    Examples
    --------
    >>> stopping_time([1.0, -2.0, 0.0], [2.0, 2.0, 2.0])
    1.0
    """
    v = check_array(theta_dot, "theta_dot", (3,))
    return float(np.max(np.abs(v) / np.asarray(max_accel, dtype=np.float64)))


def within_range(theta, limits: SafetyLimits, *, tol: float = 0.0) -> bool:
    """True if every joint lies inside the hard range widened by ``tol`` rad."""
    th = check_array(theta, "theta", (3,))
    lim = limits.joint_limits_rad
    return bool(np.all(th >= lim[:, 0] - tol) and np.all(th <= lim[:, 1] + tol))
