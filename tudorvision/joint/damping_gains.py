"""Tuned gains of the damping laws per plant, and their payload schedules (sections 8.1-8.3).

The laws, the filter and ``default_damping_config`` (which picks from these tables) are
in :mod:`tudorvision.joint.damping`, which re-exports these names. A gain set is chosen by the plant the layer runs on
(:data:`GAIN_SETS`): ``"soft"`` for the plant identified on the seed's measured
modes (the lab's default: hub springs, dampers and backlash, two-way coupling),
``"one-way"`` and ``"two-way"`` for the stiff rigid-hub plant
(``PlantConfig.stiff()``). A plant tells its set through a ``gain_set``
attribute; without one the layer falls back on ``two_way``.
"""
from __future__ import annotations

import numpy as np

from .._checks import check_mass

__all__ = ["HOLD_LOOPS", "hold_loop_of", "LAWS", "ONE_WAY_GAINS", "TWO_WAY_GAINS", "SOFT_GAINS", "GAIN_SETS",
           "DEFAULT_GAINS", "ASSISTED_GAINS",
           "PAYLOAD_SCHEDULE", "PAYLOAD_SCHEDULES", "PD_SCALES", "payload_gain_factor", "pd_scale_of", "gain_set_of",
           "gain_table", "scheduled_gains"]

#: The damping laws (``"off"``: the bare cascade).
LAWS = ("off", "proportional", "integral", "half_integrator")

#: Gains tuned on experiment 06 (300 g, no noise) by minimising IATS of both root
#: gauges (Nelder-Mead on log gains, ``benchmarks/bench_damping_ch8.py --tune``, refined
#: on a grid for the proportional law); fixed for all experiments as in chapter 8.
#: Stiff one-way plant (the seed's independent joint-link modules, ``PlantConfig.stiff()``):
ONE_WAY_GAINS = {
    "proportional": (0.0, 1600.0, 300.0),
    "integral": (0.0, 948.0, 1283.0),
    "half_integrator": (0.0, 245.0, 7.3),
}
#: Stiff two-way coupled plant (``PlantConfig.stiff(two_way=True)``; the joint servo feels the links):
TWO_WAY_GAINS = {
    "proportional": (0.0, 400.0, 6400.0),
    "integral": (0.0, 864.0, 520.0),
    "half_integrator": (0.0, 245.0, 7.3),
}
#: The default soft plant (``PlantConfig()``, seed-measured; ``docs/joint_layer.md``, "Chapter 8 on the
#: soft plant"), chosen on grids over all 12 experiments (no noise, the seed's filter), not by
#: Nelder-Mead. Integral: the one-way gains (all 12 settle, mean 3.2 s); half-integrator: k2 halved
#: from 245 (a tail at experiment 10), all 12 settle. Proportional (issue 18): together with the
#: position-loop scale of :data:`PD_SCALES` (0.04 on the former 3 / 10 ms holding loop, i.e. k_PD 1 1/s; 0.01 on
#: today's 1 / 3 ms, 0.83 1/s); grid pd scale in {0.04 ... 1} x k2 in {150 ... 1600} x
#: k3 in {300 ... 1500} on experiment 06 with 0.05 / 0.35 / 0.65 / 0.85 kg, then all 12 experiments,
#: holds near the vertical (backlash canyon) with 0.05 / 0.35 / 0.85 kg and the 600 g drop
#: (``docs/benchmarks.md``, "Proportional damping on the soft plant"): all 12 settle (mean 2.8 s, no
#: noise), no tail at the vertical, no growing oscillation from 0.05 to 0.85 kg with the fixed gains.
SOFT_GAINS = {
    "proportional": (0.0, 250.0, 800.0),
    "integral": (0.0, 948.0, 1283.0),
    "half_integrator": (0.0, 120.0, 7.3),
}
#: Gain sets by plant name (``gain_set`` of a plant).
GAIN_SETS = {"soft": SOFT_GAINS, "one-way": ONE_WAY_GAINS, "two-way": TWO_WAY_GAINS}
DEFAULT_GAINS = SOFT_GAINS
#: Proportional gains with the model-assisted static strain cancellation (``StrainDamper(...,
#: strain_model=...)``). The link-3 gain is lower than in ``ONE_WAY_GAINS``: 300 rad/s per m/m
#: is stable for the small strains the plain filter passes but, on the one-way plant, starts a
#: growing joint-3 oscillation once a larger signal breaks the joint loose (5 deg steps from the
#: operating points of figure 8.1 with the assisted filter); 100 is stable on all 12 experiments.
#: Two-way plant: best of a coarse grid k2 in {400, 800, 1600} x k3 in {400, 1600, 3200} on
#: experiment 06 (2 noise seeds): 4.33 s, i.e. only a 57 % cut on that plant.
#: Soft plant: the soft plant's former proportional gains (not re-tuned with a strain model; kept for the
#: chapter-10 identification runs, which damp with them at the designed ``k_PD``). Through
#: ``default_damping_config`` the position-loop scale of :data:`PD_SCALES` applies to them as well
#: (0.04 on the former 3 / 10 ms loop: with the plain filter experiment 06 settled with them in 3.4 s at 0.35 kg,
#: 3.9 s at 0.85 kg).
ASSISTED_GAINS = {"one-way": (0.0, 1600.0, 100.0), "two-way": (0.0, 800.0, 1600.0), "soft": (0.0, 200.0, 300.0)}

