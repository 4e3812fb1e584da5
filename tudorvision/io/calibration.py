"""The project's calibration file: cameras, stereo extrinsics, transforms, depth model.

File format (YAML, SI units, named frames)::

    format: tudorvision-calibration
    version: 1
    cameras:
      left:                      # any name: left, right, rgbd, hand, ...
        width: 640               # pixels
        height: 480
        K: [[700.0, 0.0, 319.5], [0.0, 700.0, 239.5], [0.0, 0.0, 1.0]]
        dist: [k1, k2, p1, p2, k3]        # OpenCV / plumb_bob order
        line_time_s: 3.0e-05              # optional, rolling shutter row time
        T_ref_cam: [[...], ...]           # optional 4x4, camera -> rig reference
    stereo:                      # optional
      left: left                 # camera names
      right: right
      R: [[...], ...]            # x_right = R @ x_left + T  (OpenCV convention)
      T: [tx, ty, tz]            # metres
      rectification: {R1: ..., R2: ..., P1: ..., P2: ..., Q: ...}   # optional
    transforms:                  # optional, 4x4, name T_<to>_<from>
      T_base_left: [[...], ...]  # p_base = T_base_left @ p_left
      T_ee_cam: [[...], ...]     # hand-eye
    depth_model:                 # optional: sigma_z(z) polynomial, highest power first
      sigma_z_poly: [0.51, -2.1, 5.12, -2.18]
      z_unit: m
      sigma_unit: cm
      valid_range_m: [0.6, 6.0]
    circle_rmse_m: 0.0482        # optional
    metadata: {}                 # free

``load_calibration`` / ``save_calibration`` round-trip this exactly (to float
precision). :meth:`Calibration.with_updates` and :meth:`Calibration.merge`
make partial updates easy (a calibration command adding ``T_base_left``).
"""
from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

import numpy as np

from .._checks import TudorVisionError, check_transform
from ._yaml import YamlContext as _Ctx
from ._yaml import dump_yaml, read_yaml
from .atomic import write_text_atomic
from .camera_models import (RECTIFICATION_SHAPES, CameraModel, DepthModel, StereoExtrinsics, frozen_array,
                            optional_allclose)

__all__ = ["CameraModel", "StereoExtrinsics", "DepthModel", "Calibration",
           "load_calibration", "save_calibration"]

FORMAT_NAME = "tudorvision-calibration"


_T_NAME = re.compile(r"^T_[A-Za-z0-9]+(?:_[A-Za-z0-9]+)+$")


