"""Payload-scheduled collision thresholds (section 11.1: 6 sigma of collision-free residuals).

The seed sets the detection thresholds at 6 sigma of the momentum residual on
collision-free data. On the simulated arm the residual is the unmodelled first
bending mode, whose amplitude grows with the payload (on the soft plant the
residual sigma at 400 g is about 3x that at 0 g), so one pooled pair of
thresholds is too low for the heavy payloads (false positives) and needlessly
high for the light ones. The layer knows the payload (it schedules its damping
on it), so the thresholds can follow it: per payload the larger of its own
6 sigma and the pooled 6 sigma of all payloads (the pooled floor keeps a payload
whose own run happened to be quiet from getting a threshold below what the
others show).
"""
from __future__ import annotations

import numpy as np

from .._checks import check_array
from .collision import thresholds_from_residuals

__all__ = ["payload_thresholds"]


def payload_thresholds(residuals_per_payload, *, n_sigma: float = 6.0):
    """Pooled and per-payload thresholds from collision-free residuals, one run per payload.

    Parameters
    ----------
    residuals_per_payload : sequence of array_like, each shape (N_p, 2)
        Collision-free residuals (link-2, link-3 root), m/m, one array per payload in the
        payload order the thresholds are used in.
    n_sigma : float
        Multiple of the standard deviation.

    Returns
    -------
    pooled : ndarray, shape (2,)
        ``n_sigma`` times the standard deviation of all residuals together, m/m.
    per_payload : ndarray, shape (P, 2)
        Per payload ``max(own n_sigma std, pooled)``, m/m.

    Raises
    ------
    ValueError
        Without residuals, or if an array is not (N, 2).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> runs = [rng.normal(0.0, s, size=(20000, 2)) for s in (1e-6, 3e-6)]
    >>> pooled, per = payload_thresholds(runs)
    >>> np.round(pooled * 1e6, 1).tolist(), np.round(per * 1e6, 1).tolist()
    ([13.4, 13.4], [[13.4, 13.4], [18.0, 17.9]])
    """
    runs = [check_array(r, "residuals", (None, 2)) for r in residuals_per_payload]
    if not runs:
        raise ValueError("residuals_per_payload: expected at least one run")
    pooled = thresholds_from_residuals(np.concatenate(runs), n_sigma=n_sigma)
    own = np.array([thresholds_from_residuals(r, n_sigma=n_sigma) for r in runs])
    return pooled, np.maximum(own, pooled)