#: Factor on the position-loop gain ``k_PD`` while a law acts, per gain set (``DampingConfig.pd_gain_scale``;
#: a law not listed keeps ``DampingConfig``'s default: 0.5 for the integral law (section 6.5), else 1).
#: Soft plant: its holding loop (:data:`HOLD_LOOPS`, 1 / 3 ms) has ``k_PD`` = 83.3 1/s; the integral and
#: half-integrator laws keep the 12.5 and 25 1/s they were tuned with on the former 3 / 10 ms loop (0.15, 0.3).
#: Proportional law: 0.01 (``k_PD`` 0.83 1/s; on the 3 / 10 ms loop it ran at 0.04 x 25 = 1 1/s: with the
#: stiffer velocity loop 1 1/s left a 15.7 um/m tail at the vertical with 0.85 kg, 0.83 1/s 11 um/m, against the
#: 15 um/m band; experiment 06 settles in 2.9 s either way). The velocity the law adds at the
#: velocity-loop input (5.2.1) is pulled back by the position loop: with an ideal velocity loop the
#: joint answers it as ``s / (s + k_PD)``, so the link sees its root held by a spring ``k_PD / k`` beside
#: the damper ``1 / k`` the law makes. For one mode of ``omega`` this bounds the decay rate the law can
#: give, whatever ``k``, to about ``omega^2 / (2 k_PD)``: 0.79 1/s at 2.0 Hz and 0.42 1/s at 1.45 Hz with
#: ``k_PD = 25`` (the soft plant rings ~10x longer after a move than the stiff one, and its heavy-payload
#: mode is lower), ~12 1/s with ``k_PD = 1``, where the mode's poles can reach the real axis as in the
#: seed's root locus (figure 5.2 (d)); the stiff plant (2.67 Hz, little residual ringing) hid it. With
#: ``k_PD = 25`` larger gains only lower the frequency, and near the vertical (backlash canyon) and with
#: heavy payloads they start joint-2 limit cycles. The joints still reach their goals without error
#: (the PI velocity loop holds the load; the position error decays at ``k_PD``, ~1 s). The cost is a
#: softer hold: where the law breaks a joint loose from stiction the load can make it sag before the
#: PI loop takes it (servo goal pose, right after the mode switch: joint 2 0.65 deg, 5.5 mm at the
#: camera, against 0.07 deg with the designed ``k_PD``). Integrating the law's velocity into the
#: position reference with a leak (2 1/s) instead keeps the hold (1 mm) but damps 0.85 kg less
#: (vertical hold: 221 um/m tail; 600 g drop 7.7 s against 4.0 s).
PD_SCALES = {"soft": {"proportional": 0.01, "integral": 0.15, "half_integrator": 0.3}, "one-way": {}, "two-way": {}}