@dataclass(frozen=True, kw_only=True, eq=False)
class Calibration:
    """Everything calibrated about the lab's cameras, in SI units.

    Parameters
    ----------
    cameras : mapping of str to CameraModel
        Cameras by name (``left``, ``right``, ``rgbd``, ``hand``, ...).
    stereo : StereoExtrinsics, optional
        Stereo pair geometry.
    transforms : mapping of str to ndarray (4, 4)
        Named rigid transforms ``T_<to>_<from>``, e.g. ``T_base_left``
        (``p_base = T_base_left @ p_left``) or ``T_ee_cam`` (hand-eye).
    depth_model : DepthModel, optional
        RGB-D depth noise model.
    circle_rmse_m : float, optional
        RMSE of the base-frame circle fit, metres.
    metadata : mapping
        Free information (date, source, notes); must be YAML-serialisable.

    Examples
    --------
    >>> cam = CameraModel(K=np.diag([500.0, 500.0, 1.0]), width=64, height=48)
    >>> cal = Calibration(cameras={"rgbd": cam})
    >>> cal2 = cal.with_updates(transforms={"T_base_rgbd": np.eye(4)})
    >>> sorted(cal2.transforms), sorted(cal.transforms)
    (['T_base_rgbd'], [])
    """

    cameras: Mapping[str, CameraModel] = field(default_factory=dict)
    stereo: StereoExtrinsics | None = None
    transforms: Mapping[str, np.ndarray] = field(default_factory=dict)
    depth_model: DepthModel | None = None
    circle_rmse_m: float | None = None
    metadata: Mapping = field(default_factory=dict)

    def __post_init__(self):
        cams = dict(self.cameras)
        for name, cam in cams.items():
            if not isinstance(cam, CameraModel):
                raise ValueError(f"cameras[{name!r}]: expected a CameraModel, got {type(cam).__name__}")
        object.__setattr__(self, "cameras", MappingProxyType(cams))
        if self.stereo is not None:
            if not isinstance(self.stereo, StereoExtrinsics):
                raise ValueError("stereo: expected a StereoExtrinsics")
            for side in (self.stereo.left, self.stereo.right):
                if side not in cams:
                    raise ValueError(f"stereo: camera {side!r} is not in cameras {sorted(cams)}")
        trans = {}
        for name, T in dict(self.transforms).items():
            if not _T_NAME.match(str(name)):
                raise ValueError(f"transforms: name {name!r} must read T_<to>_<from>, e.g. T_base_left")
            trans[str(name)] = frozen_array(check_transform(T, name))
        object.__setattr__(self, "transforms", MappingProxyType(trans))
        if self.depth_model is not None and not isinstance(self.depth_model, DepthModel):
            raise ValueError("depth_model: expected a DepthModel")
        if self.circle_rmse_m is not None:
            object.__setattr__(self, "circle_rmse_m", float(self.circle_rmse_m))
        object.__setattr__(self, "metadata", MappingProxyType(dict(self.metadata)))

    def camera(self, name: str) -> CameraModel:
        """The camera called ``name``; ``TudorVisionError`` listing the known names otherwise.

        Parameters
        ----------
        name : str
            Camera name, e.g. ``"left"`` or ``"rgbd"``.

        Returns
        -------
        CameraModel
            The camera.

        Raises
        ------
        TudorVisionError
            If the calibration has no camera ``name``.
        """
        try:
            return self.cameras[name]
        except KeyError:
            raise TudorVisionError(f"no camera {name!r} in calibration (have {sorted(self.cameras)})") from None

    def transform(self, name: str) -> np.ndarray:
        """The transform called ``name`` (e.g. ``"T_base_left"``), shape (4, 4).

        Parameters
        ----------
        name : str
            Transform name ``T_<to>_<from>``.

        Returns
        -------
        ndarray, shape (4, 4)
            A writable copy of the homogeneous transform; ``T_base_left``
            maps left-camera points to the base frame (``p_base = T @
            p_left``), translation in metres.

        Raises
        ------
        TudorVisionError
            If the calibration has no transform ``name``.
        """
        try:
            return np.array(self.transforms[name])
        except KeyError:
            raise TudorVisionError(f"no transform {name!r} in calibration "
                                   f"(have {sorted(self.transforms)})") from None

    def with_updates(self, *, cameras=None, stereo=None, transforms=None, depth_model=None,
                     circle_rmse_m=None, metadata=None) -> "Calibration":
        """A copy with entries added or replaced; ``None`` keeps the current value.

        ``cameras``, ``transforms`` and ``metadata`` are merged key by key
        (new keys win); ``stereo``, ``depth_model`` and ``circle_rmse_m``
        replace the old value.

        Parameters
        ----------
        cameras : mapping of str to CameraModel, optional
            Cameras to add or replace.
        stereo : StereoExtrinsics, optional
            New stereo geometry; its cameras must be in the result.
        transforms : mapping of str to array_like (4, 4), optional
            Transforms ``T_<to>_<from>`` to add or replace (translation in
            metres).
        depth_model : DepthModel, optional
            New depth noise model.
        circle_rmse_m : float, optional
            New base-frame circle fit RMSE, metres.
        metadata : mapping, optional
            Entries to add or replace.

        Returns
        -------
        Calibration
            The updated copy; ``self`` is unchanged.

        Raises
        ------
        ValueError
            If the result is invalid (a transform name not ``T_<to>_<from>``
            or not a rigid transform, stereo cameras missing).
        """
        return Calibration(
            cameras={**self.cameras, **(cameras or {})},
            stereo=stereo if stereo is not None else self.stereo,
            transforms={**self.transforms, **(transforms or {})},
            depth_model=depth_model if depth_model is not None else self.depth_model,
            circle_rmse_m=circle_rmse_m if circle_rmse_m is not None else self.circle_rmse_m,
            metadata={**self.metadata, **(metadata or {})})

    def merge(self, other: "Calibration") -> "Calibration":
        """Combine two calibrations; entries present in ``other`` win.

        Parameters
        ----------
        other : Calibration
            Calibration whose cameras, transforms and metadata are merged
            key by key, and whose stereo, depth model and circle RMSE
            replace those of ``self`` when present.

        Returns
        -------
        Calibration
            The merged copy; neither input is changed.
        """
        return self.with_updates(cameras=other.cameras, stereo=other.stereo,
                                 transforms=other.transforms, depth_model=other.depth_model,
                                 circle_rmse_m=other.circle_rmse_m, metadata=other.metadata)

    def allclose(self, other: "Calibration", atol: float = 1e-9) -> bool:
        """Compare all numeric content with absolute tolerance ``atol``.

        Parameters
        ----------
        other : Calibration
            Calibration to compare with; any other type compares unequal.
        atol : float
            Absolute tolerance on every number (pixels, metres, radians as
            stored).

        Returns
        -------
        bool
            True when both hold the same camera and transform names, the
            same optional parts, equal metadata, and all numbers agree
            within ``atol``.
        """
        if not isinstance(other, Calibration):
            return False
        if sorted(self.cameras) != sorted(other.cameras) or sorted(self.transforms) != sorted(other.transforms):
            return False
        pairs = [(self.stereo, other.stereo), (self.depth_model, other.depth_model)]
        for a, b in pairs:
            if (a is None) != (b is None) or (a is not None and not a.allclose(b, atol)):
                return False
        return (all(self.cameras[n].allclose(other.cameras[n], atol) for n in self.cameras)
                and all(optional_allclose(self.transforms[n], other.transforms[n], atol) for n in self.transforms)
                and optional_allclose(self.circle_rmse_m, other.circle_rmse_m, atol)
                and dict(self.metadata) == dict(other.metadata))

    # ------------------------------------------------------------------ dict form
    def to_dict(self) -> dict:
        """Plain-Python form of the file format (lists, floats, strings).

        Returns
        -------
        dict
            ``format``, ``version``, ``units`` and ``cameras``, plus
            ``stereo``, ``transforms``, ``depth_model``, ``circle_rmse_m``
            and ``metadata`` where present (see the module docstring); SI
            units. :meth:`from_dict` reads it back.
        """
        out: dict = {"format": FORMAT_NAME, "version": 1, "units": {"length": "m", "angle": "rad"},
                     "cameras": {}}
        for name, cam in self.cameras.items():
            c = {"width": cam.width, "height": cam.height, "K": cam.K.tolist(), "dist": cam.dist.tolist()}
            if cam.line_time_s is not None:
                c["line_time_s"] = cam.line_time_s
            if cam.T_ref_cam is not None:
                c["T_ref_cam"] = cam.T_ref_cam.tolist()
            out["cameras"][name] = c
        if self.stereo is not None:
            s = self.stereo
            d = {"left": s.left, "right": s.right, "R": s.R.tolist(), "T": s.T.tolist()}
            rect = {n: getattr(s, n).tolist() for n in RECTIFICATION_SHAPES if getattr(s, n) is not None}
            if rect:
                d["rectification"] = rect
            out["stereo"] = d
        if self.transforms:
            out["transforms"] = {n: T.tolist() for n, T in self.transforms.items()}
        if self.depth_model is not None:
            dm = self.depth_model
            d = {"sigma_z_poly": dm.sigma_z_poly.tolist(), "z_unit": dm.z_unit, "sigma_unit": dm.sigma_unit}
            if dm.valid_range_m is not None:
                d["valid_range_m"] = list(dm.valid_range_m)
            out["depth_model"] = d
        if self.circle_rmse_m is not None:
            out["circle_rmse_m"] = self.circle_rmse_m
        if self.metadata:
            out["metadata"] = dict(self.metadata)
        return out

    @classmethod
    def from_dict(cls, data, *, source="<calibration>", line_of=None) -> "Calibration":
        """Build from the plain-Python file form; errors name ``source`` and the line.

        Parameters
        ----------
        data : dict
            The file form (see :meth:`to_dict` and the module docstring),
            SI units.
        source : str or Path
            File name (or other label) the errors start with.
        line_of : callable, optional
            ``line_of(keys) -> int or None``, the 1-based line of the value
            at a key path (as returned by the YAML reader); errors then name
            the line.

        Returns
        -------
        Calibration
            The validated calibration.

        Raises
        ------
        TudorVisionError
            If a key is unknown, a value has the wrong type or shape, units
            are not SI, or the content is inconsistent; the message names
            ``source``, the line and the key path.

        Examples
        --------
        >>> cam = CameraModel(K=np.diag([500.0, 500.0, 1.0]), width=64, height=48)
        >>> cal = Calibration(cameras={"rgbd": cam}, transforms={"T_base_rgbd": np.eye(4)})
        >>> Calibration.from_dict(cal.to_dict()).allclose(cal)
        True
        """
        ctx = _Ctx(source, line_of)
        if not isinstance(data, dict):
            raise ctx.error((), "expected a mapping at the top level")
        fmt = data.get("format", FORMAT_NAME)
        if fmt != FORMAT_NAME:
            raise ctx.error(("format",), f"expected {FORMAT_NAME!r}, got {fmt!r}")
        known = {"format", "version", "units", "cameras", "stereo", "transforms", "depth_model",
                 "circle_rmse_m", "metadata"}
        for key in data:
            if key not in known:
                raise ctx.error((key,), f"unknown key (known: {', '.join(sorted(known))})")
        units = data.get("units") or {}
        if not isinstance(units, dict) or units.get("length", "m") != "m" or units.get("angle", "rad") != "rad":
            raise ctx.error(("units",), "only SI units (length: m, angle: rad) are supported")
        cams = {}
        raw_cams = data.get("cameras") or {}
        if not isinstance(raw_cams, dict):
            raise ctx.error(("cameras",), "expected a mapping of camera name to camera")
        for name, c in raw_cams.items():
            keys = ("cameras", name)
            if not isinstance(c, dict):
                raise ctx.error(keys, "expected a mapping with width, height, K, dist")
            for req in ("width", "height", "K"):
                if req not in c:
                    raise ctx.error(keys, f"missing {req!r}")
            try:
                cams[str(name)] = CameraModel(
                    K=ctx.array(c["K"], keys + ("K",), (3, 3)),
                    dist=ctx.array(c.get("dist", [0.0] * 5), keys + ("dist",), (5,)),
                    width=c["width"], height=c["height"], line_time_s=c.get("line_time_s"),
                    T_ref_cam=None if c.get("T_ref_cam") is None
                    else ctx.transform(c["T_ref_cam"], keys + ("T_ref_cam",)))
            except (ValueError, TypeError) as exc:
                if isinstance(exc, TudorVisionError):
                    raise
                raise ctx.error(keys, str(exc)) from None
        stereo = None
        if data.get("stereo") is not None:
            s = data["stereo"]
            if not isinstance(s, dict) or "R" not in s or "T" not in s:
                raise ctx.error(("stereo",), "expected a mapping with R and T")
            rect = s.get("rectification") or {}
            kw = {n: ctx.array(rect[n], ("stereo", "rectification", n), shp)
                  for n, shp in RECTIFICATION_SHAPES.items() if n in rect}
            try:
                stereo = StereoExtrinsics(R=ctx.array(s["R"], ("stereo", "R"), (3, 3)),
                                          T=ctx.array(s["T"], ("stereo", "T"), (3,)),
                                          left=str(s.get("left", "left")),
                                          right=str(s.get("right", "right")), **kw)
            except ValueError as exc:
                if isinstance(exc, TudorVisionError):
                    raise
                raise ctx.error(("stereo",), str(exc)) from None
        trans = {}
        raw_t = data.get("transforms") or {}
        if not isinstance(raw_t, dict):
            raise ctx.error(("transforms",), "expected a mapping of name to 4x4 matrix")
        for name, T in raw_t.items():
            trans[str(name)] = ctx.transform(T, ("transforms", name))
        dm = None
        if data.get("depth_model") is not None:
            d = data["depth_model"]
            if not isinstance(d, dict) or "sigma_z_poly" not in d:
                raise ctx.error(("depth_model",), "expected a mapping with sigma_z_poly")
            try:
                dm = DepthModel(sigma_z_poly=ctx.array(d["sigma_z_poly"], ("depth_model", "sigma_z_poly"),
                                                       (None,)),
                                z_unit=d.get("z_unit", "m"), sigma_unit=d.get("sigma_unit", "m"),
                                valid_range_m=d.get("valid_range_m"))
            except ValueError as exc:
                if isinstance(exc, TudorVisionError):
                    raise
                raise ctx.error(("depth_model",), str(exc)) from None
        rmse = data.get("circle_rmse_m")
        if rmse is not None and (isinstance(rmse, bool) or not isinstance(rmse, (int, float))):
            raise ctx.error(("circle_rmse_m",), f"expected a number in metres, got {rmse!r}")
        meta = data.get("metadata") or {}
        if not isinstance(meta, dict):
            raise ctx.error(("metadata",), "expected a mapping")
        try:
            return cls(cameras=cams, stereo=stereo, transforms=trans, depth_model=dm,
                       circle_rmse_m=rmse, metadata=meta)
        except ValueError as exc:
            if isinstance(exc, TudorVisionError):
                raise
            raise ctx.error((), str(exc)) from None


