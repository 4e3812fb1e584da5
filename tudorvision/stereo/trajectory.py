"""End-effector trajectory: finite-difference velocity and acceleration, CSV file, plot.

Velocity and acceleration come from finite differences of the triangulated
positions, as in figure 2.7 (g), (h) of the seed (50 Hz camera rate). For
sample k with neighbours k-1 and k+1 (spacings ``h0 = t_k - t_{k-1}``,
``h1 = t_{k+1} - t_k``, which may differ after a dropped frame)::

    v_k = (p_{k+1} - p_{k-1}) / (h0 + h1)
    a_k = 2 * ((p_{k+1} - p_k) / h1 - (p_k - p_{k-1}) / h0) / (h0 + h1)

Both are NaN at the ends, at samples whose own or a neighbour's position is
missing (NaN), and where a spacing exceeds ``max_dt_s``.

CSV file
--------
``#`` comment lines naming the format, the frame and the units, then one
header line and one row per camera frame::

    # tudorvision trajectory v1
    # frame: base (robot base frame, z up)
    # units: t s; x y z m; vx vy vz m/s; ax ay az m/s^2; valid 0/1
    t,x,y,z,vx,vy,vz,ax,ay,az,valid

Frames without a valid 3D position are written with ``valid = 0`` and
``nan`` values so a partial trajectory keeps its time base.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._checks import TudorVisionError, check_array, check_points
from ..io.atomic import write_text_atomic

__all__ = ["Trajectory", "finite_differences", "trajectory_from_points", "write_trajectory_csv",
           "read_trajectory_csv", "plot_trajectory", "FRAME_DESCRIPTIONS"]

COLUMNS = ("t", "x", "y", "z", "vx", "vy", "vz", "ax", "ay", "az", "valid")
FORMAT_LINE = "# tudorvision trajectory v1"
UNITS_LINE = "# units: t s; x y z m; vx vy vz m/s; ax ay az m/s^2; valid 0/1"

FRAME_DESCRIPTIONS = {
    "left": "left camera optical frame, x right, y down, z forward",
    "base": "robot base frame, z up",
}


@dataclass(frozen=True, kw_only=True)
class Trajectory:
    """A sampled 3D trajectory with its derivatives (SI units).

    Attributes
    ----------
    t : ndarray, shape (N,)
        Timestamps, seconds, increasing.
    p : ndarray, shape (N, 3)
        Positions in metres, frame ``frame``; NaN rows where not measured.
    v : ndarray, shape (N, 3)
        Velocity, m/s (NaN where it cannot be differenced).
    a : ndarray, shape (N, 3)
        Acceleration, m/s^2.
    valid : ndarray of bool, shape (N,)
        True where the position was measured.
    frame : str
        Frame name (``"left"``, ``"base"`` or another name).
    """

    t: np.ndarray
    p: np.ndarray
    v: np.ndarray
    a: np.ndarray
    valid: np.ndarray
    frame: str

    @property
    def speed(self) -> np.ndarray:
        """|v| in m/s, shape (N,)."""
        return np.linalg.norm(self.v, axis=1)

    @property
    def accel_norm(self) -> np.ndarray:
        """|a| in m/s^2, shape (N,)."""
        return np.linalg.norm(self.a, axis=1)


def _times(t, name="t") -> np.ndarray:
    t = check_array(t, name, (None,))
    if len(t) > 1 and np.any(np.diff(t) <= 0):
        k = int(np.flatnonzero(np.diff(t) <= 0)[0])
        raise ValueError(f"{name}: timestamps must increase (t[{k + 1}] = {t[k + 1]} "
                         f"after t[{k}] = {t[k]})")
    return t


def finite_differences(t, p, *, max_dt_s: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Central-difference velocity and acceleration of a sampled trajectory.

    Parameters
    ----------
    t : array_like, shape (N,)
        Timestamps in seconds, strictly increasing (spacing may vary).
    p : array_like, shape (N, D)
        Positions (metres), NaN rows for missing samples.
    max_dt_s : float, optional
        Spacings larger than this (a long dropout) give NaN instead of a
        difference across the gap.

    Returns
    -------
    v, a : ndarray, shape (N, D)
        Velocity and acceleration; NaN at both ends and next to missing samples.

    Raises
    ------
    ValueError
        If timestamps do not increase or shapes do not match.

    Examples
    --------
    >>> t = np.arange(5) * 0.02
    >>> v, a = finite_differences(t, np.column_stack([t ** 2, t, 0 * t]))
    >>> np.round(v[:, 0], 6).tolist()
    [nan, 0.04, 0.08, 0.12, nan]
    >>> np.round(a[1:4], 6).tolist()
    [[2.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 0.0, 0.0]]
    """
    t = _times(t)
    p = np.asarray(p, dtype=np.float64)
    if p.ndim != 2 or len(p) != len(t):
        raise ValueError(f"p: expected shape ({len(t)}, D) like t, got {p.shape}")
    v = np.full_like(p, np.nan)
    a = np.full_like(p, np.nan)
    if len(t) < 3:
        return v, a
    h0 = (t[1:-1] - t[:-2])[:, None]
    h1 = (t[2:] - t[1:-1])[:, None]
    v[1:-1] = (p[2:] - p[:-2]) / (h0 + h1)
    a[1:-1] = 2.0 * ((p[2:] - p[1:-1]) / h1 - (p[1:-1] - p[:-2]) / h0) / (h0 + h1)
    if max_dt_s is not None:
        gap = (np.maximum(h0, h1)[:, 0] > max_dt_s)
        v[1:-1][gap] = np.nan
        a[1:-1][gap] = np.nan
    # a NaN neighbour already propagates; a sample without its own position gets
    # no derivative either, and partially NaN rows become whole NaN rows
    missing = ~np.all(np.isfinite(p), axis=1)
    v[missing] = np.nan
    a[missing] = np.nan
    bad = ~np.all(np.isfinite(v), axis=1)
    v[bad] = np.nan
    bad = ~np.all(np.isfinite(a), axis=1)
    a[bad] = np.nan
    return v, a


