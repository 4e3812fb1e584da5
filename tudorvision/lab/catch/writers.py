"""Outputs of the catching demo: CSV tables, JSON summary, the plot and the rerun recording.

Files written by :func:`~tudorvision.lab.catch.run.run_demo`:

* ``throws.csv``: one :class:`~tudorvision.lab.catch.score.ThrowResult` per row,
  columns :data:`~tudorvision.lab.catch.score.PER_THROW_COLUMNS`;
* ``predictions.csv``, ``setpoints.csv``: the agent's intercept estimates and
  setpoints (:data:`~tudorvision.lab.catch.agent.PREDICTION_COLUMNS`,
  :data:`~tudorvision.lab.catch.agent.SETPOINT_COLUMNS`);
* ``summary.json``; ``catch.png`` (:func:`plot_catch`); ``catch.rrd`` (:class:`RerunLog`).

Numbers are written with 6 significant digits, missing values (``nan``,
``inf``) as empty cells, flags as 0/1.
"""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from .agent import PREDICTION_COLUMNS, SETPOINT_COLUMNS
from .score import PER_THROW_COLUMNS

__all__ = ["RerunLog", "format_cell", "format_row", "plot_catch", "write_csv", "write_summary_json",
           "write_throws_csv"]



def format_cell(v, *, timestamp: bool = False):
    """One CSV cell: strings as they are, integers (and flags) as integers, floats with 6 digits, nan/inf empty.

    Parameters
    ----------
    v : str, int, bool or float
        The value.
    timestamp : bool
        A time in seconds (a ``t_..._s`` column): to the microsecond instead of 6 significant digits, so that a
        frame's exposure and the setpoint that answers it, one latency later, still tell apart and line up late
        in a session.

    Returns
    -------
    str or int
        The cell.

    Examples
    --------
    >>> [format_cell(x) for x in ("arm late", True, 3, 0.1234567, float("nan"))]
    ['arm late', 1, 3, '0.123457', '']
    >>> format_cell(123.4566667, timestamp=True)
    '123.456667'
    """
    if isinstance(v, str):
        return v
    if isinstance(v, (int, np.integer)):
        return int(v)
    v = float(v)
    if not np.isfinite(v):
        return ""
    return f"{v:.6f}" if timestamp else f"{v:.6g}"


def format_row(columns, values) -> list:
    """The cells of one CSV row (:func:`format_cell`; columns named ``t_s`` or ``t_..._s`` as timestamps).

    Parameters
    ----------
    columns : sequence of str
        The header, one name per value.
    values : sequence
        The row's values, in ``columns`` order.

    Returns
    -------
    list
        The cells.

    Examples
    --------
    >>> format_row(["throw", "t_s", "lead_time_s"], [2, 12.3456789, 0.3456789])
    [2, '12.345679', '0.345679']
    """
    return [format_cell(v, timestamp=c.startswith("t_") and c.endswith("_s")) for c, v in zip(columns, values)]


def write_csv(path, columns, rows) -> Path:
    """Write ``rows`` (sequences of values in ``columns`` order) under a header line.

    Parameters
    ----------
    path : str or Path
        Output file.
    columns : sequence of str
        Header.
    rows : iterable of sequence
        Values, formatted by :func:`format_row`.

    Returns
    -------
    Path
        The file written.
    """
    path = Path(path)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        for row in rows:
            w.writerow(format_row(columns, row))
    return path


def write_throws_csv(path, results) -> Path:
    """Write ``throws.csv``: one row per :class:`~tudorvision.lab.catch.score.ThrowResult`.

    Parameters
    ----------
    path : str or Path
        Output file.
    results : sequence of ThrowResult
        The throws.

    Returns
    -------
    Path
        The file written.
    """
    return write_csv(path, PER_THROW_COLUMNS, (r.as_row() for r in results))


