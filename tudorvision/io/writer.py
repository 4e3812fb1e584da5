"""Write recorded sequences in the directory format of :mod:`tudorvision.io.sequence`.

Index files are written line by line as frames arrive (a crashed recording
keeps its frames); :meth:`SequenceWriter.close` writes ``sequence.yaml``.
Depth is always a 16-bit PNG; colour is PNG (lossless) or JPEG (small).

A recording is marked incomplete until it completes: the writer creates an
``INCOMPLETE`` marker file first and removes it only in a successful
:meth:`SequenceWriter.close`. Leaving the ``with`` block by an exception
(Ctrl-C, a full disk) writes ``sequence.yaml`` with ``incomplete: true`` and
``interrupted: "<reason> after N frames"`` and keeps the marker, so
``tudorvision seq check`` reports the sequence as incomplete.
"""
from __future__ import annotations

import math
import re
import shutil
from pathlib import Path

import cv2
import numpy as np

from .._checks import TudorVisionError, check_array
from ._layouts import FRAME_STREAMS, INCOMPLETE_MARKER, KINDS
from ._yaml import dump_yaml, read_yaml
from .atomic import atomic_path, write_error, write_text_atomic
from .calibration import Calibration, load_calibration, save_calibration
from .frames import raw_from_depth_m

__all__ = ["SequenceWriter"]


