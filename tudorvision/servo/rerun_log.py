"""A rerun recording of a visual-servoing run: images, square features, errors, joint commands.

Entity layout (rerun 0.41)::

    goal/image              rr.EncodedImage (JPEG) of the goal, static
    camera/goal_features    rr.Points2D, goal centroid and corners (px), static
    camera/image            rr.EncodedImage (JPEG) of every ``image_every``-th frame
    camera/features         rr.Points2D, centroid and corners of the frame (px)
    errors/e_u_px, errors/e_v_px, errors/e_z_mm, errors/estimated_mm   rr.Scalars
    command/theta_dot_1..3  rr.Scalars, joint velocity command, rad/s

Timelines: ``frame`` (step index) and ``time`` (seconds). rerun is imported
when a log is created, so the rest of the package works without it.
"""
from __future__ import annotations

import numpy as np

from .._checks import TudorVisionError

__all__ = ["RerunServoLog"]


class RerunServoLog:
    """Log the steps of a :class:`~tudorvision.servo.loop.VisualServo` to a rerun stream.

    Parameters
    ----------
    recording : rerun.RecordingStream
        The stream (its sinks: a file, a live or a web viewer); the caller
        flushes and closes it.
    goal : GoalFeatures, optional
        The taught goal, drawn by :meth:`log_goal`.
    image_every : int
        Log the image of every n-th frame only (features and errors every frame).

    Examples
    --------
    >>> import rerun as rr
    >>> log = RerunServoLog(rr.RecordingStream("doc", default_enabled=False))
    >>> log.n_frames
    0
    """

    def __init__(self, recording, goal=None, *, image_every: int = 3):
        if int(image_every) != image_every or image_every < 1:
            raise TudorVisionError(f"image_every: expected a positive integer, got {image_every!r}")
        try:
            import rerun as rr
        except ImportError:
            raise TudorVisionError("the rerun recording needs the rerun SDK: pip install rerun-sdk") from None
        self._rr = rr
        self._rec = recording
        self._goal = goal
        self.image_every = int(image_every)
        self.n_frames = 0

    def _jpeg(self, path: str, bgr, quality: int, *, static: bool = False) -> None:
        import cv2
        ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, quality])
        if ok:
            self._rec.log(path, self._rr.EncodedImage(contents=buf.tobytes(), media_type="image/jpeg"), static=static)

    def log_goal(self, bgr) -> None:
        """Log the goal image and, with a goal, its features (static).

        Parameters
        ----------
        bgr : ndarray, shape (H, W, 3)
            Goal colour image, uint8 BGR.

        Returns
        -------
        None
        """
        self._jpeg("goal/image", bgr, 85, static=True)
        if self._goal is not None:
            f = self._goal.features
            self._rec.log("camera/goal_features", self._rr.Points2D(np.vstack([f.centroid_uv, f.corners_uv]),
                                                                    radii=3, colors=[(0, 200, 0)]), static=True)

    def log_frame(self, t, bgr, depth, step) -> None:
        """Log one servo step (the ``on_frame`` callback of the closed loop).

        Parameters
        ----------
        t : float
            Time, s.
        bgr : ndarray, shape (H, W, 3) or None
            The frame's colour image (uint8 BGR); None logs no image.
        depth : ndarray, shape (H, W) or None
            Depth in metres (not logged; kept for the callback's signature).
        step : ServoStep
            The step's features, camera command (errors in px and m) and
            joint command (rad/s).

        Returns
        -------
        None
        """
        rr, rec = self._rr, self._rec
        rec.set_time("frame", sequence=self.n_frames)
        rec.set_time("time", duration=float(t))
        if bgr is not None and self.n_frames % self.image_every == 0:
            self._jpeg("camera/image", bgr, 80)
        f = step.features
        if f.found:
            rec.log("camera/features", rr.Points2D(np.vstack([f.centroid_uv, f.corners_uv]), radii=3,
                                                   colors=[(255, 60, 60)]))
        c = step.command
        if c.ok:
            rec.log("errors/e_u_px", rr.Scalars(float(c.error[0])))
            rec.log("errors/e_v_px", rr.Scalars(float(c.error[1])))
            rec.log("errors/e_z_mm", rr.Scalars(float(c.error[2]) * 1e3))
            rec.log("errors/estimated_mm", rr.Scalars(float(c.error_m) * 1e3))
        for j, v in enumerate(step.theta_dot):
            rec.log(f"command/theta_dot_{j + 1}", rr.Scalars(float(v)))
        self.n_frames += 1