def write_predictions_csv(path, rows) -> Path:
    """Write ``predictions.csv`` from the agent's prediction rows (:data:`PREDICTION_COLUMNS`)."""
    return write_csv(path, PREDICTION_COLUMNS, rows)


def write_setpoints_csv(path, rows) -> Path:
    """Write ``setpoints.csv`` from the agent's setpoint rows (:data:`SETPOINT_COLUMNS`)."""
    return write_csv(path, SETPOINT_COLUMNS, rows)


def write_summary_json(path, summary: dict) -> Path:
    """Write the run's summary as indented JSON.

    Parameters
    ----------
    path : str or Path
        Output file.
    summary : dict
        JSON-serialisable summary.

    Returns
    -------
    Path
        The file written.
    """
    path = Path(path)
    path.write_text(json.dumps(summary, indent=2))
    return path


def plot_catch(results, predictions, *, net_radius_m: float, params):
    """Crossings and nets in the working plane, and the intercept error against the time before the crossing.

    Parameters
    ----------
    results : sequence of ThrowResult
        The throws.
    predictions : sequence of sequence
        The agent's prediction rows (:data:`PREDICTION_COLUMNS`).
    net_radius_m : float
        Net radius drawn around each net centre, m.
    params : RobotParams
        The robot (its reach is drawn).

    Returns
    -------
    matplotlib.figure.Figure
        Two panels; the global pyplot state and backend are left alone.
    """
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    fig = Figure(figsize=(12, 5))
    a, b = fig.subplots(1, 2)
    reach = params.link2_length_m + params.link3_length_m
    ang = np.linspace(0, 2 * np.pi, 200)
    a.plot(reach * np.cos(ang), params.link1_height_m + reach * np.sin(ang), "k--", lw=0.8, label="reach")
    for r in results:
        if not r.crosses_plane:
            continue
        col = "tab:green" if r.caught else ("tab:red" if r.crossing_workspace else "tab:gray")
        a.plot(r.x_cross_true_m, r.z_cross_true_m, "o", color=col)
        if np.isfinite(r.x_net_m):
            a.add_patch(Circle((r.x_net_m, r.z_net_m), net_radius_m, fill=False, color=col, lw=0.8))
    a.set_aspect("equal")
    a.set_xlabel("x base (m)")
    a.set_ylabel("z base (m)")
    a.set_title("true crossings (dots) and the net at the crossing (circles)")
    from matplotlib.lines import Line2D
    a.legend(handles=[Line2D([], [], color="k", ls="--", lw=0.8, label="reach (link 2 + link 3)"),
                      Line2D([], [], color="tab:green", marker="o", ls="", label="caught"),
                      Line2D([], [], color="tab:red", marker="o", ls="", label="missed (in workspace)"),
                      Line2D([], [], color="tab:gray", marker="o", ls="", label="outside the workspace"),
                      Line2D([], [], color="k", marker="o", ls="", mfc="none", ms=10,
                             label=f"net (radius {100 * net_radius_m:.0f} cm)")],
             loc="lower right", fontsize=8)
    col = {name: PREDICTION_COLUMNS.index(name) for name in ("throw", "t_s", "x_cross_m", "z_cross_m")}
    pr = np.array([[p[col["throw"]], p[col["t_s"]], p[col["x_cross_m"]], p[col["z_cross_m"]]] for p in predictions],
                  float) if len(predictions) else np.zeros((0, 4))
    for r in results:
        if not r.crosses_plane:
            continue
        sel = pr[pr[:, 0] == r.throw]
        if len(sel) == 0:
            continue
        t_cross = r.t_release_s + r.t_cross_true_s
        err = np.hypot(sel[:, 2] - r.x_cross_true_m, sel[:, 3] - r.z_cross_true_m)
        b.semilogy(t_cross - sel[:, 1], err * 100, ".-", lw=0.8, label=f"throw {r.throw}")
    b.axvline(0.3, color="k", ls=":", label="0.3 s before the crossing")
    b.axhline(2.0, color="k", ls="-.", lw=0.8, label="2 cm")
    b.grid(True, which="both", alpha=0.3)
    handles, labels = b.get_legend_handles_labels()
    if len(labels) > 12:            # many throws: name the reference lines only
        keep = [i for i, lab in enumerate(labels) if not lab.startswith("throw ")]
        handles, labels = [handles[i] for i in keep], [labels[i] for i in keep]
    b.legend(handles, labels, loc="upper left", fontsize=8)
    b.invert_xaxis()
    b.set_xlabel("time before crossing (s)")
    b.set_ylabel("intercept error (cm)")
    b.set_title("EKF intercept error vs time before crossing")
    fig.tight_layout()
    return fig


