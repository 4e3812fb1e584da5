"""The main job on an embedded default (``tudorvision demo``).

Runs the virtual lab end to end in well under a minute and writes what a
person wants to look at into ``--out``:

1. the elastic arm's physics at a glance: natural frequencies of links 2 and 3
   from the boundary-value problem for several payloads, static end-effector sag;
2. the step motion [0, 45, -45] -> [0, 135, 45] deg with 300 g (joint angles,
   strains, end-effector path) as ``step_motion.png``;
3. a short rendered stereo recording of the same motion, tracked by the
   stereo pipeline and scored against the lab's ground truth, and a contact
   sheet of stereo and RGB-D views (``views.png``);
4. the ball-catching demo (``tudorvision catch demo`` defaults) in ``catch/``.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

__all__ = ["run_demo", "views_sheet"]


def _physics_summary(params):
    from ..robot import fk_ee
    from ..sim.arm import ElasticArm, Payload
    rows = []
    for plates in (0, 3, 6):
        payload = Payload.from_parts(params, plates=plates)
        arm = ElasticArm(np.zeros(3), payload=payload, params=params)
        f2 = arm.link2.basis.omega_rad_s / (2 * np.pi)
        f3 = arm.link3.basis.omega_rad_s / (2 * np.pi)
        sag = fk_ee(np.zeros(3), params) - arm.ee_position()
        rows.append({"payload_g": round(1000 * plates * params.plate_mass_kg),
                     "link2_modes_hz": [round(float(x), 2) for x in f2],
                     "link3_modes_hz": [round(float(x), 2) for x in f3],
                     "ee_sag_at_zero_config_mm": round(float(sag[2]) * 1000, 1)})
    return rows


def _plot_step(log, path):
    from matplotlib.figure import Figure
    ee = log.ee_position()
    fig = Figure(figsize=(11, 7))
    ax = fig.subplots(2, 2)
    ax[0, 0].plot(log.t, np.rad2deg(log.theta)); ax[0, 0].set_ylabel("joint angle [deg]")
    ax[0, 0].legend(["θ1", "θ2", "θ3"]); ax[0, 0].set_xlabel("t [s]")
    ax[0, 1].plot(log.t, log.strain * 1e6); ax[0, 1].set_ylabel("strain [µm/m]"); ax[0, 1].set_xlabel("t [s]")
    ax[0, 1].legend(["link 2 near", "link 2 far", "link 3 near", "link 3 far"], fontsize=8)
    ax[1, 0].plot(ee[:, 0], ee[:, 2], label="elastic (simulated)")
    from ..robot import fk_ee
    rig = fk_ee(log.theta)
    ax[1, 0].plot(rig[:, 0], rig[:, 2], "--", label="rigid-equivalent")
    ax[1, 0].set_xlabel("x [m]"); ax[1, 0].set_ylabel("z [m]"); ax[1, 0].axis("equal"); ax[1, 0].legend()
    ax[1, 1].plot(log.t, np.linalg.norm(ee - rig, axis=1) * 1e3)
    ax[1, 1].set_ylabel("elastic − rigid EE [mm]"); ax[1, 1].set_xlabel("t [s]")
    fig.suptitle("TUDOR step [0,45,−45] → [0,135,45] deg, 300 g payload, no damping")
    fig.tight_layout()
    fig.savefig(path, dpi=90)


DEPTH_MAX_M = 6.0          # depth tiles: turbo colour map over 0 .. DEPTH_MAX_M, black = no depth


def _label(tile, text: str):
    """Write ``text`` in the tile's top-left corner, white on a dark box; returns the tile."""
    import cv2
    (w, h), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.55, 1)
    cv2.rectangle(tile, (4, 4), (12 + w, 12 + h + base), (30, 30, 30), -1)
    cv2.putText(tile, text, (8, 8 + h), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1, cv2.LINE_AA)
    return tile


