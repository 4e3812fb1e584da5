"""The IIR variant of the static strain cancellation (section 2.2, equation 2.2.3, figures 2.3 and 2.4).

An exponentially weighted moving average ``G_IIR = alpha / (1 - (1 - alpha) z^-1)``
applied twice with trend correction (double exponential smoothing, "second order
smoothing" of figure 2.2): ``mu_hat = 2 s1 - s2`` with ``s1 = G eps`` and
``s2 = G s1``, so ``eps_tilde = (1 - G)^2 eps`` has a double zero at DC like the FIR
variant. The seed compares it with the FIR filter at 100 Hz (``alpha = 0.02``
against ``N = 50``, figure 2.4) and keeps the FIR one; the damper uses this one
when :class:`tudorvision.joint.damping.DampingConfig` has ``iir_alpha``.
"""
from __future__ import annotations

import numpy as np

from .._checks import check_array

__all__ = ["ExponentialStrainFilter"]


class ExponentialStrainFilter:
    """Running static strain estimate by double exponential smoothing (2.2.3).

    Parameters
    ----------
    eps0 : array_like, shape (C,)
        Initial strain, m/m (a static start).
    alpha : float
        Discount factor ``alpha_IIR`` in (0, 1] (the seed: 0.02 at 100 Hz).
    decimation : int
        New input every ``decimation`` calls, estimate held in between (20 at 2 kHz = 100 Hz).

    Examples
    --------
    >>> f = ExponentialStrainFilter([1e-4], alpha=0.02)
    >>> mu, et = f.step([1e-4])
    >>> float(et[0])
    0.0
    """

    def __init__(self, eps0, *, alpha: float = 0.02, decimation: int = 1):
        e0 = check_array(np.atleast_1d(eps0), "eps0", (None,))
        if not 0.0 < float(alpha) <= 1.0 or int(decimation) < 1:
            raise ValueError(f"alpha, decimation: expected 0 < alpha <= 1 and >= 1, got {alpha}, {decimation}")
        self.alpha = float(alpha)
        self.decimation = int(decimation)
        self.channels = e0.size
        self.reset(e0)

    def reset(self, eps0) -> None:
        """Start both smoothers at ``eps0`` (static state)."""
        e0 = [float(x) for x in np.atleast_1d(eps0)]
        self._s1, self._s2 = list(e0), list(e0)
        self._count = 0
        self.mu = list(e0)

    def step(self, eps):
        """Take one strain sample; return ``(mu_hat, eps_tilde)`` as lists of C floats."""
        if self._count % self.decimation == 0:
            a = self.alpha
            for c in range(self.channels):
                s1 = self._s1[c] + a * (float(eps[c]) - self._s1[c])
                s2 = self._s2[c] + a * (s1 - self._s2[c])
                self._s1[c], self._s2[c] = s1, s2
                self.mu[c] = 2.0 * s1 - s2
        self._count += 1
        mu = list(self.mu)
        return mu, [float(eps[c]) - mu[c] for c in range(self.channels)]
