"""Data-based kinematics of the elastic arm under load (section 9.2).

The elastic deflections act in the vertical arm plane and do not depend on
theta1, so every model works on planar coordinates: the signed reach ``r``
along ``[cos t1, sin t1, 0]`` and the height ``z`` of the (deflected) end
effector, base frame, metres. The joint angles enter through the rigid-arm
regressors ``(cos t2, sin t2, cos(t2+t3), sin(t2+t3))``
(:func:`rigid_regressors`), as in the seed.

Models (all linear in their parameters, fitted by least squares; the seed used
small MLPs trained with Levenberg-Marquardt on the same inputs):

* :class:`ForwardModel`: ``(r, z)`` from the regressors plus the settled
  strains (and their products with the regressors: a strain scales a
  deflection whose direction depends on the link orientation);
* :class:`StrainModel` / payload estimator: settled strains as
  ``a(theta) + m b(theta)`` with ``a, b`` linear in ``[1, R, R_i R_j]``
  (statics: gauge moments are linear in the payload ``m``); the payload is the
  weighted least-squares ``m`` given measured strains (TUDOR as a weighing
  machine; ill-conditioned when the links align with gravity, as in the seed);
* :class:`DeflectionModel`: the plant-free forward model used for setpoints,
  ``p(theta, m) = p_rigid(theta) + D(theta) [1, m]`` (no strain needed before
  the move);
* :class:`InverseKinematics`: separate inverse solutions for elbow up
  (theta3 > 0) and elbow down, each a Gauss-Newton solve of the learned
  forward model seeded by the rigid solution of that branch; solutions
  outside the joint ranges are dropped and the one nearest the current
  configuration wins.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import check_array

__all__ = ["rigid_regressors", "ForwardModel", "StrainModel", "DeflectionModel", "InverseKinematics",
           "KinematicsModels", "fit_kinematics"]


def rigid_regressors(theta23) -> np.ndarray:
    """``(cos t2, sin t2, cos(t2+t3), sin(t2+t3))`` for joint angles ``(t2, t3)``.

    Parameters
    ----------
    theta23 : array_like, shape (N, 2)
        Joint angles 2 and 3, radians.

    Returns
    -------
    ndarray, shape (N, 4)

    Examples
    --------
    >>> np.round(rigid_regressors([[0.0, np.pi / 2]]), 6).tolist()
    [[1.0, 0.0, 0.0, 1.0]]
    """
    th = check_array(np.atleast_2d(np.asarray(theta23, float)), "theta23", (None, 2))
    t2, t23 = th[:, 0], th[:, 0] + th[:, 1]
    return np.stack([np.cos(t2), np.sin(t2), np.cos(t23), np.sin(t23)], axis=1)


def _basis(theta23) -> np.ndarray:
    """``[1, R, products R_i R_j (i <= j)]``, shape (N, 15)."""
    R = rigid_regressors(theta23)
    iu = np.triu_indices(4)
    return np.hstack([np.ones((len(R), 1)), R, (R[:, :, None] * R[:, None, :])[:, iu[0], iu[1]]])


def _lstsq(A, Y, ridge=1e-10):
    s = np.sqrt((A ** 2).mean(axis=0)) + 1e-12
    As = A / s
    W = np.linalg.solve(As.T @ As + ridge * len(A) * np.eye(A.shape[1]), As.T @ Y)
    return W / s[:, None]


@dataclass(frozen=True, kw_only=True)
class ForwardModel:
    """``(r, z)`` of the deflected end effector from joint angles and settled strains.

    ``W`` (F, 2): weights on ``[1, R, eps, R (x) eps]`` with ``R`` the 4 rigid
    regressors and ``eps`` the strains scaled by ``strain_scale``.
    """

    W: np.ndarray
    strain_scale: float = 1e4

    @staticmethod
    def features(theta23, strains, strain_scale: float = 1e4) -> np.ndarray:
        B = _basis(theta23)
        e = check_array(np.atleast_2d(np.asarray(strains, float)), "strains", (len(B), None)) * strain_scale
        cross = (B[:, 1:, None] * e[:, None, :]).reshape(len(B), -1)
        return np.hstack([B, e, cross])

    @classmethod
    def fit(cls, theta23, strains, p_rz, *, strain_scale: float = 1e4) -> "ForwardModel":
        A = cls.features(theta23, strains, strain_scale)
        Y = check_array(p_rz, "p_rz", (len(A), 2))
        return cls(W=_lstsq(A, Y), strain_scale=strain_scale)

    def __call__(self, theta23, strains) -> np.ndarray:
        """Predicted ``(r, z)``, shape (N, 2), metres."""
        return self.features(theta23, strains, self.strain_scale) @ self.W


@dataclass(frozen=True, kw_only=True)
class StrainModel:
    """Settled strains ``a(theta) + m b(theta)``; ``A``, ``B`` (15, C) on ``[1, R, R_i R_j]``; payload estimator."""

    A: np.ndarray
    B: np.ndarray

    @classmethod
    def fit(cls, theta23, payload_kg, strains) -> "StrainModel":
        Bs = _basis(theta23)
        m = np.asarray(payload_kg, float).ravel()[:, None]
        E = np.atleast_2d(np.asarray(strains, float))
        W = _lstsq(np.hstack([Bs, Bs * m]), E)
        k = Bs.shape[1]
        return cls(A=W[:k], B=W[k:])

    def predict(self, theta23, payload_kg) -> np.ndarray:
        """Strains, shape (N, C)."""
        Bs = _basis(theta23)
        m = np.asarray(payload_kg, float).ravel()[:, None]
        return Bs @ self.A + m * (Bs @ self.B)

    def payload(self, theta23, strains) -> np.ndarray:
        """Least-squares payload (kg) per sample from the measured strains, shape (N,)."""
        Bs = _basis(theta23)
        E = np.atleast_2d(np.asarray(strains, float))
        a, b = Bs @ self.A, Bs @ self.B
        return np.sum(b * (E - a), axis=1) / np.maximum(np.sum(b * b, axis=1), 1e-30)


@dataclass(frozen=True, kw_only=True)
class DeflectionModel:
    """Plant-free forward kinematics under load: ``p_rigid(theta) + (D0 + m D1)^T [1, R, R_i R_j]``.

    ``D`` (30, 2) stacks ``D0`` and ``D1`` on the basis ``[1, R, R_i R_j]`` (15 terms).
    """

    D: np.ndarray
    params: object = None

    @classmethod
    def fit(cls, theta23, payload_kg, p_rz, params=None) -> "DeflectionModel":
        from ..robot import planar_from_joints

        th = check_array(np.atleast_2d(np.asarray(theta23, float)), "theta23", (None, 2))
        r0, z0 = planar_from_joints(th[:, 0], th[:, 1], params)
        Y = check_array(p_rz, "p_rz", (len(th), 2)) - np.stack([r0, z0], axis=1)
        Bs = _basis(th)
        m = np.asarray(payload_kg, float).ravel()[:, None]
        return cls(D=_lstsq(np.hstack([Bs, Bs * m]), Y), params=params)

    def __call__(self, theta23, payload_kg) -> np.ndarray:
        """Predicted ``(r, z)``, shape (N, 2), metres."""
        from ..robot import planar_from_joints

        th = np.atleast_2d(np.asarray(theta23, float))
        r0, z0 = planar_from_joints(th[:, 0], th[:, 1], self.params)
        Bs = _basis(th)
        m = np.broadcast_to(np.asarray(payload_kg, float).ravel(), (len(th),))[:, None]
        return np.stack([r0, z0], axis=1) + np.hstack([Bs, Bs * m]) @ self.D


class InverseKinematics:
    """Compensated inverse kinematics: the joint angles that put the *deflected* end effector on a target.

    Parameters
    ----------
    model : DeflectionModel or callable
        ``model(theta23 (N, 2), payload_kg) -> (N, 2)`` planar position.
    params : RobotParams, optional
    margin_rad : float
        Joint-range margin for the validity check.
    """

    def __init__(self, model, params=None, *, margin_rad: float = 0.0, tol_m: float = 1e-5, max_iter: int = 20):
        self.model = model
        self.params = params
        self.margin_rad = float(margin_rad)
        self.tol_m = float(tol_m)
        self.max_iter = int(max_iter)

    def _solve_branch(self, target_rz, seed23, payload_kg):
        th = np.array(seed23, float)
        for _ in range(self.max_iter):
            f = self.model(th[None], payload_kg)[0]
            e = target_rz - f
            if np.linalg.norm(e) < self.tol_m:
                return th, True
            J = np.zeros((2, 2))
            for j in range(2):
                d = np.zeros(2); d[j] = 1e-6
                J[:, j] = (self.model((th + d)[None], payload_kg)[0] - f) / 1e-6
            try:
                step = np.linalg.solve(J, e)
            except np.linalg.LinAlgError:
                return th, False
            n = np.linalg.norm(step)
            if n > 0.3:
                step *= 0.3 / n
            th = th + step
        return th, np.linalg.norm(target_rz - self.model(th[None], payload_kg)[0]) < 1e-3

    def _rigid_seeds(self, r: float, z: float, theta1: float) -> dict:
        """Rigid IK of the planar target ``(r, z)`` (m) in the plane of ``theta1`` per elbow, ranges ignored.

        ``{"up" | "down": (theta2, theta3)}`` (rad): the seeds of the compensated solves.
        """
        from ..robot import ik_all

        p_plane = np.array([r * np.cos(theta1), r * np.sin(theta1), z])
        out = {}
        for s in ik_all(p_plane, self.params, respect_limits=False):
            if abs((s[0] - theta1 + np.pi) % (2 * np.pi) - np.pi) <= 1e-6:
                out["up" if s[2] > 0 else "down"] = s[1:]
        return out

    def solutions(self, p_base, theta1: float, payload_kg: float) -> dict:
        """Per elbow (``"up"``: theta3 > 0, ``"down"``: theta3 <= 0) the valid compensated solution.

        Returns
        -------
        dict of str to ndarray, shape (3,)
            Only valid branches (converged, same elbow sign, within the ranges).
        """
        from ..robot import within_limits
        from .intercept import planar_coordinates

        r, z = planar_coordinates(p_base, theta1)
        target = np.array([r, z])
        out = {}
        for elbow, seed23 in self._rigid_seeds(r, z, theta1).items():
            th23, ok = self._solve_branch(target, seed23, payload_kg)
            if not ok or (th23[1] > 0) != (elbow == "up"):
                continue
            th = np.array([theta1, *th23])
            if not within_limits(th, self.params, margin_rad=self.margin_rad):
                continue
            out[elbow] = th
        return out

    def nearest_on_branch(self, p_base, theta1: float, payload_kg: float, *, elbow: str, lower_rad,
                          upper_rad) -> tuple[np.ndarray, float]:
        """Joint angles on one elbow branch, within bounds, whose deflected end effector comes nearest ``p_base``.

        Where the branch reaches the target inside the bounds this is its solution; where it does not
        (a crossing low on the right needs joint 2 below its range on the elbow-up branch), it is the
        bounded least-squares point of the learnt forward model: the arm as near as it can get
        without swinging joint 3 through the other branch.

        Parameters
        ----------
        p_base : array_like, shape (3,)
            Target, metres, base frame.
        theta1 : float
            Azimuth of the working plane, rad.
        payload_kg : float
            Payload on top of the mount, kg.
        elbow : {"up", "down"}
            The branch (``"up"``: theta3 > 0).
        lower_rad, upper_rad : array_like, shape (3,)
            Joint bounds, rad (e.g. the ranges less the setpoint margins); theta1's are ignored.

        Returns
        -------
        theta : ndarray, shape (3,)
            ``[theta1, theta2, theta3]``, rad.
        distance_m : float
            Distance of the predicted end effector from the target in the working plane, m.

        Raises
        ------
        ValueError
            On an unknown ``elbow`` or empty bounds on the branch.

        Examples
        --------
        >>> from tudorvision.robot import fk_ee
        >>> ikm = InverseKinematics(DeflectionModel(D=np.zeros((30, 2))))
        >>> lo, hi = np.deg2rad([-170, -4, -99]), np.deg2rad([180, 182, 99])
        >>> th, d = ikm.nearest_on_branch(fk_ee([0.0, 0.9, 0.5]), 0.0, 0.0, elbow="up", lower_rad=lo, upper_rad=hi)
        >>> np.round(th, 6).tolist(), round(d, 9)
        ([0.0, 0.9, 0.5], 0.0)
        """
        from scipy.optimize import least_squares

        from .intercept import planar_coordinates

        if elbow not in ("up", "down"):
            raise ValueError(f"elbow: expected 'up' or 'down', got {elbow!r}")
        lo = np.asarray(lower_rad, float)[1:].copy()
        hi = np.asarray(upper_rad, float)[1:].copy()
        eps = 1e-3                     # the branch's own side of the stretched arm
        if elbow == "up":
            lo[1] = max(lo[1], eps)
        else:
            hi[1] = min(hi[1], -eps)
        if not np.all(lo < hi):
            raise ValueError(f"lower_rad, upper_rad: no room on the {elbow} branch between "
                             f"{np.round(lo, 4).tolist()} and {np.round(hi, 4).tolist()}")
        r, z = planar_coordinates(p_base, theta1)
        target = np.array([r, z])
        seed23 = self._rigid_seeds(r, z, theta1).get(elbow)
        x0 = np.clip(seed23 if seed23 is not None else (lo + hi) / 2, lo, hi)

        def residual(th23):
            return self.model(th23[None], payload_kg)[0] - target

        sol = least_squares(residual, x0, bounds=(lo, hi), xtol=1e-10, ftol=1e-12, gtol=1e-12)
        return np.array([theta1, *sol.x]), float(np.linalg.norm(residual(sol.x)))

    def __call__(self, p_base, theta1: float, payload_kg: float, *, near=None, elbow: str | None = None):
        """One solution: valid branches, then the one nearest ``near`` (rad, (3,)).

        Raises
        ------
        ValueError
            If no valid solution exists.

        Examples
        --------
        >>> from tudorvision.robot import fk_ee
        >>> ikm = InverseKinematics(DeflectionModel(D=np.zeros((30, 2))))    # no deflection: rigid IK
        >>> np.round(ikm(fk_ee([0.0, 0.9, 0.5]), 0.0, 0.1, elbow="up"), 6).tolist()
        [0.0, 0.9, 0.5]
        """
        sols = self.solutions(p_base, theta1, payload_kg)
        if elbow is not None:
            sols = {k: v for k, v in sols.items() if k == elbow}
        if not sols:
            raise ValueError(f"p_base: {np.round(np.asarray(p_base, float), 4).tolist()} is not reachable"
                             f" (payload {payload_kg:.3f} kg, elbow={elbow})")
        cands = list(sols.values())
        if near is None:
            return cands[0]
        ref = check_array(near, "near", (3,))
        return min(cands, key=lambda th: float(np.linalg.norm(th - ref)))


@dataclass(frozen=True, kw_only=True)
class KinematicsModels:
    """The fitted models of section 9.2 and their test errors (metres, kg)."""

    forward: ForwardModel
    strain: StrainModel
    deflection: DeflectionModel
    report: dict


def fit_kinematics(data: dict, *, test_payloads_kg=None, rng=None, params=None) -> KinematicsModels:
    """Fit forward, payload and deflection models on collected settled poses.

    Parameters
    ----------
    data : dict
        ``theta`` (N, 3) rad, ``strains`` (N, 4), ``payload_kg`` (N,), ``p_meas_base`` (N, 3)
        measured end effector (base frame; NaN rows, or rows with ``valid`` False, were not
        measured and only train the strain model), optionally ``p_true_base`` (N, 3) for evaluation.
    test_payloads_kg : sequence of float, optional
        Payloads held out entirely (the seed's unseen payload); otherwise a
        random 70/30 split.

    Returns
    -------
    KinematicsModels
        ``report``: forward RMSE (r, z) on the test set, payload RMSE, deflection-model RMSE.
    """
    th = check_array(data["theta"], "theta", (None, 3))
    eps = check_array(data["strains"], "strains", (len(th), None))
    m = np.asarray(data["payload_kg"], float).ravel()
    p = np.asarray(data["p_meas_base"], dtype=np.float64)        # NaN rows: not measured
    if p.shape != (len(th), 3):
        raise ValueError(f"p_meas_base: expected shape ({len(th)}, 3), got {p.shape}")
    rz = np.stack([p[:, 0] * np.cos(th[:, 0]) + p[:, 1] * np.sin(th[:, 0]), p[:, 2]], axis=1)
    if test_payloads_kg is not None:
        test = np.isin(np.round(m, 6), np.round(np.asarray(test_payloads_kg, float), 6))
    else:
        rng = np.random.default_rng(0) if rng is None else rng
        test = rng.random(len(th)) < 0.3
    train = ~test
    # poses the measurement missed (a sphere hidden from a camera) train the strain model only
    ok = np.all(np.isfinite(p), axis=1) & np.asarray(data.get("valid", np.ones(len(th), bool)), bool)
    t23 = th[:, 1:]
    fwd = ForwardModel.fit(t23[train & ok], eps[train & ok], rz[train & ok])
    sm = StrainModel.fit(t23[train], m[train], eps[train])
    dm = DeflectionModel.fit(t23[train & ok], m[train & ok], rz[train & ok], params)
    truth = np.where(ok[:, None], rz, np.nan)
    if "p_true_base" in data:
        pt = np.asarray(data["p_true_base"], float)
        truth = np.stack([pt[:, 0] * np.cos(th[:, 0]) + pt[:, 1] * np.sin(th[:, 0]), pt[:, 2]], axis=1)
    rmse = lambda e: np.sqrt(np.nanmean(e ** 2, axis=0)).tolist()
    rep = {"n_train": int(train.sum()), "n_test": int(test.sum()), "n_unmeasured": int((~ok).sum()),
           "forward_rmse_m": rmse(fwd(t23[test], eps[test]) - truth[test]) if test.any() else None,
           "deflection_model_rmse_m": rmse(dm(t23[test], m[test]) - truth[test]) if test.any() else None,
           "payload_rmse_kg": float(np.sqrt(np.mean((sm.payload(t23[test], eps[test]) - m[test]) ** 2)))
           if test.any() else None}
    return KinematicsModels(forward=fwd, strain=sm, deflection=dm, report=rep)
