"""Identification of the strain-referred dynamics with a block-wise validation (10.4, 10.5).

Shared by the collision core (thresholds, residual) and the model-assisted
static strain cancellation of the damper: runs recorded on APRBS stimuli
(one per payload) are stacked, the model (10.2.8) is fitted by linear least
squares on alternate blocks of each run and validated (B.4 goodness of fit,
RMSE) on the blocks in between, per run.
"""
from __future__ import annotations

import numpy as np

from .strain_dynamics import StrainDynamicsModel, fit_report, fit_strain_dynamics

__all__ = ["fit_with_validation"]

_KEYS = ("theta", "d", "dd", "eps", "m")


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
        ``label -> {"fit_pct": [link 2, link 3], "rmse_um_m": [link 2, link 3]}`` on the
        validation blocks.

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
    if not runs:
        raise ValueError("runs: expected at least one recording")
    if not block_s > 0:
        raise ValueError(f"block_s: expected > 0, got {block_s}")
    for i, r in enumerate(runs):
        missing = [k for k in ("t",) + _KEYS if k not in r]
        if missing:
            raise ValueError(f"runs[{i}]: missing {missing}")
    odd = [((np.asarray(r["t"]) // block_s).astype(int) % 2).astype(bool) for r in runs]
    cat = {k: np.concatenate([np.asarray(r[k])[~b] for r, b in zip(runs, odd)]) for k in _KEYS}
    model = fit_strain_dynamics(cat["theta"], cat["d"], cat["dd"], cat["eps"], cat["m"])
    fits = {}
    for i, (r, b) in enumerate(zip(runs, odd)):
        label = r.get("label", f"{100 * r['plates']} g" if "plates" in r else str(i))
        rep = fit_report(model, *(np.asarray(r[k])[b] for k in _KEYS))
        fits[label] = {"fit_pct": np.round(rep.fit_pct, 1).tolist(),
                       "rmse_um_m": np.round(np.array(rep.rmse) * 1e6, 2).tolist()}
    return model, fits
