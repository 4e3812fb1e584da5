"""Identification of the damped-dynamics models with a block-wise validation (10.4, 10.5).

Shared by the collision core (thresholds, residual) and the model-assisted
static strain cancellation of the damper: runs recorded on APRBS stimuli
(one per payload) are stacked, the strain model (10.2.8) is fitted by linear
least squares on alternate blocks of each run and validated (B.4 goodness of
fit, RMSE) on the blocks in between, per run. The motor-current model (10.1.2,
:mod:`tudorvision.joint.current_model`) is identified the same way from the
runs' winding currents (:func:`fit_current_with_validation`). Both report the
fit on the identification blocks too, the two halves of the seed's table 10.1.
"""
from __future__ import annotations

import numpy as np

from .current_model import MotorCurrentModel, current_fit_report, fit_motor_current
from .strain_dynamics import StrainDynamicsModel, fit_report, fit_strain_dynamics

__all__ = ["fit_with_validation", "fit_current_with_validation"]

_KEYS = ("theta", "d", "dd", "eps", "m")
_CURRENT_KEYS = ("theta", "d", "dd", "i_M", "m")


def _blockwise(runs, block_s, keys, fit, report, scale, unit, digits):
    """Fit on the even blocks of all runs, report per run on the odd (validation) and even ones."""
    if not runs:
        raise ValueError("runs: expected at least one recording")
    if not block_s > 0:
        raise ValueError(f"block_s: expected > 0, got {block_s}")
    for i, r in enumerate(runs):
        missing = [k for k in ("t",) + keys if k not in r]
        if missing:
            raise ValueError(f"runs[{i}]: missing {missing}")
    odd = [((np.asarray(r["t"]) // block_s).astype(int) % 2).astype(bool) for r in runs]
    cat = {k: np.concatenate([np.asarray(r[k])[~b] for r, b in zip(runs, odd)]) for k in keys}
    model = fit(*(cat[k] for k in keys))
    fits = {}
    for i, (r, b) in enumerate(zip(runs, odd)):
        label = r.get("label", f"{100 * r['plates']} g" if "plates" in r else str(i))
        val = report(model, *(np.asarray(r[k])[b] for k in keys))
        ide = report(model, *(np.asarray(r[k])[~b] for k in keys))
        fits[label] = {"fit_pct": np.round(val.fit_pct, 1).tolist(),
                       f"rmse_{unit}": np.round(np.array(val.rmse) * scale, digits).tolist(),
                       f"sigma_{unit}": np.round(np.array(val.sigma) * scale, digits).tolist(),
                       "fit_pct_id": np.round(ide.fit_pct, 1).tolist(),
                       f"rmse_{unit}_id": np.round(np.array(ide.rmse) * scale, digits).tolist()}
    return model, fits


def fit_with_validation(runs, *, block_s: float = 5.0) -> tuple[StrainDynamicsModel, dict]:
    """Fit on the even ``block_s`` blocks of every run, validate on the odd ones.

    Parameters
    ----------
    runs : sequence of dict
        One per recording, with ``t`` (N,) s, ``theta``, ``d``, ``dd`` (N, 3) rad, rad/s,
        rad/s^2, ``eps`` (N, 2) root strains m/m, ``m`` (N,) payload kg and an optional
        ``label`` (default ``"<plates * 100> g"`` from ``plates``, else the run index).
    block_s : float
        Block length, seconds.

    Returns
    -------
    model : StrainDynamicsModel
    fits : dict
        ``label -> {"fit_pct": [link 2, link 3], "rmse_um_m": [link 2, link 3], "sigma_um_m"}`` on
        the validation blocks, ``"fit_pct_id"``, ``"rmse_um_m_id"`` on the identification blocks.

    Raises
    ------
    ValueError
        Without runs, on a missing key or a non-positive ``block_s``.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(2000) * 0.01
    >>> th = np.c_[np.zeros(2000), rng.uniform(0.2, 2.8, (2000, 2))]
    >>> chi = rng.normal(0, 1e-4, (2, 32))
    >>> run = {"t": t, "theta": th, "d": 0 * th, "dd": 0 * th, "m": np.full(2000, 0.3)}
    >>> run["eps"] = StrainDynamicsModel(chi=chi).predict(th, 0 * th, 0 * th, 0.3)
    >>> model, fits = fit_with_validation([dict(run, plates=3)])
    >>> fits["300 g"]["fit_pct"][0] > 99.9
    True
    """
    return _blockwise(runs, block_s, _KEYS, fit_strain_dynamics, fit_report, 1e6, "um_m", 2)


def fit_current_with_validation(runs, *, block_s: float = 5.0) -> tuple[MotorCurrentModel, dict]:
    """Motor-current model (10.1.2): fit on the even ``block_s`` blocks of every run, validate on the odd ones.

    Parameters
    ----------
    runs : sequence of dict
        As for :func:`fit_with_validation`, with ``i_M`` (N, 2) winding currents of
        joints 2 and 3 (A) instead of ``eps``.
    block_s : float
        Block length, seconds.

    Returns
    -------
    model : MotorCurrentModel
    fits : dict
        ``label -> {"fit_pct": [joint 2, joint 3], "rmse_A", "sigma_A"}`` on the validation
        blocks, ``"fit_pct_id"``, ``"rmse_A_id"`` on the identification blocks.

    Raises
    ------
    ValueError
        Without runs, on a missing key or a non-positive ``block_s``.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(2000) * 0.01
    >>> th = np.c_[np.zeros(2000), rng.uniform(0.2, 2.8, (2000, 2))]
    >>> d = rng.normal(0, 1, (2000, 3))
    >>> true = MotorCurrentModel(chi=rng.normal(0, 0.1, (2, 35)))
    >>> run = {"t": t, "theta": th, "d": d, "dd": 0 * th, "m": np.full(2000, 0.3)}
    >>> run["i_M"] = true.predict(th, d, 0 * th, 0.3)
    >>> model, fits = fit_current_with_validation([dict(run, plates=3)])
    >>> fits["300 g"]["fit_pct"][1] > 99.9
    True
    """
    return _blockwise(runs, block_s, _CURRENT_KEYS, fit_motor_current, current_fit_report, 1.0, "A", 4)