def trajectory_from_points(t, p, *, frame: str = "left", max_dt_s: float | None = None) -> Trajectory:
    """Build a :class:`Trajectory` from timestamps and positions.

    Parameters
    ----------
    t : array_like, shape (N,)
        Seconds, increasing.
    p : array_like, shape (N, 3)
        End-effector positions in metres (NaN rows where missing).
    frame : str
        Frame of ``p``: ``"left"``, ``"base"`` or another name.
    max_dt_s : float, optional
        See :func:`finite_differences`.

    Returns
    -------
    Trajectory
        Positions with invalid rows set wholly to NaN, and the central
        difference velocity (m/s) and acceleration (m/s^2), same frame.

    Raises
    ------
    ValueError
        If ``t`` does not increase, ``p`` is not shape (N, 3) like ``t``, or
        ``frame`` is empty or not a single line without commas.

    Examples
    --------
    >>> tr = trajectory_from_points([0.0, 0.02, 0.04], [[0, 0, 1], [0.1, 0, 1], [np.nan] * 3])
    >>> tr.valid.tolist(), bool(np.isnan(tr.v).all())
    ([True, True, False], True)
    """
    t = _times(t)
    p = check_points(p, "p", finite=False)
    if len(p) != len(t):
        raise ValueError(f"p: expected {len(t)} rows like t, got {len(p)}")
    if not isinstance(frame, str) or not frame or any(c in frame for c in "\n\r,"):
        raise ValueError(f"frame: expected a single-line name, got {frame!r}")
    valid = np.all(np.isfinite(p), axis=1)
    p = p.copy()
    p[~valid] = np.nan
    v, a = finite_differences(t, p, max_dt_s=max_dt_s)
    return Trajectory(t=t, p=p, v=v, a=a, valid=valid, frame=frame)


