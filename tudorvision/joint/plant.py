"""What the joint-control layer needs from an arm: the :class:`Plant` protocol.

The layer's controller (:class:`tudorvision.joint.controlled.ControlledArm`)
and its core (:class:`tudorvision.joint.controlled.CascadeCore`) drive any
object with these members: the simulated elastic TUDOR
(:class:`tudorvision.sim.arm.ElasticArm`) implements it, and so would a driver
for a real arm (amplifier voltages out, encoder and strain-gauge readings in,
stepped once per control sample).
"""
from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from ..robot.params import RobotParams

__all__ = ["Plant"]


@runtime_checkable
class Plant(Protocol):
    """An arm the joint layer can control at a fixed sample time.

    Attributes
    ----------
    params : RobotParams
        Joint ranges, rated speeds and accelerations, actuator constants.
    dt : float
        Control sample time, seconds (0.5 ms on TUDOR).
    t : float
        Time of the latest sample, seconds.
    theta, dtheta : list of float, length 3
        Joint angles (rad) and rates (rad/s) at ``t``; on a real arm the best
        available estimates.
    strain : list of float, length 4
        Root strains of links 2 and 3 (gauges ``[2a, 2b, 3a, 3b]``), m/m.
    payload_kg : float
        End-effector payload mass at start-up, kg (what the layer is told first).
    two_way : bool
        Whether joint motion and link vibration load each other (selects the
        damping gains tuned for that plant).
    """

    params: RobotParams
    t: float
    theta: list
    dtheta: list
    strain: list

    @property
    def dt(self) -> float: ...

    @property
    def two_way(self) -> bool: ...

    @property
    def payload_kg(self) -> float: ...

    def measured_theta(self) -> list:
        """Encoder readings, rad, length 3."""

    def measured_strain(self) -> list:
        """Strain-gauge readings, m/m, length 4."""

    def design_inertia_kg_m2(self) -> np.ndarray:
        """Joint inertias the cascade is designed for, kg m^2, shape (3,)."""

    def step(self, v_M) -> None:
        """Apply amplifier voltages ``v_M`` (3 floats, V) for one sample ``dt``."""