def load_calibration(path) -> Calibration:
    """Read a calibration file in the project's YAML format.

    Parameters
    ----------
    path : str or Path
        The ``.yaml`` file.

    Returns
    -------
    Calibration

    Raises
    ------
    TudorVisionError
        If the file is absent, not valid YAML, or has wrong content; the
        message names the file, the line and the key.
    """
    data, line_of = read_yaml(Path(path))
    return Calibration.from_dict(data, source=Path(path), line_of=line_of)


def save_calibration(calibration: Calibration, path, *, header: str | None = None) -> Path:
    """Write ``calibration`` to ``path`` in the project's YAML format.

    Parameters
    ----------
    calibration : Calibration
        Calibration to write (SI units: metres, radians).
    path : str or Path
        Output file; parent directories are created. Written atomically: a
        failed write leaves a previous file intact.
    header : str, optional
        Comment lines written at the top of the file.

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    TypeError
        If ``calibration`` is not a :class:`Calibration`.
    OSError
        If missing parent folders cannot be created.
    TudorVisionError
        If the file cannot be written (disk full, read-only folder).
    """
    if not isinstance(calibration, Calibration):
        raise TypeError("calibration: expected a Calibration")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = "# tudorvision calibration (SI units: metres, radians)\n"
    if header:
        text += "".join(f"# {line}\n" for line in header.splitlines())
    text += dump_yaml(calibration.to_dict())
    write_text_atomic(path, text)
    return path
