"""Caught balls swinging in the net: a point mass hanging below the end effector on an elastic bag.

The seed (section 9.3): "caught balls add payload and swing like pendulums". Before this model the lab's
balls were point masses fixed at the end effector. :class:`SwingingBalls` hangs their mass on a string of
``length_m`` (the net's bag) that stretches like fabric (axial mode ``axial_hz``, damping ratio
``axial_zeta``; it only pulls, a slack bag carries nothing) and whose swing the fabric damps
(``swing_zeta`` of the pendulum's frequency). It implements the obstacle interface of
:class:`~tudorvision.sim.arm.ElasticArm` (``force(p_base, v_base)``, ``probe_link``, ``probe_x_m``): the
plant calls :meth:`SwingingBalls.force` once per step with the end effector's position and velocity and
applies the returned force in the next step, joint torques and link modes both.

At rest the bag transmits the balls' weight, so the static deflection, the strains and the payload
estimated from them are those of point masses; in motion the balls lag, swing at about
``sqrt(g / length_m) / (2 pi)`` Hz (1.55 Hz for 0.1 m with the bag's stretch, near the arm's first mode) and
pull the net about.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["SwingingBalls"]

G_M_S2 = 9.81


class SwingingBalls:
    """The balls in the net as one point mass on an elastic, damped string below the end effector.

    Parameters
    ----------
    dt : float
        The plant's step, s (one :meth:`force` call per step).
    length_m : float
        Unstretched length of the bag, from the ring to the balls' centre of mass, m.
    axial_hz, axial_zeta : float
        Stretch mode of the bag with the balls on it, Hz, and its damping ratio.
    swing_zeta : float
        Damping ratio of the swing (the fabric and the balls rubbing), of the pendulum's frequency.
    g : float
        Gravity, m/s^2 (down along the base z axis).

    Attributes
    ----------
    mass_kg : float
        Mass of the balls in the net, kg (0: no force).
    bob_base : ndarray, shape (3,), or None
        The balls' centre of mass, m, base frame (None before the first step with balls).
    """

    probe_link = 3
    probe_x_m = None

    def __init__(self, dt: float, *, length_m: float = 0.1, axial_hz: float = 8.0, axial_zeta: float = 0.3,
                 swing_zeta: float = 0.1, g: float = G_M_S2):
        if not (dt > 0 and length_m > 0 and axial_hz > 0 and axial_zeta >= 0 and swing_zeta >= 0):
            raise ValueError(f"SwingingBalls: expected dt, length_m, axial_hz > 0 and damping ratios >= 0, got "
                             f"{dt}, {length_m}, {axial_hz}, {axial_zeta}, {swing_zeta}")
        self.dt, self.length_m, self.g = float(dt), float(length_m), float(g)
        w_ax = 2 * math.pi * float(axial_hz)
        self._k_per_kg, self._c_per_kg = w_ax * w_ax, 2 * float(axial_zeta) * w_ax
        self._swing_per_s = 2 * float(swing_zeta) * math.sqrt(self.g / self.length_m)
        self._gravity = np.array([0.0, 0.0, -self.g])
        self._none = np.zeros(3)
        self.mass_kg = 0.0
        self.bob_base = None
        self._v_bob = None

    @property
    def swing_hz(self) -> float:
        """Small-swing frequency of the balls below a fixed ring, Hz."""
        return math.sqrt(self.g / (self.length_m + self.g / self._k_per_kg)) / (2 * math.pi)

    def set_mass(self, mass_kg: float) -> None:
        """Balls in the net now weigh ``mass_kg`` (kg); the swing goes on (0: empty, the next ball hangs at rest)."""
        if not (math.isfinite(mass_kg) and mass_kg >= 0):
            raise ValueError(f"mass_kg: expected a finite mass >= 0, got {mass_kg}")
        self.mass_kg = float(mass_kg)
        if self.mass_kg == 0.0:
            self.bob_base = self._v_bob = None

    def force(self, p_base, v_base) -> np.ndarray:
        """Advance the balls one step and return the bag's pull on the end effector, N, base frame, shape (3,).

        Parameters
        ----------
        p_base, v_base : array_like, shape (3,)
            The end effector's position (m) and velocity (m/s), base frame.
        """
        if self.mass_kg == 0.0:
            return self._none.copy()
        p, v = np.asarray(p_base, float), np.asarray(v_base, float)
        if self.bob_base is None:            # the balls start hanging at rest, the bag stretched by their weight
            self.bob_base = p + self._gravity * ((self.length_m + self.g / self._k_per_kg) / self.g)
            self._v_bob = v.copy()
        d = self.bob_base - p
        dist = float(np.linalg.norm(d))
        n = d / dist if dist > 1e-9 else self._gravity / self.g
        dv = self._v_bob - v
        along = float(dv @ n)
        stretch = dist - self.length_m
        pull = 0.0 if stretch <= 0 else max(0.0, self._k_per_kg * stretch + self._c_per_kg * along)
        # per kg of balls: the bag's pull towards the ring and the fabric's damping of the swing across it
        a_bag = -pull * n - self._swing_per_s * (dv - along * n)
        a = a_bag + self._gravity
        self._v_bob = self._v_bob + a * self.dt
        self.bob_base = self.bob_base + self._v_bob * self.dt
        return -self.mass_kg * a_bag
