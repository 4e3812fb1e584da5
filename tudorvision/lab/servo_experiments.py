"""The repeatability experiment of section 9.1 in the virtual lab, and square tracking.

Eight start postures around the goal (four near, four far, the square near
the image corners), payloads 0, 200 and 400 g in addition to the camera,
``repetitions`` runs each with fresh sensor noise, for the hybrid law and
for classical four-point IBVS in the same run. The goal is taught once, as an
image, with the camera payload only; the start postures are remembered in
joint space (computed with the rigid model for the camera-only arm), so the
payload changes the start view as in the seed's figure 9.2.

Scoring uses the lab's ground truth only: the error of a run is the distance
of the true (deflected) camera position at the end of the run from the true
camera position in which the goal image was taken. ``radius_m`` is the radius
of the sphere about the goal position enclosing all end positions;
``iso_radius_m`` the ISO 9283 repeatability about the barycentre of the end
positions (mean + 3 standard deviations of the distances).
"""
from __future__ import annotations

import csv
import json
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..io.atomic import atomic_write
from ..robot import T_base_ee, load_robot_params
from ..servo.laws import LawConfig
from ..servo.loop import DEFAULT_SMOOTHING_FRAMES, VisualServo
from .servo_lab import LabConfig, ServoLab, run_closed_loop, teach_goal

__all__ = ["start_poses", "RunSpec", "run_one", "repeatability", "plan_repeatability", "repeatability_task",
           "write_repeatability", "summarize", "track_moving_square", "PAYLOADS_G", "RUN_COLUMNS"]

PAYLOADS_G = (0, 200, 400)


def _camera_view(theta, cfg: LabConfig, square_world, params, *, elastic: bool = False):
    """View of the square centre, (x/z, y/z, z) in the camera frame: rigid model or statically deflected arm."""
    if elastic:
        from ..sim import ElasticArm, Payload
        T_be = ElasticArm(theta, payload=Payload.from_parts(params, camera=True), params=params).T_base_ee()
    else:
        T_be = T_base_ee(theta, params)
    T = cfg.T_world_base @ T_be @ cfg.T_ee_cam
    p = np.linalg.solve(T, np.append(square_world, 1.0))[:3]
    return np.array([p[0] / p[2], p[1] / p[2], p[2]])


def start_poses(cfg: LabConfig, square_world, *, near_dz_m: float = -0.07, far_dz_m: float = 0.10,
                corner_fraction: float = 0.5, params=None) -> np.ndarray:
    """Eight start postures: the square's centre near the image corners, camera nearer and farther.

    Solved on the statically deflected arm carrying the camera only (what a
    lab teaches by jogging the arm), 3 degrees inside the joint ranges; where the range ends
    forbid the requested view the nearest feasible one is taken (the seed's
    "as distant as feasible"). Order: near TL, TR, BR, BL, then far TL, TR, BR, BL.

    Returns
    -------
    thetas : ndarray, shape (8, 3)
        Radians.

    Raises
    ------
    ValueError
        If a pose is unreachable within the joint ranges.
    """
    from scipy.optimize import least_squares
    p = params or cfg.params or load_robot_params()
    w, h = cfg.image_size
    f = 525.0 * w / 640.0
    th_goal = np.asarray(cfg.theta_goal, float)
    z0 = _camera_view(th_goal, cfg, square_world, p)[2]
    m = np.deg2rad(3.0)
    lo, hi = p.joint_limits_rad[:, 0] + m, p.joint_limits_rad[:, 1] - m
    out = []
    for dz in (near_dz_m, far_dz_m):
        for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            target = np.array([su * corner_fraction * (w / 2) / f, sv * corner_fraction * (h / 2) / f, z0 + dz])
            res = least_squares(lambda th: _camera_view(th, cfg, square_world, p, elastic=True) - target,
                                np.clip(th_goal, lo, hi), bounds=(lo, hi), diff_step=1e-4)
            view = _camera_view(res.x, cfg, square_world, p, elastic=True)
            # as far as feasible: accept the nearest view inside the ranges if the square stays well inside
            if not (abs(view[0]) < 0.75 * (w / 2) / f and abs(view[1]) < 0.75 * (h / 2) / f
                    and view[2] > 0.6):
                raise ValueError(f"start pose ({su}, {sv}, {dz:+.2f} m) is not reachable")
            out.append(res.x)
    return np.array(out)