def _depth_colourbar(width: int):
    """The depth tiles' colour scale: a caption, the turbo ramp over 0..6 m, ticks and labels every metre."""
    import cv2
    bar = np.full((64, width, 3), 30, np.uint8)
    cv2.putText(bar, f"depth tiles: colour scale 0-{DEPTH_MAX_M:g} m (black: no depth)", (8, 16),
                cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
    margin = 20
    ramp = np.linspace(0, 255, width - 2 * margin).astype(np.uint8)
    bar[24:38, margin:width - margin] = cv2.applyColorMap(np.tile(ramp, (14, 1)), cv2.COLORMAP_TURBO)
    for z in range(int(DEPTH_MAX_M) + 1):
        x = margin + int(round(z / DEPTH_MAX_M * (width - 2 * margin - 1)))
        cv2.line(bar, (x, 38), (x, 43), (255, 255, 255), 1)
        text = f"{z} m"
        (w, _), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.45, 1)
        cv2.putText(bar, text, (x - w // 2, 58), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
    return bar


def views_sheet(stereo_dir, rgbd_dirs, path) -> None:
    """Write ``views.png``: the stereo pair, then colour and depth of each RGB-D recording, every tile labelled.

    Each tile names its recording, camera or stream and frame (the middle frame).
    Depth tiles use the turbo colour map over 0..6 m, black where there is no
    depth; the colour bar at the bottom gives the scale in metres.

    Parameters
    ----------
    stereo_dir : str or Path
        A stereo recording (top row: left and right camera, 640x480 each).
    rgbd_dirs : sequence of str or Path
        RGB-D recordings (two per row: colour and depth, 320x240 each).
    path : str or Path
        Image to write (PNG), atomically.
    """
    import cv2
    from ..io import open_sequence
    seq = open_sequence(stereo_dir)
    k = len(seq) // 2
    f = seq[k]
    name = Path(stereo_dir).name
    top = np.hstack([_label(cv2.resize(f.left, (640, 480)), f"{name}: left camera, frame {k}"),
                     _label(cv2.resize(f.right, (640, 480)), f"{name}: right camera, frame {k}")])
    tiles = []
    for d in rgbd_dirs:
        s = open_sequence(d)
        i = min(len(s) - 1, len(s) // 2)
        fr = s[i]
        z = np.nan_to_num(fr.depth_m, nan=0.0)
        vis = cv2.applyColorMap((np.clip(z / DEPTH_MAX_M, 0, 1) * 255).astype(np.uint8), cv2.COLORMAP_TURBO)
        vis[z == 0] = 0
        label = Path(d).name
        tiles.append(np.hstack([_label(cv2.resize(fr.bgr, (320, 240)), f"{label}: colour, frame {i}"),
                                _label(cv2.resize(vis, (320, 240)), f"{label}: depth, frame {i}")]))
    rows = [top] + [np.hstack(tiles[i:i + 2]) if i + 1 < len(tiles)
                    else np.hstack([tiles[i], np.zeros_like(tiles[i])]) for i in range(0, len(tiles), 2)]
    sheet = np.vstack(rows + [_depth_colourbar(rows[0].shape[1])])
    from ..io.atomic import write_bytes_atomic
    ok, buf = cv2.imencode(Path(path).suffix or ".png", sheet)
    if ok:
        write_bytes_atomic(path, buf.tobytes())


def _track_step(stereo_dir: Path, out: Path, log) -> dict:
    """Track the rendered step motion with the stereo pipeline and score it against the lab's truth.

    The colour models are picked on frame 0 where a user would click: at the
    sphere centres (here read from the lab's truth, standing in for the
    user's eye) with the edge one sphere radius to the right. The tracker
    itself never reads ground truth.
    """
    from ..io import open_sequence
    from ..stereo import fit_color_model_set, plot_trajectory, track_stereo, write_trajectory_csv
    seq = open_sequence(stereo_dir)
    gt = seq.groundtruth("ee")
    f0 = seq[0]
    picks = []
    for cam in ("left", "right"):
        for sphere in ("red", "green"):
            u, v = gt[f"{cam}_{sphere}_u_px"][0], gt[f"{cam}_{sphere}_v_px"][0]
            picks.append((cam, sphere, (u, v), (u + 5.0, v)))
    models = fit_color_model_set({"left": f0.left, "right": f0.right}, picks)
    T = seq.groundtruth("transforms")
    T_base_left = np.array([[T[f"m{i}{j}"][0] for j in range(4)] for i in range(4)])
    res = track_stereo(seq, seq.calibration, models, T_base_left=T_base_left)
    write_trajectory_csv(out / "stereo_step_traj.csv", res.trajectory)
    plot_trajectory(res.trajectory, out / "stereo_step_traj.png")
    truth = np.column_stack([gt["ee_x_m"], gt["ee_y_m"], gt["ee_z_m"]])
    err = np.linalg.norm(res.trajectory.p - truth[res.index], axis=1)
    ok = np.isfinite(err)
    summary = {"frames": int(len(err)), "valid": int(ok.sum()),
               "rms_error_mm": round(float(np.sqrt(np.mean(err[ok] ** 2)) * 1000), 2) if ok.any() else None,
               "note": "calibration: the lab's nominal camera models and true T_base_left"}
    log(f"stereo tracking of the step: {summary['valid']}/{summary['frames']} frames valid, RMS 3D error "
        f"{summary['rms_error_mm']} mm -> {out / 'stereo_step_traj.png'}")
    return summary


def run_demo(out, *, seed: int = 0, log=print, params=None) -> dict:
    """Run the embedded demo into directory ``out``; returns the summary dict.

    ``params``: the robot (``--robot``), for the arm physics, the step motion, the recordings
    and the catching demo; default the packaged ``tudor.yaml``.
    """
    from ..robot import load_robot_params
    from ..sim.arm import Payload
    from .simulation import simulate_ptp
    from .record import RecordOptions, record
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    p = params or load_robot_params()
    summary = {"physics": _physics_summary(p)}
    for row in summary["physics"]:
        log(f"payload {row['payload_g']:4d} g: link 2 modes {row['link2_modes_hz']} Hz, link 3 modes "
            f"{row['link3_modes_hz']} Hz, EE sag at zero configuration {row['ee_sag_at_zero_config_mm']} mm")
    lg = simulate_ptp(np.deg2rad([0, 45, -45]), np.deg2rad([0, 135, 45]), 5.0,
                      payload=Payload.from_parts(p, plates=3), t_move=0.2, params=p)
    _plot_step(lg, out / "step_motion.png")
    peak = float(np.abs(lg.strain).max() * 1e6)
    settle = lg.strain[-2000:, 0] - lg.strain[-2000:, 0].mean()
    summary["step"] = {"peak_strain_um_m": round(peak, 1),
                       "residual_oscillation_last_1s_um_m": round(float(np.abs(settle).max() * 1e6), 1)}
    log(f"step motion: peak strain {peak:.0f} µm/m; undamped oscillation still "
        f"{summary['step']['residual_oscillation_last_1s_um_m']:.0f} µm/m after 4 s -> {out / 'step_motion.png'}")
    opts = RecordOptions(seed=seed, small=True, frames=60, force=True, params=params)   # the demo's own folder: re-runs replace it
    stereo_dir = record("stereo-step", out / "recordings" / "stereo-step", opts)
    rgbd = [record(k, out / "recordings" / k, RecordOptions(seed=seed, small=True, frames=n, force=True, params=params))
            for k, n in (("rgbd-disc", 4), ("servo-views", 2))]
    log(f"rendered recordings with ground truth -> {out / 'recordings'}")
    summary["stereo_tracking"] = _track_step(stereo_dir, out, log)
    from .catch_demo import DemoOptions, run_demo as run_catch_demo
    catch = run_catch_demo(out / "catch", DemoOptions(seed=seed, params=params))
    summary["catch"] = {k: catch[k] for k in ("throws", "crossing_workspace", "caught", "success_rate") if k in catch}
    log(f"ball catching: {summary['catch']} -> {out / 'catch'}")
    views_sheet(stereo_dir, rgbd, out / "views.png")
    log(f"views -> {out / 'views.png'}")
    summary["wall_time_s"] = round(time.monotonic() - t0, 1)
    from ..io.atomic import write_text_atomic
    write_text_atomic(out / "summary.json", json.dumps(summary, indent=2))
    log(f"summary -> {out / 'summary.json'} ({summary['wall_time_s']} s)")
    return summary