#: The joint cascade's holding loop per gain set: ``(t_d, t_l)`` of :func:`~tudorvision.joint.cascade.design_cascade`
#: (velocity filter and position-loop lag, s). Soft plant (seed-measured): 1 / 3 ms, identified on the ring-downs
#: of figure 4.8 (the seed gives no values): the held arm's slowest decay is then the seed's 0.03 1/s, where the
#: softer 3 / 10 ms loop dissipates the links' swing through the joints (0.11 1/s; ``docs/simulation.md``,
#: "Decay floor"). Its damping laws keep the position-loop gains they were tuned with (:data:`PD_SCALES`). The
#: stiff plants keep the designed 3 / 10 ms their gains were tuned on.
HOLD_LOOPS = {"soft": (0.001, 0.003), "one-way": (0.003, 0.01), "two-way": (0.003, 0.01)}


#: Payload schedule of the link-3 gain for the one-way plant's tuned gains (``ONE_WAY_GAINS``,
#: tuned at 300 g of plates + the 50 g mount = 0.35 kg): ``(masses_kg, factors)``, the factor on
#: ``k_eps[2]`` piecewise linear in the known payload mass and constant beyond the ends. Fixed
#: gains, as in section 8.3 of the seed, are not robust on the simulated arm: the tuned link-3
#: gain starts a growing joint-3 oscillation at the mount alone (0.05 kg, link-3 mode ~13.6 Hz)
#: and from ~0.45 kg (proportional) / ~0.5 kg (integral) once a large motion excites it (e.g. a
#: payload dropped while the links swing). Breakpoints from a stability sweep (three operating
#: points, large steps, payloads 0.05-0.65 kg, factors 1/4-1): every scheduled gain decays
#: there. The half-integrator needs no schedule (stable over the whole range).
PAYLOAD_SCHEDULE = {
    "proportional": ((0.05, 0.08, 0.36, 0.45, 0.55), (2.0 / 3.0, 1.0, 1.0, 0.5, 1.0 / 3.0)),
    "integral": ((0.08, 0.12, 0.45, 0.5, 0.65), (0.5, 1.0, 1.0, 0.5, 0.25)),
}
#: Payload schedules by gain set (a set without one keeps its gains at every payload). The soft plant
#: needs none: with :data:`PD_SCALES` its fixed gains damp from the bare mount to 0.85 kg.
PAYLOAD_SCHEDULES = {"one-way": PAYLOAD_SCHEDULE, "soft": {}}


def gain_set_of(plant) -> str:
    """The gain set (key of :data:`GAIN_SETS`) of a plant.

    Parameters
    ----------
    plant : Plant
        An arm; its ``gain_set`` attribute if it has one, else ``"two-way"`` or
        ``"one-way"`` from its ``two_way`` flag.

    Returns
    -------
    str
        ``"soft"``, ``"one-way"`` or ``"two-way"``.
    """
    name = getattr(plant, "gain_set", None)
    if name is None:
        return "two-way" if getattr(plant, "two_way", False) else "one-way"
    if name not in GAIN_SETS:
        raise ValueError(f"gain_set: expected one of {tuple(GAIN_SETS)}, got {name!r}")
    return name


def payload_gain_factor(law: str, payload_kg: float, plant: str = "soft") -> float:
    """Factor on the tuned link-3 gain of ``law`` at this payload (:data:`PAYLOAD_SCHEDULES`; 1 if none).

    Parameters
    ----------
    law : str
        Damping law.
    payload_kg : float
        Known payload mass, kg.
    plant : str
        Gain set (:data:`GAIN_SETS`).

    Returns
    -------
    float
        Factor on ``k_eps[2]``.

    Examples
    --------
    >>> f = [payload_gain_factor("proportional", m, "one-way") for m in (0.35, 0.5)]
    >>> f[0], round(f[1], 4)
    (1.0, 0.4167)
    >>> payload_gain_factor("half_integrator", 0.05, "one-way"), payload_gain_factor("proportional", 0.05)
    (1.0, 1.0)
    """
    if law not in LAWS:
        raise ValueError(f"law: expected one of {LAWS}, got {law!r}")
    m = check_mass(payload_kg)
    schedule = PAYLOAD_SCHEDULES.get(plant, {})
    if law not in schedule:
        return 1.0
    masses, factors = schedule[law]
    return float(np.interp(m, masses, factors))


