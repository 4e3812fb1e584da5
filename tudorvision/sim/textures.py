"""Image textures on rectangles: photographs (or procedural noise) as floor, wall and background albedo.

A :class:`TexturedRectangle` is a :class:`~tudorvision.sim.shapes.Rectangle`
whose albedo is looked up (nearest texel) in a linear-RGB image stretched
over ``texture_size_m`` and tiled beyond it. Photographs are sRGB-encoded
8-bit images; :func:`albedo_from_bgr` decodes them to linear reflectance.
:func:`procedural_texture` is the fallback when no photograph is available.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import check_array
from .shapes import Rectangle

__all__ = ["TexturedRectangle", "albedo_from_bgr", "procedural_texture", "load_texture_crop"]


def albedo_from_bgr(image_bgr, *, max_albedo: float = 0.85) -> np.ndarray:
    """Linear-RGB albedo from an 8-bit sRGB BGR image (gamma 2.2), scaled so the 99th percentile is ``max_albedo``.

    Parameters
    ----------
    image_bgr : ndarray, shape (H, W, 3), uint8
        Photograph crop, OpenCV BGR order.
    max_albedo : float
        Reflectance given to the image's 99th-percentile value (0 < x <= 1).

    Returns
    -------
    ndarray, shape (H, W, 3), float32
        Linear RGB albedo in [0, 1].

    Raises
    ------
    ValueError
        If the image is not (H, W, 3) or ``max_albedo`` is out of range.

    Examples
    --------
    >>> a = albedo_from_bgr(np.full((2, 2, 3), 255, np.uint8), max_albedo=0.5)
    >>> float(a.max())
    0.5
    """
    img = np.asarray(image_bgr)
    if img.ndim != 3 or img.shape[2] != 3 or img.shape[0] < 1 or img.shape[1] < 1:
        raise ValueError(f"image_bgr: expected shape (H, W, 3), got {img.shape}")
    if not 0 < max_albedo <= 1:
        raise ValueError(f"max_albedo: expected in (0, 1], got {max_albedo!r}")
    lin = (img[..., ::-1].astype(np.float32) / 255.0) ** 2.2
    top = float(np.percentile(lin, 99))
    scale = max_albedo / top if top > 1e-6 else 1.0
    return np.clip(lin * scale, 0.0, 1.0).astype(np.float32)


def procedural_texture(rng: np.random.Generator, size_px: int = 128) -> np.ndarray:
    """Smooth random colour texture (blurred noise over a random base colour), linear RGB.

    Parameters
    ----------
    rng : numpy.random.Generator
        Chooses the base colour and the noise.
    size_px : int
        Side of the square texture, pixels (>= 8).

    Returns
    -------
    ndarray, shape (size_px, size_px, 3), float32
        Linear RGB albedo in [0.02, 0.9].

    Examples
    --------
    >>> procedural_texture(np.random.default_rng(0), 16).shape
    (16, 16, 3)
    """
    import cv2
    if int(size_px) != size_px or size_px < 8:
        raise ValueError(f"size_px: expected an integer >= 8, got {size_px!r}")
    n = int(size_px)
    base = rng.uniform(0.15, 0.6, 3)
    noise = rng.standard_normal((n, n, 3)).astype(np.float32)
    smooth = cv2.GaussianBlur(noise, (0, 0), sigmaX=n / 16)
    smooth /= max(float(smooth.std()), 1e-6)
    fine = cv2.GaussianBlur(rng.standard_normal((n, n, 1)).astype(np.float32), (0, 0), 1.0)
    tex = base * (1.0 + 0.25 * smooth + 0.1 * fine[..., None].reshape(n, n, 1))
    return np.clip(tex, 0.02, 0.9).astype(np.float32)


def load_texture_crop(path, rng: np.random.Generator, *, crop_px: int = 160) -> np.ndarray:
    """A random square crop of a photograph as linear-RGB albedo.

    Parameters
    ----------
    path : str or Path
        Image file readable by OpenCV (8-bit colour).
    rng : numpy.random.Generator
        Chooses the crop position.
    crop_px : int
        Side of the crop, pixels (clipped to the image size).

    Returns
    -------
    ndarray, shape (S, S, 3), float32
        Linear RGB albedo (see :func:`albedo_from_bgr`).

    Raises
    ------
    ValueError
        If the file cannot be read as a colour image.
    """
    import cv2
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise ValueError(f"path: cannot read an image from {str(path)!r}")
    s = int(min(crop_px, img.shape[0], img.shape[1]))
    v0 = int(rng.integers(0, img.shape[0] - s + 1))
    u0 = int(rng.integers(0, img.shape[1] - s + 1))
    return albedo_from_bgr(img[v0:v0 + s, u0:u0 + s])


@dataclass(frozen=True, kw_only=True, eq=False)
class TexturedRectangle(Rectangle):
    """A rectangle whose albedo is an image, tiled every ``texture_size_m`` along u and v.

    Parameters
    ----------
    texture_rgb : ndarray, shape (Ht, Wt, 3)
        Linear RGB albedo in [0, 1]; texel (0, 0) sits at the ``(-u, -v)``
        corner, columns run along ``axis_u`` and rows along ``axis_v``.
    texture_size_m : tuple of 2 floats
        Size covered by one copy of the texture along u and v, metres (> 0).
    center, axis_u, axis_v, half_size, color_rgb, name
        As :class:`~tudorvision.sim.shapes.Rectangle` (``color_rgb`` unused
        for shading; checker options must stay unset).

    Raises
    ------
    ValueError
        If the texture is not an (H, W, 3) image in [0, 1] or a size is not positive.

    Examples
    --------
    >>> tex = np.zeros((2, 2, 3)); tex[:, 1] = 1.0
    >>> r = TexturedRectangle(texture_rgb=tex, texture_size_m=(1.0, 1.0), half_size=(0.5, 0.5))
    >>> r.albedo(np.array([[-0.25, 0.0, 0.0], [0.25, 0.0, 0.0]]))[:, 0].tolist()
    [0.0, 1.0]
    """

    texture_rgb: np.ndarray = None
    texture_size_m: tuple = (1.0, 1.0)

    def __post_init__(self):
        super().__post_init__()
        tex = check_array(self.texture_rgb, "texture_rgb", (None, None, 3))
        if tex.min() < 0 or tex.max() > 1:
            raise ValueError("texture_rgb: expected linear RGB in [0, 1]")
        size = check_array(self.texture_size_m, "texture_size_m", (2,))
        if np.any(~(size > 0)):
            raise ValueError(f"texture_size_m: expected positive values, got {size.tolist()}")
        if self.checker_square_m is not None:
            raise ValueError("checker_square_m: a textured rectangle has no checker")
        object.__setattr__(self, "texture_rgb", np.ascontiguousarray(tex, dtype=np.float32))
        object.__setattr__(self, "texture_size_m", size)

    def albedo(self, p):
        """Texel albedo at points on the rectangle (nearest texel, tiled).

        Parameters
        ----------
        p : ndarray, shape (N, 3)
            Points on the rectangle, metres, world frame.

        Returns
        -------
        ndarray, shape (N, 3)
            Linear RGB albedo in [0, 1] per point.
        """
        rel = np.asarray(p, float) - self.center
        a = rel @ self.axis_u + self.half_size[0] if np.isfinite(self.half_size[0]) else rel @ self.axis_u
        b = rel @ self.axis_v + self.half_size[1] if np.isfinite(self.half_size[1]) else rel @ self.axis_v
        h, w = self.texture_rgb.shape[:2]
        col = np.floor(a / self.texture_size_m[0] * w).astype(np.int64) % w
        row = np.floor(b / self.texture_size_m[1] * h).astype(np.int64) % h
        return self.texture_rgb[row, col].astype(np.float64)
