"""What the net holds, kg: weighings at rest fused with what each catch can add.

The catching arm weighs its payload from the strains at rest (the strain
model of section 9.2, :class:`~tudorvision.catch.kinematics.StrainModel`). At
rest that reading is good to about a centimetre's worth of deflection (10-30 g
in the lab), but between two throws the elastic arm is often not at rest: its
damper is still working on the links' and the balls' swing when the next ball
comes, and a weighing taken while the joints move carries the motion (errors of
hundreds of grams). Skipping those weighings leaves the estimate of the last
good one, several balls behind a net that keeps filling.

The payload changes in known steps: a throw the arm tried to catch adds one
ball's mass with the probability of a catch, an emptied net holds nothing. A
scalar Kalman filter carries that knowledge between weighings
(:func:`after_throw`, :func:`after_emptying`) and takes each good weighing in
(:func:`weighed`; :func:`between_throws` chains the three); a weighing far outside the belief (a ball that fell out, a
wrong prior) replaces it. Pure functions on a small frozen state; the catching
agent holds one.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["PayloadBelief", "after_throw", "after_emptying", "weighed", "between_throws"]


@dataclass(frozen=True)
class PayloadBelief:
    """Belief about the payload on top of the end-effector mount.

    Parameters
    ----------
    mean_kg : float
        Expected payload, kg.
    var_kg2 : float
        Its variance, kg^2.
    """

    mean_kg: float = 0.0
    var_kg2: float = 0.0

    @property
    def sigma_kg(self) -> float:
        """Standard deviation, kg."""
        return math.sqrt(max(self.var_kg2, 0.0))


def _check(name: str, value: float, lo: float, hi: float = math.inf, *, above: bool = False) -> float:
    """``value`` as a float, finite and in ``[lo, hi]`` (``(lo, hi]`` with ``above``), else a one-line ValueError."""
    v = float(value)
    if not (math.isfinite(v) and (v > lo if above else v >= lo) and v <= hi):
        raise ValueError(f"{name}: expected a finite value in {'(' if above else '['}{lo:g}, {hi:g}], got {value!r}")
    return v


def after_throw(belief: PayloadBelief, ball_kg: float, p_catch: float) -> PayloadBelief:
    """The belief after a throw that adds ``ball_kg`` with probability ``p_catch`` (a Bernoulli step).

    Parameters
    ----------
    belief : PayloadBelief
        Before the throw.
    ball_kg : float
        Mass of one ball, kg (>= 0).
    p_catch : float
        Probability that the throw was caught, 0-1 (0 for a throw the arm did not try to catch).

    Returns
    -------
    PayloadBelief
        Mean raised by ``p ball_kg``, variance by ``p (1 - p) ball_kg^2``.

    Examples
    --------
    >>> b = after_throw(PayloadBelief(0.06, 1e-4), 0.03, 0.9)
    >>> round(b.mean_kg, 4), round(b.var_kg2, 7)
    (0.087, 0.000181)
    """
    m = _check("ball_kg", ball_kg, 0.0)
    p = _check("p_catch", p_catch, 0.0, 1.0)
    return PayloadBelief(belief.mean_kg + p * m, belief.var_kg2 + p * (1.0 - p) * m * m)


def after_emptying(sigma_kg: float = 0.0) -> PayloadBelief:
    """The belief once the net has been emptied: nothing on the mount, within ``sigma_kg``.

    Examples
    --------
    >>> after_emptying(0.005)
    PayloadBelief(mean_kg=0.0, var_kg2=2.5e-05)
    """
    s = _check("sigma_kg", sigma_kg, 0.0)
    return PayloadBelief(0.0, s * s)


def weighed(belief: PayloadBelief, z_kg: float, sigma_kg: float, *, gate_sigmas: float = 4.0) -> PayloadBelief:
    """The belief after a weighing ``z_kg`` with standard deviation ``sigma_kg`` (a Kalman update).

    A weighing whose innovation exceeds ``gate_sigmas`` standard deviations of
    the innovation replaces the belief (mean ``z_kg``, variance ``sigma_kg^2``):
    the belief's own steps were wrong (a ball lost, the net emptied unseen).

    Parameters
    ----------
    belief : PayloadBelief
        Before the weighing.
    z_kg : float
        The weighing, kg (not clipped: a clipped reading would bias the mean).
    sigma_kg : float
        Its standard deviation, kg (> 0).
    gate_sigmas : float
        Innovation gate, standard deviations (> 0).

    Returns
    -------
    PayloadBelief

    Examples
    --------
    >>> b = weighed(PayloadBelief(0.09, 1e-4), 0.12, 0.01)      # equal variances: halfway
    >>> round(b.mean_kg, 4), round(b.var_kg2, 7)
    (0.105, 5e-05)
    >>> weighed(PayloadBelief(0.0, 1e-4), 0.2, 0.01)             # 14 sigma off: the weighing wins
    PayloadBelief(mean_kg=0.2, var_kg2=0.0001)
    """
    z = _check("z_kg", z_kg, -math.inf)
    s = _check("sigma_kg", sigma_kg, 0.0, above=True)
    g = _check("gate_sigmas", gate_sigmas, 0.0, above=True)
    r = s * s
    s_inn = belief.var_kg2 + r
    nu = z - belief.mean_kg
    if nu * nu > g * g * s_inn:
        return PayloadBelief(z, r)
    k = belief.var_kg2 / s_inn
    return PayloadBelief(belief.mean_kg + k * nu, (1.0 - k) * belief.var_kg2)


def between_throws(belief: PayloadBelief, z_kg: float | None, *, ball_kg: float, p_catch: float, emptied: bool,
                   sigma_kg: float, gate_sigmas: float = 4.0) -> PayloadBelief:
    """The belief from one throw to the next: the throw's step, the emptying, then the weighing if there is one.

    Parameters
    ----------
    belief : PayloadBelief
        At the previous throw.
    z_kg : float or None
        The weighing at rest after this throw, kg; None when the arm did not rest (no weighing).
    ball_kg, p_catch : float
        As :func:`after_throw` (``p_catch`` 0 for a throw the arm did not try to catch).
    emptied : bool
        The net was emptied after the throw (:func:`after_emptying`; the throw's step is then moot).
    sigma_kg, gate_sigmas : float
        As :func:`weighed`.

    Returns
    -------
    PayloadBelief

    Examples
    --------
    Three tried throws without a weighing, then one at rest:

    >>> b = PayloadBelief()
    >>> for _ in range(3):
    ...     b = between_throws(b, None, ball_kg=0.03, p_catch=0.9, emptied=False, sigma_kg=0.012)
    >>> round(b.mean_kg, 3), round(b.sigma_kg, 4)
    (0.081, 0.0156)
    >>> b = between_throws(b, 0.12, ball_kg=0.03, p_catch=0.9, emptied=False, sigma_kg=0.012)
    >>> round(b.mean_kg, 3)
    0.116
    """
    b = after_emptying() if emptied else after_throw(belief, ball_kg, p_catch)
    return b if z_kg is None else weighed(b, z_kg, sigma_kg, gate_sigmas=gate_sigmas)