class RerunLog:
    """rerun recording of the catch: detections, intercepts, net, setpoints (rerun 0.41).

    Entities: ``world/detections`` (last 40 detections), ``world/net``,
    ``world/intercept`` (rr.Points3D, metres, base frame), ``world/setpoint``,
    ``plots/intercept_sigma_m``, ``plots/setpoint/theta<j>_rad``
    (rr.Scalars) and ``camera/depth`` (rr.DepthImage, metres), on the
    ``time`` timeline (s).

    Parameters
    ----------
    path : str or Path, optional
        The ``.rrd`` file; not used when a recording is given.
    net_radius_m : float
        Radius the net is drawn with, m.
    recording : rerun.RecordingStream, optional
        Log to this stream instead of opening ``path``.
    """

    def __init__(self, path=None, *, net_radius_m: float, recording=None):
        import rerun as rr

        self.rr = rr
        self._own = recording is None
        if self._own:
            if path is None:
                raise ValueError("RerunLog: give a path or a recording")
            self.rec = rr.RecordingStream("tudorvision_catch")
            self.rec.save(str(path))
        else:
            self.rec = recording
        self.net_radius_m = float(net_radius_m)
        self._pts: list = []

    def frame(self, t: float, p_det_base, record: dict, net_now_base=None) -> None:
        """Log one detection at ``t`` (s): the last 40 detections, the net now (if given) and the intercept (m, base)."""
        rr, r = self.rr, self.rec
        r.set_time("time", duration=float(t))
        self._pts.append(p_det_base)
        r.log("world/detections", rr.Points3D(np.array(self._pts[-40:]), radii=0.01, colors=(255, 200, 0)))
        if net_now_base is not None:
            r.log("world/net", rr.Points3D([net_now_base], radii=self.net_radius_m, colors=(80, 160, 255)))
        it = record.get("intercept")
        if it is not None:
            r.log("world/intercept", rr.Points3D([it.p_base], radii=max(it.sigma_m, 0.01),
                                                 colors=(0, 255, 0) if it.send else (255, 80, 80)))
            r.log("plots/intercept_sigma_m", rr.Scalars(it.sigma_m))

    def setpoint(self, t: float, theta_rad, p_target_base) -> None:
        """Log a joint setpoint sent at ``t`` (s): the joint angles (rad) and the target point (m, base frame)."""
        rr, r = self.rr, self.rec
        r.set_time("time", duration=float(t))
        for j, v in enumerate(np.asarray(theta_rad, float).ravel()):
            r.log(f"plots/setpoint/theta{j + 1}_rad", rr.Scalars(float(v)))
        r.log("world/setpoint", rr.Points3D([np.asarray(p_target_base, float)], radii=0.02, colors=(0, 200, 255)))

    def depth(self, t: float, depth_m) -> None:
        """Log a depth frame (H, W) in metres at ``t`` (s)."""
        self.rec.set_time("time", duration=float(t))
        self.rec.log("camera/depth", self.rr.DepthImage(np.asarray(depth_m, np.float32), meter=1.0))

    def close(self) -> None:
        """Flush the recording (and close its file when this log opened it)."""
        self.rec.flush()
        if self._own:
            self.rec.disconnect()
