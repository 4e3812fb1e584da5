"""rerun logging of RGB-D perception: depth frames, the tracked disc and the fitted base frame (rerun 0.41).

Entity layout; 3D entities in metres in the camera's optical frame::

    camera/depth        rr.DepthImage (metres) of a frame
    camera/disc         rr.Points3D, the disc centre of the frame
    camera/sweep        rr.Points3D, all disc centres of the sweep (static)
    camera/base         rr.Transform3D + axes: the fitted robot base frame, T_cam_base (static)

Timelines: ``frame`` (sequence index) and ``time`` (s). rerun is imported on
first use.
"""
from __future__ import annotations

import numpy as np

__all__ = ["log_base_frame", "log_depth_frame", "log_disc"]


def _time(recording, index: int, t: float) -> None:
    recording.set_time("frame", sequence=int(index))
    recording.set_time("time", duration=float(t))


def log_depth_frame(recording, index: int, t: float, depth_m) -> None:
    """Log one depth frame.

    Parameters
    ----------
    recording : rerun.RecordingStream
        The stream to log to.
    index : int
        Sequence index of the frame.
    t : float
        Frame time, s.
    depth_m : ndarray, shape (H, W)
        Depth in metres (0 or NaN: no depth).

    Returns
    -------
    None
    """
    import rerun as rr

    _time(recording, index, t)
    d = np.nan_to_num(np.asarray(depth_m, np.float32), nan=0.0)
    recording.log("camera/depth", rr.DepthImage(d, meter=1.0))


def log_disc(recording, index: int, t: float, centre_cam=None) -> None:
    """Log the disc centre of one frame (None or non-finite clears it).

    Parameters
    ----------
    recording : rerun.RecordingStream
        The stream to log to.
    index : int
        Sequence index of the frame.
    t : float
        Frame time, s.
    centre_cam : array_like, shape (3,), optional
        Disc centre, m, camera optical frame.

    Returns
    -------
    None
    """
    import rerun as rr

    _time(recording, index, t)
    if centre_cam is None or not np.all(np.isfinite(centre_cam)):
        recording.log("camera/disc", rr.Clear(recursive=False))
        return
    recording.log("camera/disc", rr.Points3D([np.asarray(centre_cam, float)], radii=0.02, colors=[(255, 140, 0)]))


def log_base_frame(recording, T_base_cam, points_cam) -> None:
    """Log the sweep's disc centres and the fitted base frame (static).

    Parameters
    ----------
    recording : rerun.RecordingStream
        The stream to log to.
    T_base_cam : ndarray, shape (4, 4)
        Camera pose in the robot base frame (m).
    points_cam : ndarray, shape (N, 3)
        Disc centres of the sweep, m, camera frame (NaN rows skipped).

    Returns
    -------
    None
    """
    import rerun as rr

    pts = np.asarray(points_cam, float).reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    recording.log("camera/sweep", rr.Points3D(pts, radii=0.01, colors=[(255, 200, 0)]), static=True)
    T_cam_base = np.linalg.inv(np.asarray(T_base_cam, float))
    recording.log("camera/base", rr.Transform3D(translation=T_cam_base[:3, 3], mat3x3=T_cam_base[:3, :3]),
                  static=True)
    recording.log("camera/base/axes", rr.Arrows3D(vectors=0.2 * np.eye(3),
                                                  colors=[(255, 0, 0), (0, 255, 0), (0, 0, 255)],
                                                  labels=["x", "y", "z"]), static=True)
