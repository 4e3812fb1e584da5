"""Low-level pieces of the sequence reader: index files, association, image decoding.

Everything here is a pure function on paths and arrays. Errors are reported
as :class:`Problem` records (``where`` is ``file:line`` or a file name); the
caller decides whether a problem raises (strict) or is skipped (lenient).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from .._checks import TudorVisionError
from ._imageheader import DEFAULT_MAX_PIXELS, HEADER_BYTES, check_pixel_limit, image_size_from_header

__all__ = ["Problem", "IndexEntry", "parse_index", "path_inside", "parse_table", "associate", "read_image",
           "ImageProblem", "read_columns"]


@dataclass(frozen=True)
class Problem:
    """One defect found while reading a sequence.

    Attributes
    ----------
    where : str
        ``"path/left.txt:7"`` for an index line, or an image path.
    reason : str
        What is wrong, in words.
    frame : int or None
        Frame index (0-based, into the sequence) when the defect belongs to a frame.
    """

    where: str
    reason: str
    frame: int | None = None

    def __str__(self) -> str:
        return f"{self.where}: {self.reason}"

    def error(self) -> TudorVisionError:
        """The problem as an exception (strict mode)."""
        return TudorVisionError(str(self))


@dataclass(frozen=True)
class IndexEntry:
    """One ``timestamp path`` line of a TUM-style index file.

    Attributes
    ----------
    t : float
        Timestamp in seconds.
    path : Path
        Absolute path of the referenced file (relative paths are resolved
        against the directory of the index file).
    source : Path
        The index file.
    line : int
        1-based line number in ``source``.
    """

    t: float
    path: Path
    source: Path
    line: int

    @property
    def where(self) -> str:
        return f"{self.source}:{self.line}"


class ImageProblem(Exception):
    """Raised by :func:`read_image`; carries the reason only (the caller adds where)."""


def _parse_float(token: str) -> float:
    value = float(token)
    if not math.isfinite(value):
        raise ValueError(token)
    return value


def path_inside(name: str) -> bool:
    """Whether an index entry's file name stays inside the index file's folder.

    Lexical test: absolute paths and names whose normalised form climbs out
    with ``..`` are outside (symbolic links are not followed).

    Parameters
    ----------
    name : str
        The file name as written in the index line.

    Returns
    -------
    bool

    Examples
    --------
    >>> path_inside("left/000001.png"), path_inside("../../x.png"), path_inside("/etc/passwd")
    (True, False, False)
    """
    if not name or os.path.isabs(name) or Path(name).anchor:
        return False
    norm = os.path.normpath(name)
    return norm != ".." and not norm.startswith(".." + os.sep) and norm != "."


def parse_index(path: Path, *, check_files: bool = True,
                allow_outside: bool = False) -> tuple[list[IndexEntry], list[Problem]]:
    """Parse a TUM-style index file (``timestamp path`` per line, ``#`` comments).

    Parameters
    ----------
    path : Path
        The index file, e.g. ``left.txt``.
    check_files : bool
        Report lines whose file does not exist.
    allow_outside : bool
        Accept absolute paths and paths climbing out of the index file's
        folder (``../x.png``); by default such lines are problems.

    Returns
    -------
    entries : list of IndexEntry
        The good lines, in file order, with strictly increasing timestamps.
    problems : list of Problem
        Malformed lines, absent files and non-monotonic timestamps, each
        naming ``file:line``; the offending lines are not in ``entries``.

    Raises
    ------
    TudorVisionError
        If the index file itself cannot be read.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise TudorVisionError(f"{path}: index file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise TudorVisionError(f"{path}: cannot read index file ({exc})") from None
    base = path.parent
    entries: list[IndexEntry] = []
    problems: list[Problem] = []
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        where = f"{path}:{lineno}"
        parts = line.split(maxsplit=1)
        if len(parts) != 2:
            problems.append(Problem(where, f"malformed line {raw!r}: expected 'timestamp path'"))
            continue
        try:
            t = _parse_float(parts[0])
        except ValueError:
            problems.append(Problem(where, f"malformed timestamp {parts[0]!r}"))
            continue
        if not allow_outside and not path_inside(parts[1].strip()):
            problems.append(Problem(where, f"file {parts[1].strip()!r} is outside the sequence folder "
                                           "(allow it with --allow-outside / allow_outside=True)"))
            continue
        file = (base / parts[1].strip()).resolve() if not Path(parts[1].strip()).is_absolute() \
            else Path(parts[1].strip())
        if entries and t <= entries[-1].t:
            problems.append(Problem(where, f"timestamp {parts[0]} is not after {entries[-1].t!r} "
                                           f"(line {entries[-1].line}): timestamps must increase"))
            continue
        if check_files and not file.is_file():
            problems.append(Problem(where, f"file {parts[1].strip()!r} does not exist"))
            continue
        entries.append(IndexEntry(t, file, path, lineno))
    return entries, problems


def parse_table(path: Path, ncols: int | None = None, *, monotonic: bool = True
                ) -> tuple[np.ndarray, list[int], list[Problem]]:
    """Parse a whitespace-separated numeric table with ``#`` comments.

    Used for ``joints.txt`` (``timestamp θ1 θ2 θ3``) and TUM ``groundtruth.txt``.

    Parameters
    ----------
    path : Path
        The table file.
    ncols : int, optional
        Required number of columns; by default the first data line decides.
    monotonic : bool
        Require strictly increasing values in the first column.

    Returns
    -------
    rows : ndarray, shape (N, ncols)
        The good rows.
    lines : list of int
        1-based line number of every row.
    problems : list of Problem
        Malformed and out-of-order lines, each naming ``file:line``.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise TudorVisionError(f"{path}: cannot read ({exc})") from None
    rows: list[list[float]] = []
    lines: list[int] = []
    problems: list[Problem] = []
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        where = f"{path}:{lineno}"
        parts = line.replace(",", " ").split()
        try:
            values = [_parse_float(p) for p in parts]
        except ValueError:
            problems.append(Problem(where, f"malformed line {raw!r}: expected numbers"))
            continue
        want = ncols if ncols is not None else (len(rows[0]) if rows else len(values))
        if len(values) != want:
            problems.append(Problem(where, f"malformed line {raw!r}: expected {want} numbers, "
                                           f"got {len(values)}"))
            continue
        if monotonic and rows and values[0] <= rows[-1][0]:
            problems.append(Problem(where, f"timestamp {parts[0]} is not after {rows[-1][0]!r} "
                                           f"(line {lines[-1]}): timestamps must increase"))
            continue
        rows.append(values)
        lines.append(lineno)
    width = ncols if ncols is not None else (len(rows[0]) if rows else 0)
    arr = np.asarray(rows, dtype=np.float64).reshape(len(rows), width)
    return arr, lines, problems


def associate(t_a: np.ndarray, t_b: np.ndarray, max_dt_s: float) -> np.ndarray:
    """Match two sorted timestamp lists one-to-one by nearest time.

    Greedy on the time difference, like the TUM benchmark's association: the
    closest candidate pairs are taken first, each item is used at most once,
    and pairs further apart than ``max_dt_s`` are never matched. Candidates
    are only the two temporal neighbours in ``t_b`` of each item of ``t_a``
    (and vice versa), so it runs in O((N + M) log(N + M)); the result equals
    the exhaustive greedy matching whenever ``max_dt_s`` is smaller than the
    frame spacing of both streams (the usual case: 0.02 s at 30 Hz).

    Parameters
    ----------
    t_a, t_b : ndarray, shape (N,), (M,)
        Increasing timestamps in seconds.
    max_dt_s : float
        Largest accepted time difference.

    Returns
    -------
    ndarray, shape (K, 2), int
        Index pairs ``(i_a, i_b)`` sorted by ``i_a``.

    Examples
    --------
    >>> associate(np.array([0.0, 1.0, 2.0]), np.array([0.01, 1.5, 2.02]), 0.05).tolist()
    [[0, 0], [2, 2]]
    """
    t_a = np.asarray(t_a, dtype=np.float64)
    t_b = np.asarray(t_b, dtype=np.float64)
    if t_a.size == 0 or t_b.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    cands = []
    for src, dst, flip in ((t_a, t_b, False), (t_b, t_a, True)):
        pos = np.searchsorted(dst, src)
        for nb in (pos - 1, pos):
            ok = (nb >= 0) & (nb < dst.size)
            i = np.nonzero(ok)[0]
            j = nb[ok]
            pair = np.column_stack([j, i]) if flip else np.column_stack([i, j])
            cands.append(pair)
    pairs = np.unique(np.concatenate(cands), axis=0)
    dt = np.abs(t_a[pairs[:, 0]] - t_b[pairs[:, 1]])
    keep = dt <= max_dt_s
    pairs, dt = pairs[keep], dt[keep]
    order = np.argsort(dt, kind="stable")
    used_a = np.zeros(t_a.size, bool)
    used_b = np.zeros(t_b.size, bool)
    out = []
    for i, j in pairs[order]:
        if not used_a[i] and not used_b[j]:
            used_a[i] = used_b[j] = True
            out.append((i, j))
    out.sort()
    return np.asarray(out, dtype=np.int64).reshape(-1, 2)


def read_image(path: Path, *, depth: bool = False, max_pixels: int | None = DEFAULT_MAX_PIXELS) -> np.ndarray:
    """Decode an image file without OpenCV's console warnings.

    Parameters
    ----------
    path : Path
        Image file (PNG, JPEG, PGM, ...).
    depth : bool
        Read a depth image: it must decode to a single-channel 16-bit array.
    max_pixels : int or None
        Refuse images whose header (PNG, JPEG, BMP, PNM) declares more
        pixels, before decoding; None: no limit.

    Returns
    -------
    ndarray
        ``(H, W, 3)`` uint8 BGR for colour files, ``(H, W)`` uint8 for grey
        files, ``(H, W)`` uint16 for depth.

    Raises
    ------
    ImageProblem
        If the file is absent, unreadable, corrupt, over ``max_pixels``, or
        (depth) not 16-bit.
    """
    try:
        buf = np.fromfile(str(path), dtype=np.uint8)
    except FileNotFoundError:
        raise ImageProblem("file does not exist") from None
    except OSError as exc:
        raise ImageProblem(f"cannot read file ({exc.strerror or exc})") from None
    if buf.size == 0:
        raise ImageProblem("empty image file")
    too_big = check_pixel_limit(image_size_from_header(buf[:HEADER_BYTES].tobytes()), max_pixels)
    if too_big:
        raise ImageProblem(too_big)
    try:
        img = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    except cv2.error:
        img = None
    if img is None:
        raise ImageProblem("corrupt or unsupported image (cannot decode)")
    if depth:
        if img.ndim != 2 or img.dtype != np.uint16:
            raise ImageProblem(f"depth image must be single-channel 16-bit, got "
                               f"{img.dtype} with shape {img.shape}")
        return img
    if img.dtype != np.uint8:
        img = cv2.convertScaleAbs(img, alpha=255.0 / float(np.iinfo(img.dtype).max)) \
            if np.issubdtype(img.dtype, np.integer) else np.clip(img * 255.0, 0, 255).astype(np.uint8)
    if img.ndim == 3 and img.shape[2] == 4:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
    return img


def read_columns(path: Path, names: list[str] | None = None) -> dict[str, np.ndarray]:
    """Read a numeric table with named columns.

    The file is CSV (``,``) or whitespace separated; ``#`` lines are
    comments. Without ``names`` the first non-comment line is the header of
    column names (the ground-truth files the writer produces).

    Returns
    -------
    dict of str to ndarray, shape (N,)
        One float64 array per column, in file order.

    Raises
    ------
    TudorVisionError
        Unreadable file, or a row with the wrong number of values (names
        ``file:line``).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise TudorVisionError(f"{path}: ground-truth file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise TudorVisionError(f"{path}: cannot read ({exc})") from None
    rows: list[list[float]] = []
    header = list(names) if names is not None else None
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        parts = [p.strip() for p in (line.split(",") if "," in line else line.split())]
        if header is None:
            header = parts
            continue
        try:
            values = [float(p) for p in parts]
        except ValueError:
            raise TudorVisionError(f"{path}:{lineno}: malformed row {raw!r}: expected numbers") from None
        if len(values) != len(header):
            raise TudorVisionError(f"{path}:{lineno}: expected {len(header)} values "
                                   f"({', '.join(header)}), got {len(values)}")
        rows.append(values)
    if header is None:
        raise TudorVisionError(f"{path}: no header line with column names")
    arr = np.asarray(rows, dtype=np.float64).reshape(len(rows), len(header))
    return {name: arr[:, k].copy() for k, name in enumerate(header)}