def gain_table(gains) -> np.ndarray | None:
    """Damping gains given as one ``k_eps`` (3,) or as a payload table, checked; the table as ``(M, 4)``, else None.

    A table has rows ``(payload_kg, k1, k2, k3)`` with increasing masses (M >= 1); it may also come flattened
    (``4 M`` numbers, M >= 2), as a command line gives it.

    Parameters
    ----------
    gains : array_like
        Three gains, or the table.

    Returns
    -------
    ndarray, shape (M, 4), or None
        The table; None for three gains.

    Raises
    ------
    ValueError
        On another shape, a non-finite or negative entry, or masses not increasing.

    Examples
    --------
    >>> gain_table((0.0, 400.0, 400.0)) is None
    True
    >>> gain_table((0.11, 0, 600, 400, 0.17, 0, 400, 400)).shape
    (2, 4)
    """
    g = np.asarray(gains, float)
    if g.shape == (3,):
        table = None
    elif g.ndim == 2 and g.shape[1] == 4 and len(g) >= 1:
        table = g
    elif g.ndim == 1 and len(g) >= 8 and len(g) % 4 == 0:
        table = g.reshape(-1, 4)
    else:
        raise ValueError(f"damping_gains: expected three gains or rows (payload_kg, k1, k2, k3), got shape {g.shape}")
    if not (np.all(np.isfinite(g)) and np.all(g >= 0)):
        raise ValueError(f"damping_gains: expected finite values >= 0, got {np.asarray(gains).tolist()!r}")
    if table is not None and np.any(np.diff(table[:, 0]) <= 0):
        raise ValueError(f"damping_gains: the table's payloads must increase, got {table[:, 0].tolist()}")
    return table


def scheduled_gains(table, payload_kg: float) -> tuple[float, float, float]:
    """``k_eps`` at the known payload from a table of rows ``(payload_kg, k1, k2, k3)`` (:func:`gain_table`).

    Per joint, linear in the payload between rows and constant beyond the first and last.

    Parameters
    ----------
    table : array_like, shape (M, 4)
    payload_kg : float
        The payload the layer was told, kg.

    Returns
    -------
    tuple of 3 floats

    Examples
    --------
    >>> scheduled_gains([[0.11, 0, 600, 400], [0.17, 0, 400, 400]], 0.14)
    (0.0, 500.0, 400.0)
    >>> scheduled_gains([[0.11, 0, 600, 400], [0.17, 0, 400, 400]], 0.05)[1]
    600.0
    """
    t = np.asarray(table, float).reshape(-1, 4)
    m = check_mass(payload_kg)
    return tuple(float(np.interp(m, t[:, 0], t[:, j])) for j in (1, 2, 3))


def pd_scale_of(law: str, plant: str = "soft") -> float | None:
    """Factor on the position-loop gain while ``law`` acts on ``plant`` (:data:`PD_SCALES`).

    Parameters
    ----------
    law : str
        Damping law (:data:`LAWS`).
    plant : str
        Gain set (:data:`GAIN_SETS`).

    Returns
    -------
    float or None
        The factor; ``None`` where the set lists none (``DampingConfig``'s default applies).

    Raises
    ------
    ValueError
        On an unknown law or gain set.

    Examples
    --------
    >>> pd_scale_of("proportional"), pd_scale_of("proportional", "one-way"), pd_scale_of("integral")
    (0.01, None, 0.15)
    """
    if law not in LAWS:
        raise ValueError(f"law: expected one of {LAWS}, got {law!r}")
    if plant not in GAIN_SETS:
        raise ValueError(f"plant: expected one of {tuple(GAIN_SETS)}, got {plant!r}")
    return PD_SCALES.get(plant, {}).get(law)


def hold_loop_of(plant) -> dict:
    """Keyword arguments ``t_d`` / ``t_l`` of ``design_cascade`` for the plant's holding loop (:data:`HOLD_LOOPS`).

    Parameters
    ----------
    plant : Plant or str
        An arm (its gain set, :func:`gain_set_of`) or a gain set's name.

    Returns
    -------
    dict
        ``{"t_d": seconds, "t_l": seconds}``.

    Examples
    --------
    >>> hold_loop_of("soft"), hold_loop_of("one-way")
    ({'t_d': 0.001, 't_l': 0.003}, {'t_d': 0.003, 't_l': 0.01})
    """
    name = plant if isinstance(plant, str) else gain_set_of(plant)
    if name not in HOLD_LOOPS:
        raise ValueError(f"plant: expected one of {tuple(HOLD_LOOPS)}, got {name!r}")
    t_d, t_l = HOLD_LOOPS[name]
    return {"t_d": t_d, "t_l": t_l}