class SequenceWriter:
    """Write a stereo, RGB-D or mono sequence to ``out_dir``.

    Parameters
    ----------
    out_dir : str or Path
        Sequence directory; created. It must be empty or absent unless
        ``overwrite=True``, which removes only the files a previous recording
        writes (:meth:`own_outputs`); a user's other files are kept.
    kind : {"stereo", "rgbd", "mono"}
    rate_hz : float
        Nominal frame rate, Hz.
    depth_scale : float
        Raw depth units per metre (1000: millimetres).
    calibration : Calibration or path, optional
        Saved (a path is validated and copied) as ``calibration.yaml``.
    image_ext : {".png", ".jpg"}
        Colour image format.
    jpeg_quality : int
        JPEG quality 1..100.
    description : str
        Free text for ``sequence.yaml``.
    meta : dict, optional
        Extra YAML-serialisable keys for ``sequence.yaml`` (e.g. seed, scene).
    overwrite : bool
        Allow writing into a non-empty directory.

    Raises
    ------
    TudorVisionError
        ``out_dir`` is not empty (without ``overwrite``) or is a file; an
        image or file cannot be written (disk full, read-only), naming it.

    Examples
    --------
    >>> import tempfile, numpy as np
    >>> d = tempfile.mkdtemp()
    >>> with SequenceWriter(d, kind="rgbd", rate_hz=30.0, depth_scale=1000.0) as w:
    ...     w.add_rgbd(0.0, np.zeros((4, 6, 3), np.uint8), np.full((4, 6), 1.5))
    >>> from tudorvision.io import open_sequence
    >>> float(open_sequence(d)[0].depth_m[0, 0])
    1.5
    """

    def __init__(self, out_dir, *, kind: str, rate_hz: float, depth_scale: float = 1000.0,
                 calibration=None, image_ext: str = ".png", jpeg_quality: int = 90,
                 description: str = "", meta: dict | None = None, overwrite: bool = False):
        if kind not in KINDS:
            raise ValueError(f"kind: expected one of {', '.join(KINDS)}, got {kind!r}")
        for name, v in (("rate_hz", rate_hz), ("depth_scale", depth_scale)):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"{name}: expected a positive number, got {v!r}")
        ext = image_ext.lower()
        if ext not in (".png", ".jpg", ".jpeg"):
            raise ValueError(f"image_ext: expected '.png' or '.jpg', got {image_ext!r}")
        if not 1 <= int(jpeg_quality) <= 100:
            raise ValueError(f"jpeg_quality: expected 1..100, got {jpeg_quality}")
        cal_src = None
        if calibration is not None and not isinstance(calibration, Calibration):
            cal_src = Path(calibration)
            load_calibration(cal_src)  # validate before creating anything
        self.out_dir = Path(out_dir)
        if self.out_dir.exists() and not self.out_dir.is_dir():
            raise TudorVisionError(f"{self.out_dir}: exists and is not a directory")
        if self.out_dir.is_dir() and any(self.out_dir.iterdir()):
            if not overwrite:
                raise TudorVisionError(f"{self.out_dir}: directory is not empty (pass overwrite=True)")
            self._clear()
        try:
            self.out_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise write_error(self.out_dir, exc) from None
        write_text_atomic(self.out_dir / INCOMPLETE_MARKER,
                          "recording in progress or interrupted: this sequence is incomplete\n")
        self.kind = kind
        self.rate_hz = float(rate_hz)
        self.depth_scale = float(depth_scale)
        self.image_ext = ".jpg" if ext == ".jpeg" else ext
        self.jpeg_quality = int(jpeg_quality)
        self.description = description
        self.meta = dict(meta or {})
        reserved = {"kind", "rate_hz", "streams", "depth_scale", "size", "calibration", "groundtruth",
                    "frames", "description", "layout", "video", "sync_tolerance_s", "incomplete", "interrupted"}
        for k in self.meta:
            if k in reserved:
                raise ValueError(f"meta: key {k!r} is reserved for sequence.yaml")
        self._files: dict = {}
        self._last_t: dict = {}
        self._count: dict = {}
        self._size: tuple | None = None
        self._gt: list[str] = []
        self._closed = False
        self._calibration_file = None
        if calibration is not None:
            if isinstance(calibration, Calibration):
                save_calibration(calibration, self.out_dir / "calibration.yaml")
            else:
                with atomic_path(self.out_dir / "calibration.yaml") as tmp:
                    shutil.copyfile(cal_src, tmp)
            self._calibration_file = "calibration.yaml"

    @staticmethod
    def own_outputs(out_dir) -> list[Path]:
        """The files in ``out_dir`` that a recording writes, and only those.

        Index files (``left.txt`` ... ``joints.txt``), ``sequence.yaml``,
        ``calibration.yaml``, the ``INCOMPLETE`` marker, numbered frames
        ``<stream>/NNNNNN.png|jpg`` of the image streams, and the
        ground-truth files listed in the old ``sequence.yaml``. A user's
        other files (even in ``depth/`` or ``groundtruth/``) are not listed.

        Parameters
        ----------
        out_dir : str or Path
            A directory that may hold a previous recording.

        Returns
        -------
        list of Path
            Existing files, in no particular order.
        """
        out_dir = Path(out_dir)
        files = [out_dir / n for n in ("left.txt", "right.txt", "rgb.txt", "depth.txt", "image.txt",
                                       "joints.txt", "sequence.yaml", "calibration.yaml", INCOMPLETE_MARKER)]
        frame = re.compile(r"^\d{6}\.(?:png|jpg)$")
        for stream in ("left", "right", "rgb", "depth", "image"):
            if (out_dir / stream).is_dir() and not (out_dir / stream).is_symlink():
                files += [p for p in (out_dir / stream).iterdir() if frame.match(p.name)]
        try:
            doc, _ = read_yaml(out_dir / "sequence.yaml")
        except TudorVisionError:
            doc = None
        gts = doc.get("groundtruth") if isinstance(doc, dict) else None
        for g in gts if isinstance(gts, list) else []:
            if isinstance(g, str) and re.match(r"^groundtruth/[A-Za-z0-9_-]+\.csv$", g):
                files.append(out_dir / g)
        return [p for p in files if p.is_file() and not p.is_symlink()]

    def _clear(self):
        try:
            for p in self.own_outputs(self.out_dir):
                p.unlink()
            for name in ("left", "right", "rgb", "depth", "image", "groundtruth"):
                d = self.out_dir / name
                if d.is_dir() and not d.is_symlink() and not any(d.iterdir()):
                    d.rmdir()
        except OSError as exc:
            raise write_error(exc.filename or self.out_dir, exc) from None

    # -------------------------------------------------------------- context manager
    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.close()
            return
        first = str(exc).splitlines()[0] if str(exc) else ""
        reason = "interrupted (Ctrl-C)" if issubclass(exc_type, KeyboardInterrupt) else \
            f"stopped by an error ({exc_type.__name__}: {first})"
        try:
            self.close(interrupted=reason)
        except (TudorVisionError, OSError):
            pass   # the INCOMPLETE marker is still there; the original exception goes on

    # -------------------------------------------------------------- helpers
    def _check_open(self):
        if self._closed:
            raise TudorVisionError(f"{self.out_dir}: writer is closed")

    def _check_kind(self, want):
        if self.kind != want:
            raise ValueError(f"add_{want}: this writer records kind {self.kind!r}")

    def _index(self, stream: str, header: str):
        f = self._files.get(stream)
        if f is None:
            f = open(self.out_dir / f"{stream}.txt", "w", encoding="utf-8")
            f.write(header)
            self._files[stream] = f
        return f

    def _check_t(self, stream: str, t) -> float:
        if isinstance(t, bool) or not isinstance(t, (int, float, np.floating, np.integer)) \
                or not math.isfinite(float(t)):
            raise ValueError(f"t: expected a finite timestamp in seconds, got {t!r}")
        t = float(t)
        last = self._last_t.get(stream)
        if last is not None and t <= last:
            raise ValueError(f"t: timestamps of stream {stream!r} must increase, got {t!r} after {last!r}")
        self._last_t[stream] = t
        return t

    def _check_image(self, img, name, *, depth=False) -> np.ndarray:
        a = np.asarray(img)
        if depth:
            if a.ndim != 2:
                raise ValueError(f"{name}: expected shape (H, W), got {a.shape}")
        elif not (a.ndim == 2 or (a.ndim == 3 and a.shape[2] == 3)):
            raise ValueError(f"{name}: expected shape (H, W, 3) or (H, W), got {a.shape}")
        if not depth and a.dtype != np.uint8:
            raise ValueError(f"{name}: expected dtype uint8, got {a.dtype}")
        size = (a.shape[1], a.shape[0])
        if self._size is None:
            self._size = size
        elif size != self._size:
            raise ValueError(f"{name}: image is {size[0]}x{size[1]}, the sequence is "
                             f"{self._size[0]}x{self._size[1]}")
        return a

    def _write_image(self, stream: str, t: float, img: np.ndarray, *, depth=False) -> None:
        k = self._count.get(stream, 0)
        ext = ".png" if depth else self.image_ext
        rel = f"{stream}/{k:06d}{ext}"
        (self.out_dir / stream).mkdir(exist_ok=True)
        params = [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality] if ext == ".jpg" else \
            [cv2.IMWRITE_PNG_COMPRESSION, 1]  # level 1: ~2x faster than 3, ~same size
        ok, buf = cv2.imencode(ext, np.ascontiguousarray(img), params)
        if not ok:
            raise TudorVisionError(f"{self.out_dir / rel}: cannot encode image")
        try:
            buf.tofile(str(self.out_dir / rel))
        except OSError as exc:
            raise write_error(self.out_dir / rel, exc) from None
        what = {"left": "left camera images", "right": "right camera images", "rgb": "colour images (BGR)",
                "depth": f"16-bit depth images, {self.depth_scale:g} units per metre, 0 = invalid",
                "image": "images"}[stream]
        f = self._index(stream, f"# {what}\n# timestamp filename\n")
        f.write(f"{t:.6f} {rel}\n")
        self._count[stream] = k + 1

    # -------------------------------------------------------------- public API
    def add_stereo(self, t: float, left_bgr, right_bgr) -> None:
        """Add a stereo pair: (H, W, 3) uint8 BGR (or grey) images taken at ``t`` seconds.

        Parameters
        ----------
        t : float
            Timestamp, seconds; strictly increasing from frame to frame.
        left_bgr, right_bgr : ndarray, shape (H, W, 3) or (H, W), uint8
            Left and right camera images (BGR colour or grey), taken
            together; the same size as every image of the sequence.

        Raises
        ------
        ValueError
            If the writer records another kind, an image has the wrong shape
            or dtype or another size than the sequence's first image, or
            ``t`` is not finite or does not increase.
        TudorVisionError
            If the writer is closed or an image cannot be encoded or written.
        """
        self._check_open()
        self._check_kind("stereo")
        left = self._check_image(left_bgr, "left_bgr")
        right = self._check_image(right_bgr, "right_bgr")
        t = self._check_t("frames", t)
        self._write_image("left", t, left)
        self._write_image("right", t, right)

    def add_rgbd(self, t: float, bgr, depth) -> None:
        """Add a colour + registered depth frame.

        Parameters
        ----------
        t : float
            Timestamp, seconds; strictly increasing from frame to frame.
        bgr : ndarray, shape (H, W, 3), uint8
            Colour image, BGR channel order, registered to ``depth``.
        depth : ndarray, shape (H, W)
            uint16 raw units (``depth_scale`` per metre), or float metres
            (NaN / <= 0 = invalid), converted with :func:`raw_from_depth_m`.

        Raises
        ------
        ValueError
            If the writer records another kind, ``bgr`` is not (H, W, 3)
            uint8, ``depth`` is neither uint16 nor float, the sizes differ
            from the sequence's first image, or ``t`` is not finite or does
            not increase.
        TudorVisionError
            If the writer is closed or an image cannot be encoded or written.
        """
        self._check_open()
        self._check_kind("rgbd")
        img = self._check_image(bgr, "bgr")
        if img.ndim != 3:
            raise ValueError(f"bgr: expected shape (H, W, 3), got {img.shape}")
        d = np.asarray(depth)
        if d.dtype == np.uint16:
            raw = d
        elif np.issubdtype(d.dtype, np.floating):
            raw = raw_from_depth_m(d, self.depth_scale)
        else:
            raise ValueError(f"depth: expected uint16 raw units or float metres, got dtype {d.dtype}")
        raw = self._check_image(raw, "depth", depth=True)
        t = self._check_t("frames", t)
        self._write_image("rgb", t, img)
        self._write_image("depth", t, raw, depth=True)

    def add_mono(self, t: float, image) -> None:
        """Add one image ((H, W, 3) uint8 BGR or (H, W) uint8 grey) at ``t`` seconds.

        Parameters
        ----------
        t : float
            Timestamp, seconds; strictly increasing from frame to frame.
        image : ndarray, shape (H, W, 3) or (H, W), uint8
            BGR colour or grey image; the same size as every image of the
            sequence.

        Raises
        ------
        ValueError
            If the writer records another kind, an image has the wrong shape
            or dtype or another size than the sequence's first image, or
            ``t`` is not finite or does not increase.
        TudorVisionError
            If the writer is closed or an image cannot be encoded or written.
        """
        self._check_open()
        self._check_kind("mono")
        img = self._check_image(image, "image")
        t = self._check_t("frames", t)
        self._write_image("image", t, img)

    def add_joints(self, t: float, theta) -> None:
        """Log joint angles ``theta`` (3,) in radians at ``t`` seconds to ``joints.txt``.

        Parameters
        ----------
        t : float
            Timestamp, seconds (the clock of the image timestamps); strictly
            increasing from sample to sample.
        theta : array_like, shape (3,)
            Joint angles ``theta1, theta2, theta3``, radians.

        Raises
        ------
        ValueError
            If ``theta`` is not three finite numbers, or ``t`` is not finite
            or does not increase.
        TudorVisionError
            If the writer is closed.
        """
        self._check_open()
        th = check_array(theta, "theta", (3,))
        t = self._check_t("joints", t)
        f = self._index("joints", "# joint angles\n# timestamp theta1 theta2 theta3 (radians)\n")
        f.write(f"{t:.6f} {th[0]:.9g} {th[1]:.9g} {th[2]:.9g}\n")

    def write_groundtruth(self, name: str, columns, *, comment: str = "") -> Path:
        """Write ``groundtruth/<name>.csv``.

        Parameters
        ----------
        name : str
            Table name (letters, digits, ``_``, ``-``).
        columns : dict of str to array_like (N,), or (names, ndarray (N, K))
            Column names and values (SI units; put the unit in the name,
            e.g. ``p_base_x_m``).
        comment : str
            Comment lines at the top of the file.

        Returns
        -------
        Path
            The written file, ``<out_dir>/groundtruth/<name>.csv``.

        Raises
        ------
        ValueError
            If ``name`` or a column name is invalid, or the columns differ in
            length.
        TudorVisionError
            If the writer is closed or the file cannot be written.
        """
        self._check_open()
        if not name or not all(c.isalnum() or c in "_-" for c in name):
            raise ValueError(f"name: expected letters, digits, '_' or '-', got {name!r}")
        if isinstance(columns, dict):
            names = list(columns)
            cols = [np.asarray(v, dtype=np.float64).ravel() for v in columns.values()]
            n = {c.size for c in cols}
            if len(n) > 1:
                raise ValueError(f"columns: all columns must have the same length, got "
                                 f"{dict(zip(names, [c.size for c in cols]))}")
            data = np.column_stack(cols) if cols else np.zeros((0, 0))
        else:
            names, data = columns
            names = list(names)
            data = np.asarray(data, dtype=np.float64)
            if data.ndim == 1:
                data = data[:, None]
            if data.ndim != 2 or data.shape[1] != len(names):
                raise ValueError(f"columns: expected an (N, {len(names)}) array, got {data.shape}")
        for c in names:
            if not isinstance(c, str) or not c or any(ch in c for ch in ", \t\n#"):
                raise ValueError(f"columns: bad column name {c!r}")
        path = self.out_dir / "groundtruth" / f"{name}.csv"
        lines = [f"# {line}" for line in comment.splitlines()] + [",".join(names)]
        lines += [",".join(repr(float(v)) for v in row) for row in data]
        write_text_atomic(path, "\n".join(lines) + "\n")
        rel = f"groundtruth/{name}.csv"
        if rel not in self._gt:
            self._gt.append(rel)
        return path

    @property
    def frame_count(self) -> int:
        """Frames written so far."""
        return self._count.get(FRAME_STREAMS[self.kind][0], 0)

    def close(self, *, interrupted: str | None = None) -> Path:
        """Flush the index files and write ``sequence.yaml``. Idempotent.

        Parameters
        ----------
        interrupted : str, optional
            Why the recording stopped early. Then ``sequence.yaml`` gets
            ``incomplete: true`` and ``interrupted: "<reason> after N
            frames"``, and the ``INCOMPLETE`` marker stays; without it the
            marker is removed (the recording is complete).

        Returns
        -------
        Path
            The written ``sequence.yaml``.

        Raises
        ------
        TudorVisionError
            ``sequence.yaml`` cannot be written (naming it).
        """
        ypath = self.out_dir / "sequence.yaml"
        if self._closed:
            return ypath
        for f in self._files.values():
            try:
                f.close()
            except OSError as exc:
                if interrupted is None:
                    raise write_error(f.name, exc) from None
        self._closed = True
        streams = [s for s in FRAME_STREAMS[self.kind]]
        if "joints" in self._files:
            streams.append("joints")
        if self.kind == "mono" and self.frame_count == 0:
            write_text_atomic(self.out_dir / "image.txt", "# images\n# timestamp filename\n")
        for s in FRAME_STREAMS[self.kind]:
            idx = self.out_dir / f"{s}.txt"
            if not idx.exists():
                write_text_atomic(idx, "# timestamp filename\n")
        doc = {"kind": self.kind, "rate_hz": self.rate_hz, "streams": streams}
        if self.kind == "rgbd":
            doc["depth_scale"] = self.depth_scale
        if self._size is not None:
            doc["size"] = list(self._size)
        if self._calibration_file:
            doc["calibration"] = self._calibration_file
        if self._gt:
            doc["groundtruth"] = list(self._gt)
        doc["frames"] = self.frame_count
        doc["description"] = self.description
        doc.update(self.meta)
        marker = self.out_dir / INCOMPLETE_MARKER
        if interrupted is not None:
            doc["incomplete"] = True
            doc["interrupted"] = f"{interrupted} after {self.frame_count} frames"
            write_text_atomic(marker, f"{doc['interrupted']}\n")
        write_text_atomic(ypath, "# tudorvision recorded sequence (see docs/sequence_format.md)\n"
                          + dump_yaml(doc))
        if interrupted is None:
            try:
                marker.unlink(missing_ok=True)
            except OSError as exc:
                raise write_error(marker, exc) from None
        return ypath