def write_trajectory_csv(path, traj: Trajectory, *, comment: str | None = None) -> Path:
    """Write a trajectory as CSV (see the module docstring for the layout).

    Parameters
    ----------
    path : str or Path
        Output file; parent directories are created. Written atomically, so
        a failed write leaves a previous file intact.
    traj : Trajectory
        Trajectory to write; times in seconds, positions in metres in
        ``traj.frame``, whose name (and description, for ``"left"`` and
        ``"base"``) goes into the ``# frame:`` comment.
    comment : str, optional
        Extra comment lines (e.g. the command or the calibration file).

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    desc = FRAME_DESCRIPTIONS.get(traj.frame)
    lines = [FORMAT_LINE, f"# frame: {traj.frame}" + (f" ({desc})" if desc else ""), UNITS_LINE]
    if comment:
        lines += [f"# {c}" for c in comment.splitlines()]
    lines.append(",".join(COLUMNS))
    data = np.column_stack([traj.t, traj.p, traj.v, traj.a])
    for row, ok in zip(data, traj.valid):
        vals = ["nan" if not np.isfinite(x) else repr(float(x)) for x in row]
        lines.append(",".join(vals + ["1" if ok else "0"]))
    write_text_atomic(path, "\n".join(lines) + "\n")   # a full disk leaves the previous file intact
    return path


def read_trajectory_csv(path) -> Trajectory:
    """Read a trajectory CSV written by :func:`write_trajectory_csv`.

    Positions of rows with ``valid = 0`` are NaN. The frame comes from the
    ``# frame:`` comment (first word).

    Parameters
    ----------
    path : str or Path
        Trajectory CSV file.

    Returns
    -------
    Trajectory
        Times in seconds, positions (metres), velocities (m/s) and
        accelerations (m/s^2) as stored; ``frame`` is ``"unknown"`` when the
        file has no ``# frame:`` comment.

    Raises
    ------
    TudorVisionError
        If the file is missing or malformed; the message names the file and line.

    Examples
    --------
    >>> import tempfile, os
    >>> tr = trajectory_from_points([0.0, 0.02, 0.04], [[0, 0, 1], [0.1, 0, 1], [0.2, 0, 1]], frame="base")
    >>> with tempfile.TemporaryDirectory() as d:
    ...     back = read_trajectory_csv(write_trajectory_csv(os.path.join(d, "t.csv"), tr))
    >>> back.frame, bool(np.allclose(back.v[1], [5.0, 0, 0]))
    ('base', True)
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise TudorVisionError(f"{path}: trajectory file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise TudorVisionError(f"{path}: cannot read ({exc})") from None
    frame = None
    header_seen = False
    rows = []
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            body = line[1:].strip()
            if body.lower().startswith("frame:"):
                frame = body.split(":", 1)[1].strip().split(" ")[0] or None
            continue
        if not header_seen:
            cols = tuple(c.strip() for c in line.split(","))
            if cols != COLUMNS:
                raise TudorVisionError(f"{path}:{lineno}: expected header {','.join(COLUMNS)}, got {line!r}")
            header_seen = True
            continue
        parts = line.split(",")
        if len(parts) != len(COLUMNS):
            raise TudorVisionError(f"{path}:{lineno}: expected {len(COLUMNS)} values, got {len(parts)}")
        try:
            vals = [float(x) for x in parts]
        except ValueError:
            raise TudorVisionError(f"{path}:{lineno}: malformed number in {line!r}") from None
        if vals[-1] not in (0.0, 1.0):
            raise TudorVisionError(f"{path}:{lineno}: valid must be 0 or 1, got {parts[-1]!r}")
        rows.append(vals)
    if not header_seen:
        raise TudorVisionError(f"{path}: no header line {','.join(COLUMNS)}")
    data = np.array(rows, dtype=np.float64).reshape(-1, len(COLUMNS))
    t = data[:, 0]
    if len(t) > 1 and np.any(np.diff(t) <= 0):
        k = int(np.flatnonzero(np.diff(t) <= 0)[0])
        raise TudorVisionError(f"{path}: timestamps must increase (data row {k + 2})")
    valid = data[:, 10] == 1.0
    p = data[:, 1:4].copy()
    p[~valid] = np.nan
    return Trajectory(t=t, p=p, v=data[:, 4:7], a=data[:, 7:10], valid=valid & np.all(np.isfinite(p), axis=1),
                      frame=frame or "unknown")


def plot_trajectory(traj: Trajectory, path, *, title: str | None = None) -> Path:
    """Draw the trajectory (3D), the speed and the acceleration magnitude over time as a PNG.

    Like figure 2.7 (f)-(h) of the seed. matplotlib is imported here; the plot
    is drawn on its own :class:`matplotlib.figure.Figure`, so the global
    backend is left alone.

    Parameters
    ----------
    traj : Trajectory
        Positions (metres, in ``traj.frame``), speed and acceleration to draw.
    path : str or Path
        Output PNG; parent directories are created.
    title : str, optional
        Figure title (default "end-effector trajectory").

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    TudorVisionError
        If matplotlib is not installed.
    """
    try:
        from matplotlib.figure import Figure
    except ImportError:  # pragma: no cover
        raise TudorVisionError("plotting needs matplotlib: pip install matplotlib") from None
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig = Figure(figsize=(13, 4.2))
    ax3 = fig.add_subplot(1, 3, 1, projection="3d")
    ok = traj.valid
    ax3.plot(traj.p[:, 0], traj.p[:, 1], traj.p[:, 2], "-", lw=0.6, color="0.6")
    ax3.scatter(traj.p[ok, 0], traj.p[ok, 1], traj.p[ok, 2], s=4, c=traj.t[ok], cmap="viridis")
    ax3.set_xlabel("x [m]")
    ax3.set_ylabel("y [m]")
    ax3.set_zlabel("z [m]")
    ax3.set_title(f"trajectory ({traj.frame} frame)")
    if ok.any():   # equal scale on all axes, so a planar motion does not look jagged
        lo, hi = np.nanmin(traj.p[ok], axis=0), np.nanmax(traj.p[ok], axis=0)
        mid, half = (lo + hi) / 2, max(float(np.max(hi - lo)) / 2, 1e-3)
        ax3.set_xlim(mid[0] - half, mid[0] + half)
        ax3.set_ylim(mid[1] - half, mid[1] + half)
        ax3.set_zlim(mid[2] - half, mid[2] + half)
    ax = fig.add_subplot(1, 3, 2)
    ax.plot(traj.t, traj.speed, ".-", ms=2, lw=0.8)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("|v| [m/s]")
    ax.set_title("speed")
    ax.grid(True, alpha=0.3)
    ax = fig.add_subplot(1, 3, 3)
    ax.plot(traj.t, traj.accel_norm, ".-", ms=2, lw=0.8, color="C3")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("|a| [m/s²]")
    ax.set_title("acceleration")
    ax.grid(True, alpha=0.3)
    missing = int((~ok).sum())
    sup = title or "end-effector trajectory"
    if missing:
        sup += f" ({missing} of {len(ok)} frames without a 3D position)"
    fig.suptitle(sup)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path
