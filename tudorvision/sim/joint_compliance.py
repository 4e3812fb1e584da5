"""Joint-side compliance of the elastic links: rotary clamping spring (4.4.5), hub damper and gear backlash.

Each elastic link is held at its hub by a rotary spring ``K_r`` (the seed's
imperfect clamping, gear and joint-controller compliance, equation 4.4.2).
The spring is part of the link's modal basis (:func:`tudorvision.sim.beam.modal_basis`
with ``hub_stiffness_Nm_rad``), so the linear plant rings at the frequencies
of (4.4.5). Two effects are added as a moment on the link root, evaluated
from the hub angle ``phi`` (link root relative to the gear output, rad) of
the previous step (explicit, bounded):

* backlash: a dead zone of full width ``b`` on the spring. The spring
  moment is ``-K_r dz(phi)`` with ``dz(phi) = sign(phi) max(|phi| - b/2, 0)``;
  the basis already holds ``-K_r phi``, so the correction is
  ``+K_r clip(phi, -b/2, b/2)``. Inside the gap the root turns freely.
* hub damper: ``-c_r phi'`` while the spring is engaged (outside the gap),
  the dissipation of the gear and joint controller. Inside the gap only the
  blade's own modal damping acts.

With gravity pulling the link against one side of the gap the link rings
on the engaged spring; where the hub moment of gravity vanishes (the joint-2
gravity torque near ``theta2 = 90 deg``, link 3 vertical at
``theta2 + theta3 = 90 deg``) the oscillation crosses the gap, which lowers
frequency and decay: the "canyons" of the seed's figure 4.8.

Identification (docs/simulation.md, "Matching the seed's measured modes"):
:data:`SEED_MEASURED` (the default ``PlantConfig()``) uses the two-way model. ``K_r`` of links 2 and 3:
:func:`tudorvision.lab.plant_modes.identify_hub_stiffness` scores every pair
of {inf, 3000, 1500, 1000, 800, 600} N m/rad by the worst relative error of
four linearised numbers at 300 g against the seed (link 2's first and second
frequency at theta = 0 (2.0, 9.9 Hz, figure 4.6), link 3's first on its
spring (6.3 Hz), the largest first frequency over theta3 (2.74 Hz, figure
4.8)). It ranks (1000, 600) first (4.1 %) and (1500, 800) at 6.1 %; of the
two pairs run through workspace ring-downs, (800, 600) and (1500, 800),
the latter came closer to the seed's largest first frequency (2.62 against
2.57 Hz) and was kept. Damper and backlash were then set from three
candidate ring-down maps on a 20 deg grid (``benchmarks/bench_plant_modes.py``):
the largest decay rate near the seed's 1.24 1/s and the lowest frequency
(the canyon) near its 1.56 Hz, with a backlash below the seed's "< 1 deg"
(appendix A.3).
"""
from __future__ import annotations

import math

__all__ = ["SEED_MEASURED", "STIFF", "HubCompliance"]

#: PlantConfig fields of the plant identified on the seed's sections 4.7 and 4.8.
SEED_MEASURED = {
    "two_way": True,
    "hub_stiffness_Nm_rad": (1500.0, 800.0),
    "hub_damping_Nms_rad": (6.0, 2.0),
    "backlash_rad": (math.radians(0.6), math.radians(0.6)),
}
#: PlantConfig fields of the former default plant (``PlantConfig.stiff()``): rigid hubs, one-way
#: coupling unless obstacles are present.
STIFF = {
    "two_way": None,
    "hub_stiffness_Nm_rad": (math.inf, math.inf),
    "hub_damping_Nms_rad": (0.0, 0.0),
    "backlash_rad": (0.0, 0.0),
}


class HubCompliance:
    """Backlash and damper moments at the roots of links 2 and 3 (see the module notes).

    Parameters
    ----------
    stiffness_Nm_rad, damping_Nms_rad, backlash_rad : sequence of 2 floats
        ``K_r`` (``inf`` = rigid), damper ``c_r`` and full backlash width per link.

    Raises
    ------
    ValueError
        If a stiffness is not positive, or a damping or backlash is negative,
        or a damper or backlash is given on a rigid hub.
    """

    def __init__(self, stiffness_Nm_rad, damping_Nms_rad, backlash_rad):
        K = [float(k) for k in stiffness_Nm_rad]
        c = [float(x) for x in damping_Nms_rad]
        b = [float(x) for x in backlash_rad]
        if len(K) != 2 or len(c) != 2 or len(b) != 2:
            raise ValueError("hub_stiffness_Nm_rad, hub_damping_Nms_rad, backlash_rad: expected 2 values each")
        for j in range(2):
            if not K[j] > 0 or c[j] < 0 or b[j] < 0 or not (math.isfinite(c[j]) and math.isfinite(b[j])):
                raise ValueError(f"hub compliance of link {j + 2}: expected K_r > 0, c_r >= 0, backlash >= 0, "
                                 f"got {K[j]}, {c[j]}, {b[j]}")
            if not math.isfinite(K[j]) and (c[j] or b[j]):
                raise ValueError(f"hub compliance of link {j + 2}: a damper or backlash needs a finite K_r")
        self.K = K
        self.kinv = [0.0 if not math.isfinite(k) else 1.0 / k for k in K]
        self.c = c
        self.half_gap = [0.5 * x for x in b]
        self.active = any(self.kinv)
        self.nonlinear = any(c) or any(b)

    def static_moment(self, j: int, root_moment_Nm: float) -> float:
        """Backlash correction at rest under the root moment of the loads, N m.

        Parameters
        ----------
        j : int
            0 for link 2, 1 for link 3.
        root_moment_Nm : float
            Moment of the static loads about the hub, ``q L^2/2 + P L + M``.

        Returns
        -------
        float
            ``K_r b/2 sign(M)``: the link rests against the side of the gap the load pushes it to.
        """
        if root_moment_Nm == 0.0 or not self.half_gap[j]:
            return 0.0
        return math.copysign(self.K[j] * self.half_gap[j], root_moment_Nm)

    def moment(self, j: int, phi_rad: float, dphi_rad_s: float) -> float:
        """Correction moment on link ``j``'s root at hub angle ``phi`` and rate ``dphi``, N m.

        Parameters
        ----------
        j : int
            0 for link 2, 1 for link 3.
        phi_rad, dphi_rad_s : float
            Root angle relative to the gear output (rad) and its rate (rad/s).

        Returns
        -------
        float
            ``K_r clip(phi, -b/2, b/2) - c_r phi'`` (the damper only outside the gap).
        """
        hg = self.half_gap[j]
        if phi_rad > hg:
            return self.K[j] * hg - self.c[j] * dphi_rad_s
        if phi_rad < -hg:
            return -self.K[j] * hg - self.c[j] * dphi_rad_s
        return self.K[j] * phi_rad