@dataclass(frozen=True, kw_only=True)
class RunSpec:
    """One run of the experiment."""

    law: str
    interaction: str
    payload_g: int
    pose: int
    repetition: int
    theta_start: tuple
    seed: int


def run_one(spec: RunSpec, cfg: LabConfig, goal, p_goal, scene_seed: int) -> dict:
    """Run one closed loop; returns a table row (SI units)."""
    t0 = time.perf_counter()
    rng = np.random.default_rng([spec.seed, spec.payload_g, spec.pose, spec.repetition, spec.law == "ibvs"])
    lab = ServoLab(cfg, spec.theta_start, plates=spec.payload_g // 100, rng=rng, scene_seed=scene_seed)
    servo = VisualServo(goal, cfg.T_ee_cam, law=LawConfig(law=spec.law, interaction=spec.interaction),
                        smoothing_frames=DEFAULT_SMOOTHING_FRAMES, params=cfg.params)
    r = run_closed_loop(lab, servo, p_goal)
    e0 = r.history["error_true_m"][0] if len(r.history["error_true_m"]) else float("nan")
    return {"law": spec.law, "payload_g": spec.payload_g, "pose": spec.pose,
            "start": "near" if spec.pose < 4 else "far", "repetition": spec.repetition,
            "converged": int(r.converged), "end": r.end_reason, "settling_time_s": r.settling_time_s,
            "error_m": r.final_error_m,
            "dx_m": r.final_offset_world[0], "dy_m": r.final_offset_world[1], "dz_m": r.final_offset_world[2],
            "start_error_m": float(e0), "frames": int(len(r.history["t"])),
            "stopped_frames": int(np.sum(~r.history["ok"])),
            "wall_s": time.perf_counter() - t0}


def repeatability_task(spec: RunSpec, cfg: LabConfig, goal, p_goal, scene_seed: int) -> dict:
    """One run of the repeatability study as a runner task: :func:`run_one` without its wall time.

    Parameters
    ----------
    spec : RunSpec
        The run.
    cfg : LabConfig
        The lab.
    goal : GoalFeatures
        The goal taught as an image.
    p_goal : ndarray, shape (3,)
        True goal camera position, world frame, m.
    scene_seed : int
        Seed of the scene.

    Returns
    -------
    dict
        The ``runs.csv`` row (:data:`RUN_COLUMNS`); it depends on the spec only, not on the machine.
    """
    row = run_one(spec, cfg, goal, p_goal, scene_seed)
    row.pop("wall_s")
    return row


#: Columns of ``runs.csv``.
RUN_COLUMNS = ("law", "payload_g", "pose", "start", "repetition", "converged", "end", "settling_time_s", "error_m",
               "dx_m", "dy_m", "dz_m", "start_error_m", "frames", "stopped_frames")


def summarize(rows: list[dict]) -> dict:
    """Statistics of end-position errors over runs (converged or not).

    Examples
    --------
    >>> s = summarize([{"error_m": 0.002, "converged": 1, "settling_time_s": 2.0, "dx_m": 0.002, "dy_m": 0,
    ...                 "dz_m": 0}])
    >>> s["mean_error_m"], s["convergence_rate"]
    (0.002, 1.0)
    """
    err = np.array([r["error_m"] for r in rows], float)
    conv = np.array([r["converged"] for r in rows], bool)
    settle = np.array([r["settling_time_s"] for r in rows], float)
    d = np.array([[r["dx_m"], r["dy_m"], r["dz_m"]] for r in rows], float)
    bary = d.mean(axis=0)
    li = np.linalg.norm(d - bary, axis=1)
    return {
        "n_runs": int(len(rows)),
        "mean_error_m": float(err.mean()),
        "p90_error_m": float(np.percentile(err, 90)),
        "radius_m": float(err.max()),
        "convergence_rate": float(conv.mean()),
        "settling_time_s": float(np.nanmean(settle)) if conv.any() else float("nan"),
        "settling_time_p90_s": float(np.nanpercentile(settle, 90)) if conv.any() else float("nan"),
        "barycentre_offset_m": bary.tolist(),
        "iso_radius_m": float(li.mean() + 3 * li.std(ddof=1)) if len(li) > 1 else 0.0,
    }


def plan_repeatability(*, repetitions: int = 20, seed: int = 0, laws=("hybrid", "ibvs"),
                       interaction: str = "current", payloads_g=PAYLOADS_G, cfg: LabConfig | None = None,
                       compare_repetitions: int | None = None) -> tuple[list, dict]:
    """The runs of the repeatability experiment as runner tasks (the goal is taught here, once).

    Parameters
    ----------
    repetitions : int
        Runs per (law, payload, start pose) for the first law.
    seed : int
        Seed of the experiment (scene, goal image; each run's noise comes from it and the run's key).
    laws : sequence of {"hybrid", "ibvs"}
        The laws; the first one is the main one.
    interaction : str
        IBVS interaction matrix.
    payloads_g : sequence of int
        Multiples of 100 g in addition to the camera.
    cfg : LabConfig, optional
        The lab.
    compare_repetitions : int, optional
        Repetitions for the laws after the first (default ``repetitions``).

    Returns
    -------
    tasks : list of Task
        Repetition-major (an interrupted run holds whole repetitions of every condition).
    context : dict
        ``poses`` (ndarray, shape (8, 3), rad), ``p_goal`` (ndarray, shape (3,), m), ``repetitions``,
        ``compare_repetitions``, ``laws``, ``payloads_g``, ``interaction``, ``seed``.

    Raises
    ------
    ValueError
        On repetitions < 1 or payloads that are not multiples of 100 g.
    """
    from .runner import Task, config_digest
    compare_repetitions = repetitions if compare_repetitions is None else int(compare_repetitions)
    for name, n in (("repetitions", repetitions), ("compare_repetitions", compare_repetitions)):
        if n < 1:
            raise ValueError(f"{name}: expected >= 1, got {n}")
    for g in payloads_g:
        if g % 100 or g < 0:
            raise ValueError(f"payloads_g: expected multiples of 100 g, got {g}")
    laws = tuple(laws)
    cfg = cfg or LabConfig()
    scene_seed = int(seed)
    goal, p_goal, _ = teach_goal(cfg, np.random.default_rng([seed, 999]), scene_seed=scene_seed)
    lab0 = ServoLab(cfg, cfg.theta_goal, rng=np.random.default_rng(0), scene_seed=scene_seed)
    poses = start_poses(cfg, lab0.square_center_world)
    config = config_digest(cfg)
    specs = [RunSpec(law=law, interaction=interaction, payload_g=int(g), pose=i, repetition=k,
                     theta_start=tuple(poses[i]), seed=int(seed))
             for k in range(max(repetitions, compare_repetitions)) for law in laws
             if k < (repetitions if law == laws[0] else compare_repetitions)
             for g in payloads_g for i in range(len(poses))]
    tasks = [Task("servo-repeatability", {"law": s.law, "interaction": s.interaction, "payload_g": s.payload_g,
                                          "pose": s.pose, "repetition": s.repetition, "config": config},
                  int(seed), repeatability_task, (s, cfg, goal, p_goal, scene_seed)) for s in specs]
    context = {"poses": poses, "p_goal": np.asarray(p_goal), "repetitions": int(repetitions),
               "compare_repetitions": compare_repetitions, "laws": laws, "payloads_g": [int(g) for g in payloads_g],
               "interaction": interaction, "seed": int(seed)}
    return tasks, context


def repeatability(out, *, repetitions: int = 20, seed: int = 0, laws=("hybrid", "ibvs"), interaction: str = "current",
                  payloads_g=PAYLOADS_G, cfg: LabConfig | None = None, workers: int | None = None,
                  progress=None, compare_repetitions: int | None = None, scheduler: str | None = None,
                  processes: bool = True, show_progress: bool | None = False,
                  dashboard_address: str | None = ":8787") -> dict:
    """Run the repeatability experiment and write ``summary.json``, ``runs.csv`` and ``runner.json`` to ``out``.

    The runs go through :func:`~tudorvision.lab.runner.run_tasks`: each finished
    run is kept in ``out/runs/`` as it arrives, so running the same command
    again skips what is done; ``runs.csv`` and ``summary.json`` are the same
    bytes whatever the scheduler, the number of workers or the order the runs
    finished in. Timing and the scheduler go to ``runner.json``.

    Parameters
    ----------
    out : path
        Output folder.
    repetitions : int
        Runs per (law, payload, start pose), each with its own sensor noise.
    seed : int
        Seed of the experiment.
    laws : sequence of {"hybrid", "ibvs"}
        The laws; the first one is the main one.
    interaction : str
        IBVS interaction matrix.
    payloads_g : sequence of int
        Multiples of 100 g (plates) in addition to the camera.
    cfg : LabConfig, optional
        The lab.
    workers : int, optional
        Local worker processes (default: all CPUs); with ``workers=1`` and no ``scheduler`` the runs go serially.
    progress : callable, optional
        ``f(done, total)`` after each run finished now (runs found done are not counted).
    compare_repetitions : int, optional
        Repetitions for the laws after the first (default: ``repetitions``).
    scheduler : str, optional
        ``"serial"``, ``"local"`` or a Dask scheduler address; default ``"serial"`` for ``workers=1``,
        else ``"local"``.
    processes : bool
        Local cluster of processes (else threads).
    show_progress : bool or None
        Runner progress on stderr (``None``: on a terminal a live bar, else plain lines).
    dashboard_address : str or None
        Local cluster's dashboard (``None``: none).

    Returns
    -------
    dict
        The summary as written, plus ``wall_s``, ``workers`` and ``runner`` (the runner's counts and timing).
        ``complete`` is false when runs failed or the run was interrupted (``interrupted``).
    """
    from .runner import run_tasks
    t0 = time.perf_counter()
    tasks, ctx = plan_repeatability(repetitions=repetitions, seed=seed, laws=laws, interaction=interaction,
                                    payloads_g=payloads_g, cfg=cfg, compare_repetitions=compare_repetitions)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if scheduler is None:
        scheduler = "serial" if workers == 1 else "local"
    n_done = [0]

    def on_record(rec):
        n_done[0] += 1
        if progress:
            progress(n_done[0], len(tasks))

    report = run_tasks(tasks, out, scheduler=scheduler, workers=workers, processes=processes,
                       dashboard_address=dashboard_address, show_progress=show_progress,
                       label="servo repeatability", on_record=on_record)
    return write_repeatability(out, ctx, report, wall_s=time.perf_counter() - t0)


def write_repeatability(out, context: dict, report, *, wall_s: float | None = None) -> dict:
    """Write ``runs.csv``, ``summary.json`` and ``runner.json`` of a repeatability run.

    Parameters
    ----------
    out : path
        Output folder.
    context : dict
        From :func:`plan_repeatability`.
    report : RunReport
        From :func:`~tudorvision.lab.runner.run_tasks` on the planned tasks.
    wall_s : float, optional
        Wall time of the whole experiment, s (default: the runner's).

    Returns
    -------
    dict
        The summary as written, plus ``wall_s``, ``workers`` and ``runner``.
    """
    from ..io.atomic import write_text_atomic
    out = Path(out)
    ctx = context
    interaction, seed = ctx["interaction"], ctx["seed"]
    rows = [r["result"] for r in report.done]
    with atomic_write(out / "runs.csv", "w", newline="") as fh:
        wr = csv.DictWriter(fh, fieldnames=list(RUN_COLUMNS))
        wr.writeheader()
        for row in rows:
            wr.writerow(row)
    laws = ctx["laws"]
    payloads = ctx["payloads_g"]

    def stats(sel):
        return summarize(sel) if sel else None

    per_law = {law: stats([r for r in rows if r["law"] == law]) for law in laws}
    per_payload = {law: {str(g): stats([r for r in rows if r["law"] == law and r["payload_g"] == g])
                         for g in payloads} for law in laws}
    main = per_law[laws[0]] or {}
    summary = {**{k: main.get(k) for k in ("mean_error_m", "p90_error_m", "radius_m", "convergence_rate",
                                           "settling_time_s")},
               "law": laws[0], "laws": per_law, "per_payload": per_payload, "repetitions": ctx["repetitions"],
               "compare_repetitions": ctx["compare_repetitions"], "interaction": interaction,
               "seed": int(seed), "payloads_g": payloads, "start_poses_rad": ctx["poses"].tolist(),
               "goal_camera_world_m": ctx["p_goal"].tolist(),
               "complete": report.complete, "interrupted": report.interrupted, "runs_planned": len(report.records),
               "runs_done": len(rows), "runs_failed": len(report.failed),
               "failures": [{k: r[k] for k in ("key", "seed", "params", "error")} for r in report.failed],
               "seed_result_m": {"mean": 0.004, "p90": 0.008, "radius": 0.014},
               "goal_m": {"mean": 0.002, "p90": 0.004, "radius": 0.007, "convergence_rate": 1.0},
               "error_definition": "distance of the true camera position at the end of a run from the true "
                                   "camera position of the goal image (camera payload only)"}
    write_text_atomic(out / "summary.json", json.dumps(summary, indent=2))
    info = {**report.info(), "total_wall_s": report.wall_s if wall_s is None else wall_s}
    write_text_atomic(out / "runner.json", json.dumps(info, indent=2))
    return {**summary, "wall_s": info["total_wall_s"], "workers": report.workers, "runner": info}


def track_moving_square(*, speed_m_s: float = 0.01, duration_s: float = 8.0, seed: int = 0,
                        cfg: LabConfig | None = None, law: str = "hybrid") -> dict:
    """Servo on a square sliding on the floor at constant speed; steady tracking error.

    The goal is taught with the square at rest; then the square moves along
    world x (in the arm plane) at ``speed_m_s``. Errors over the second half
    of the run, from the lab's ground truth:

    * ``steady_error_*``: the square's centre in the true camera frame
      against its position in the goal view, ``||p_sq_cam(t) - p_sq_cam*||``:
      what the 3-DOF servo regulates (the centroid ray and the depth).
    * ``world_offset_*``: the camera position against the goal camera
      position carried along with the square. It grows while the square
      moves, because the translation-only servo cannot hold the camera's
      orientation: the posture change tilts the camera, and the servo keeps
      the square in the goal view with a tilted camera somewhere else.

    Returns
    -------
    dict
        ``steady_error_mean_m``, ``steady_error_max_m``, ``world_offset_mean_m``,
        ``world_offset_end_m``, ``tilt_end_deg`` (optical-axis angle to the goal's),
        ``speed_m_s``, ``lag_expected_m`` (``speed / lambda_0``, the steady lag of a
        first-order loop), ``lost_frames``.
    """
    from ..sim.render import Scene
    cfg = replace(cfg or LabConfig(), t_max_s=duration_s, converge_frames=10 ** 6)
    goal, p_goal, _ = teach_goal(cfg, np.random.default_rng([seed, 999]), scene_seed=seed)
    lab = ServoLab(cfg, cfg.theta_goal, rng=np.random.default_rng([seed, 1]), scene_seed=seed)
    T_goal = lab.T_world_cam()                    # at rest in the goal posture: the goal view's pose
    static = [s for s in lab.setup.scene.static if s.name != "square"]
    sq = [s for s in lab.setup.scene.static if s.name == "square"][0]
    c0 = np.asarray(sq.center, float)
    velocity = np.array([speed_m_s, 0.0, 0.0])

    def dynamic(t):
        return [replace(sq, center=c0 + velocity * t)]

    lab.setup = replace(lab.setup, scene=Scene(static=static, lights=lab.setup.scene.lights, dynamic=dynamic))
    law_cfg = LawConfig(law=law)
    servo = VisualServo(goal, cfg.T_ee_cam, law=law_cfg, smoothing_frames=DEFAULT_SMOOTHING_FRAMES,
                        params=cfg.params)
    r = run_closed_loop(lab, servo, p_goal)
    t = r.history["t"]
    T = r.history["T_world_cam"]
    sq_world = c0[None, :] + np.outer(t, velocity)
    sq_cam = np.einsum("nji,nj->ni", T[:, :3, :3], sq_world - T[:, :3, 3])    # R^T (p - o)
    sq_cam_goal = T_goal[:3, :3].T @ (c0 - T_goal[:3, 3])
    err = np.linalg.norm(sq_cam - sq_cam_goal, axis=1)
    world = np.linalg.norm(r.history["p_cam_world"] - (p_goal[None, :] + np.outer(t, velocity)), axis=1)
    tilt = np.degrees(np.arccos(np.clip(T[-1, :3, 2] @ T_goal[:3, 2], -1.0, 1.0)))
    half = t >= duration_s / 2
    return {"speed_m_s": speed_m_s, "duration_s": duration_s, "law": law,
            "steady_error_mean_m": float(np.mean(err[half])), "steady_error_max_m": float(np.max(err[half])),
            "world_offset_mean_m": float(np.mean(world[half])), "world_offset_end_m": float(world[-1]),
            "tilt_end_deg": float(tilt), "lag_expected_m": speed_m_s / law_cfg.gain.lambda_0,
            "lost_frames": int(np.sum(~r.history["ok"]))}
