"""Eye-in-hand frames for the servo lab at a fraction of a full ray-cast (lab side, ground truth).

The servo lab's scene is a ground plane of one colour under ambient and
directional lights, with small foreground shapes (the black square) on it.
Every ground pixel then has the same radiance, and its depth is that of a
plane, a closed-form function of the pixel. :class:`RoiRenderer` therefore
ray-casts only the pixel box around the foreground shapes (with a camera
cropped to that box, which gives the very same rays as the full camera),
fills the rest of the frame with the ground's radiance and plane depth, and
then applies the simulator's own sensor model (colour noise, 12-bit ADC,
gamma) and depth model (range, depth edges, dark surfaces, Kinect noise,
millimetre rounding) to the whole frame. The result has the same
distribution as :func:`tudorvision.sim.render.render_rgbd`; without noise it
is the same image (tested).

Where the shortcut does not hold (lens distortion, textured ground, point
lights, ground not filling the frame, foreground covering most of the frame)
it falls back to the full render.
"""
from __future__ import annotations

import numpy as np

__all__ = ["RoiRenderer"]


class RoiRenderer:
    """Render RGB-D frames of an eye-in-hand scene, ray-casting only the foreground's pixel box.

    Parameters
    ----------
    scene : tudorvision.sim.render.Scene
        Must contain one static :class:`~tudorvision.sim.render.Rectangle`
        named ``ground_name``; all other shapes (static or dynamic) are
        foreground.
    depth_model : tudorvision.sim.render.DepthModel
        Depth noise, quantisation and range of the depth sensor.
    sensor : tudorvision.sim.lighting.SensorModel, optional
        Colour sensor model; default ``SensorModel()``.
    ground_name : str
        Name of the static ground rectangle rendered once and reused.
    max_fraction : float
        Fall back to the full render when the foreground box covers more than
        this fraction of the frame.
    supersample : int
        1 (default): colour point-sampled at pixel centres, like
        :func:`~tudorvision.sim.render.render_rgbd`. ``k > 1``: the colour of
        the foreground box is the mean of ``k x k`` samples per pixel (pixel
        area integration, as a real sensor does; edges become grey ramps with
        sub-pixel information). Depth stays point-sampled. A departure from
        the simulator's camera model, for studying its effect.

    Raises
    ------
    ValueError
        If ``supersample`` is not a positive integer.

    Examples
    --------
    >>> import numpy as np
    >>> from tudorvision.sim import eye_in_hand, render_rgbd
    >>> from tudorvision.sim.render import DepthModel
    >>> T = np.diag([1.0, -1.0, -1.0, 1.0]); T[2, 3] = 0.8
    >>> setup = eye_in_hand(T, np.random.default_rng(0), square_center_world=(0, 0, 0), width=160, height=120)
    >>> cam = setup.cameras["rgbd"]
    >>> bgr, depth = RoiRenderer(setup.scene, DepthModel()).render(cam, 0.0, rng=None)
    >>> ref_bgr, ref_depth, _ = render_rgbd(cam, setup.scene, 0.0, rng=None)
    >>> bool(np.array_equal(bgr, ref_bgr)), int(np.abs(depth.astype(int) - ref_depth).max())
    (True, 0)
    """

    def __init__(self, scene, depth_model, *, sensor=None, ground_name: str = "ground", max_fraction: float = 0.5,
                 supersample: int = 1):
        from .lighting import AmbientLight, DirectionalLight, SensorModel
        from .render import Rectangle
        self.scene = scene
        self.depth_model = depth_model
        self.sensor = sensor if sensor is not None else SensorModel()
        self.max_fraction = float(max_fraction)
        if int(supersample) != supersample or supersample < 1:
            raise ValueError(f"supersample: expected a positive integer, got {supersample!r}")
        self.supersample = int(supersample)
        grounds = [s for s in scene.static if s.name == ground_name]
        self.ground = grounds[0] if len(grounds) == 1 else None
        self.foreground_static = [s for s in scene.static if s is not self.ground]
        ok = (isinstance(self.ground, Rectangle) and self.ground.checker_square_m is None
              and all(isinstance(light, (AmbientLight, DirectionalLight)) for light in scene.lights))
        #: False when the scene does not allow the shortcut (every frame is then a full render).
        self.applicable = bool(ok)
        self.n_full = 0          # frames that fell back to the full render
        self.n_roi = 0
        self._tables = {}

    # ---------------------------------------------------------------------------------------
    def _full(self, camera, t, rng):
        from .render import render_rgbd
        self.n_full += 1
        bgr, depth, _ = render_rgbd(camera, self.scene, t, rng=rng, depth_model=self.depth_model,
                                    sensor=self.sensor)
        return bgr, depth

    @staticmethod
    def _crop(camera, v0, v1, u0, u1):
        from .camera import PinholeCamera
        K = np.array(camera.K, dtype=np.float64)
        K[0, 2] -= u0
        K[1, 2] -= v0
        return PinholeCamera(K=K, dist=camera.dist, width=u1 - u0, height=v1 - v0, T_world_cam=camera.T_world_cam)

    def _ground_depth(self, camera) -> np.ndarray:
        """Depth z (H, W) of the ground plane at every pixel centre (zero distortion)."""
        H, W = camera.height, camera.width
        T = camera.T_world_cam
        n = self.ground.normal
        n_cam = T[:3, :3].T @ n
        h = float(n @ (self.ground.center - T[:3, 3]))
        K = camera.K
        y = (np.arange(H, dtype=np.float64) - K[1, 2]) / K[1, 1]
        x = (np.arange(W, dtype=np.float64) - K[0, 2]) / K[0, 0]
        # x of pixel (u, v) is (u - cx - s y) / fx; s is zero for this lab's cameras but kept exact
        den = (n_cam[0] * x)[None, :] + (n_cam[1] * y + n_cam[2] - n_cam[0] * K[0, 1] / K[0, 0] * y)[:, None]
        with np.errstate(divide="ignore"):
            return h / den

    def _ground_covers(self, camera) -> bool:
        """All four image-corner rays hit the ground rectangle (then, it being convex, every ray does)."""
        from .camera import camera_center_world
        H, W = camera.height, camera.width
        K = camera.K
        uv = np.array([[0.0, 0.0], [W - 1.0, 0.0], [W - 1.0, H - 1.0], [0.0, H - 1.0]])
        y = (uv[:, 1] - K[1, 2]) / K[1, 1]
        x = (uv[:, 0] - K[0, 2] - K[0, 1] * y) / K[0, 0]
        d_cam = np.stack([x, y, np.ones(4)])
        d = camera.T_world_cam[:3, :3] @ (d_cam / np.linalg.norm(d_cam, axis=0))
        t = self.ground.intersect(camera_center_world(camera), d)
        return bool(np.all(np.isfinite(t)))

    def render(self, camera, t: float, *, rng: np.random.Generator | None = None):
        """One frame: ``(bgr uint8 (H, W, 3), depth uint16 (H, W))`` as :func:`~tudorvision.sim.render.render_rgbd`.

        Parameters
        ----------
        camera : PinholeCamera
            The full camera at its current pose.
        t : float
            Scene time, seconds.
        rng : numpy.random.Generator, optional
            Sensor noise; None renders noise-free.

        Returns
        -------
        bgr : ndarray, shape (H, W, 3), uint8
            Colour image, BGR order.
        depth : ndarray, shape (H, W), uint16
            z in ``1 / depth_model.units_per_m`` metres (millimetres by default), 0 invalid.
        """
        from .lighting import apply_sensor
        from .render import depth_mm_from_gbuffer, pixel_bboxes, render_gbuffer, render_radiance
        if not self.applicable or np.any(np.asarray(camera.dist) != 0) or not self._ground_covers(camera):
            return self._full(camera, t, rng)
        H, W = camera.height, camera.width
        shapes = list(self.foreground_static)
        if self.scene.dynamic is not None:
            shapes += list(self.scene.dynamic(t))
        boxes = [b for b in pixel_bboxes(camera, [s.corners() for s in shapes]) if b is not None]
        if any(s.corners() is None for s in shapes):
            return self._full(camera, t, rng)
        if boxes:
            v0, v1 = min(b[0] for b in boxes), max(b[1] for b in boxes)
            u0, u1 = min(b[2] for b in boxes), max(b[3] for b in boxes)
            if rng is not None:     # the edge jitter moves the box's edges outwards by up to this much
                j = self.depth_model.jitter_reach_px(W)
                v0, v1, u0, u1 = max(v0 - j, 0), min(v1 + j, H), max(u0 - j, 0), min(u1 + j, W)
            if (v1 - v0) * (u1 - u0) > self.max_fraction * H * W:
                return self._full(camera, t, rng)
        else:
            v0 = v1 = u0 = u1 = 0
        # a ground-only pixel: the image corner farthest from the box
        corners = [(0, 0), (0, W - 1), (H - 1, 0), (H - 1, W - 1)]
        gv, gu = max(corners, key=lambda c: max(v0 - c[0], c[0] - v1 + 1, 0) + max(u0 - c[1], c[1] - u1 + 1, 0))
        if v0 <= gv < v1 and u0 <= gu < u1:
            return self._full(camera, t, rng)
        one = self._crop(camera, gv, gv + 1, gu, gu + 1)
        g_one = render_gbuffer(one, self.scene, t)
        if g_one.object_id[0, 0] != self.scene.static.index(self.ground) + 1:
            return self._full(camera, t, rng)
        ground_rad = render_radiance(one, self.scene, t)[0, 0]
        ground_alb = g_one.albedo_rgb[0, 0]
        ground_depth = self._ground_depth_mm(camera, ground_alb, rng)
        if ground_depth is None:
            return self._full(camera, t, rng)
        bgr = self._ground_bgr(ground_rad, (H, W), rng)
        depth = ground_depth
        if v1 > v0:
            # ray-cast the box and a rim of ground (depth edges compare 4-neighbours, then dilate)
            r = max(1, int(self.depth_model.edge_width_px))
            a0, a1, b0, b1 = max(v0 - r, 0), min(v1 + r, H), max(u0 - r, 0), min(u1 + r, W)
            crop = self._crop(camera, a0, a1, b0, b1)
            box = np.s_[v0 - a0:v1 - a0, u0 - b0:u1 - b0]
            gb = render_gbuffer(crop, self.scene, t)
            depth[v0:v1, u0:u1] = depth_mm_from_gbuffer(gb, self.depth_model, rng, image_width_px=W,
                                                           image_height_px=H, image_origin_px=(a0, b0))[box]
            if self.supersample == 1:
                rad = render_radiance(crop, self.scene, t)[box]
            else:
                rad = self._supersampled_radiance(camera, t, v0, v1, u0, u1)
            bgr[v0:v1, u0:u1] = apply_sensor(rad, self.sensor, rng)
        self.n_roi += 1
        return bgr, depth

    def _supersampled_radiance(self, camera, t, v0, v1, u0, u1):
        """Radiance of the box averaged over ``k x k`` samples per pixel (float32, (h, w, 3))."""
        from .camera import PinholeCamera
        from .render import render_radiance
        k = self.supersample
        K = np.array(camera.K, dtype=np.float64)
        Ks = K.copy()
        # sample s of the fine grid sits at u = u0 + (s + 0.5) / k - 0.5 in the full image
        Ks[0, 0], Ks[1, 1], Ks[0, 1] = k * K[0, 0], k * K[1, 1], k * K[0, 1]
        Ks[0, 2] = k * (K[0, 2] - u0 + 0.5) - 0.5
        Ks[1, 2] = k * (K[1, 2] - v0 + 0.5) - 0.5
        h, w = v1 - v0, u1 - u0
        fine = PinholeCamera(K=Ks, dist=camera.dist, width=k * w, height=k * h, T_world_cam=camera.T_world_cam)
        rad = render_radiance(fine, self.scene, t)
        return rad.reshape(h, k, w, k, 3).mean(axis=(1, 3), dtype=np.float32)

    # ---------------------------------------------------------------------------------------
    def _ground_bgr(self, ground_rad, shape, rng):
        """Full frame of noisy ground colour, sampled exactly as :func:`~tudorvision.sim.lighting.apply_sensor`.

        For a constant radiance the sensor output of a pixel is a function of
        the 16-bit index of its normal-table noise sample; the table of the
        65536 outputs per channel is computed by ``apply_sensor`` itself, then
        each pixel draws a uniform 16-bit index (from ``rng.bytes``).
        """
        from .lighting import apply_sensor
        H, W = shape
        key = tuple(np.asarray(ground_rad, np.float32).tolist())
        table = self._tables.get(key)
        if table is None:
            rad = np.broadcast_to(np.asarray(ground_rad, np.float32), (65536, 1, 3))
            noisy = apply_sensor(np.ascontiguousarray(rad), self.sensor, _IndexRng())[:, 0, :]   # (65536, 3) BGR
            clean = apply_sensor(np.ascontiguousarray(rad[:1]), self.sensor, None)[0, 0]
            table = (np.ascontiguousarray(noisy.T), clean)
            if len(self._tables) > 64:
                self._tables.clear()
            self._tables[key] = table
        noisy, clean = table
        if rng is None:
            return np.broadcast_to(clean, (H, W, 3)).copy()
        idx = np.frombuffer(rng.bytes(2 * H * W * 3), dtype="<u2").reshape(3, H, W)
        out = np.empty((H, W, 3), np.uint8)
        for c in range(3):
            np.take(noisy[c], idx[c], out=out[..., c])
        return out

    def _ground_depth_mm(self, camera, ground_albedo, rng):
        """Raw depth (uint16, H x W) of the ground plane with the depth model's validity and noise.

        Same rules as :func:`~tudorvision.sim.render.depth_mm_from_gbuffer`
        (range, dark surfaces, depth edges, sigma_z(z) noise, rounding);
        None when the plane itself would show depth edges (grazing view),
        so that the caller falls back to the full render.
        """
        from .depth_sensor import noise_field, with_pattern
        from .render import depth_sigma_m
        m = self.depth_model
        z = self._ground_depth(camera)
        if not np.all(np.isfinite(z)) or np.any(z <= 0):
            return None
        # relative jump between 4-neighbours on a plane: max(z) * |d(1/z)/du| (resp. dv)
        inv = 1.0 / z
        jump = max(float(np.abs(inv[0, 1] - inv[0, 0])), float(np.abs(inv[1, 0] - inv[0, 0])))
        if jump * float(z.max()) > 0.5 * m.edge_jump_rel:
            return None
        if float(np.mean(ground_albedo)) < m.min_albedo:
            return np.zeros(z.shape, np.uint16)
        all_valid = m.min_depth_m <= float(z.min()) and float(z.max()) <= m.max_depth_m
        valid = True if all_valid else (z >= m.min_depth_m) & (z <= m.max_depth_m)
        zv = z if all_valid else np.where(valid, z, 0.0)
        zv = with_pattern(zv, m, z.shape)
        if rng is not None:
            # float32 is ample before the millimetre rounding and halves the cost of the noise
            z32 = zv.astype(np.float32)
            sigma = depth_sigma_m(z32, m.sigma_coeffs_cm).astype(np.float32)
            sigma *= noise_field(z.shape, rng, m.corr_px_for_width(z.shape[1]), np.float32)
            z32 += sigma
            z32 *= np.float32(m.units_per_m)
            out = np.clip(np.rint(z32), 1, 65535).astype(np.uint16)
        else:
            out = np.clip(np.rint(zv * m.units_per_m), 1, 65535).astype(np.uint16)
        return out if all_valid else np.where(valid, out, 0).astype(np.uint16)


class _IndexRng:
    """Stand-in generator whose 16-bit "random" draws are 0, 1, ..., 65535 along the first axis."""

    def integers(self, low, high, size=None, dtype=np.int64):
        if low != 0 or high != 65536 or size is None or size[0] != 65536:
            raise TypeError("_IndexRng only serves the sensor model's 16-bit table draws")
        idx = np.arange(65536, dtype=dtype).reshape((65536,) + (1,) * (len(size) - 1))
        return np.broadcast_to(idx, size).copy()
