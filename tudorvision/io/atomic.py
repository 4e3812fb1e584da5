"""Atomic output files: a temporary file in the same folder, then ``os.replace``.

Every result the package writes (trajectory, pixel-track and ball CSVs,
calibration YAML and its ROS / OpenCV exports, colour models, point clouds,
summaries) goes through these helpers, so a full disk, a read-only folder or
a Ctrl-C while writing never leaves a half-written file: the previous file
stays as it was, or no file appears at all. A failed write raises
:class:`~tudorvision._checks.TudorVisionError` naming the file (one line).
"""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from .._checks import TudorVisionError

__all__ = ["atomic_path", "atomic_write", "write_text_atomic", "write_bytes_atomic", "write_error"]


def write_error(path, exc: OSError) -> TudorVisionError:
    """The one-line error for an ``OSError`` raised while writing ``path``.

    Parameters
    ----------
    path : str or Path
        The output file.
    exc : OSError
        What the operating system said (disk full, read-only, ...).

    Returns
    -------
    TudorVisionError
        ``"<path>: cannot write (<reason>)"``.

    Examples
    --------
    >>> import errno
    >>> str(write_error("out.csv", OSError(errno.ENOSPC, "No space left on device")))
    'out.csv: cannot write (no space left on device)'
    """
    reason = exc.strerror or str(exc) or type(exc).__name__
    return TudorVisionError(f"{path}: cannot write ({reason[:1].lower() + reason[1:]})")


@contextlib.contextmanager
def atomic_path(path, *, mkdir: bool = True):
    """Yield a temporary path next to ``path``; on success it replaces ``path``.

    For writers that want a file name (Open3D, ``cv2.imwrite``,
    ``numpy.savez``): write to the yielded path; when the ``with`` block ends
    without an exception the file is moved onto ``path`` with
    ``os.replace``. On any exception the temporary file is removed and
    ``path`` is left untouched.

    Parameters
    ----------
    path : str or Path
        Final file.
    mkdir : bool
        Create missing parent folders first.

    Yields
    ------
    Path
        Temporary file in ``path``'s folder, with ``path``'s suffix (some
        writers choose the format by the suffix).

    Raises
    ------
    TudorVisionError
        If the folder cannot be created or written, the disk is full, or the
        final rename fails; the message names ``path``.
    """
    path = Path(path)
    try:
        if mkdir:
            path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".tmp{path.suffix}",
                                   dir=path.parent if str(path.parent) else ".")
        os.close(fd)
    except OSError as exc:
        raise write_error(path, exc) from None
    tmp = Path(tmp)
    try:
        yield tmp
        _keep_mode(path, tmp)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise write_error(path, exc) from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _keep_mode(path: Path, tmp: Path) -> None:
    """Give the new file the old file's permissions, or the usual umask default."""
    try:
        mode = path.stat().st_mode & 0o7777
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        mode = 0o666 & ~umask
    os.chmod(tmp, mode)


@contextlib.contextmanager
def atomic_write(path, mode: str = "w", *, encoding: str | None = "utf-8", newline: str | None = None,
                 mkdir: bool = True):
    """Open a temporary file for writing; it replaces ``path`` when the block succeeds.

    Parameters
    ----------
    path : str or Path
        Final file.
    mode : {"w", "wb"}
        Text or binary.
    encoding : str or None
        Text encoding (ignored for ``"wb"``).
    newline : str or None
        As for :func:`open` (``""`` for :mod:`csv`).
    mkdir : bool
        Create missing parent folders first.

    Yields
    ------
    file object
        Write to it; it is flushed, ``fsync``-ed and closed before the rename.

    Raises
    ------
    TudorVisionError
        On any ``OSError`` (disk full, read-only folder); ``path`` keeps its
        previous content.

    Examples
    --------
    >>> import tempfile, os
    >>> d = tempfile.mkdtemp()
    >>> with atomic_write(os.path.join(d, "a.txt")) as fh:
    ...     _ = fh.write("one\\n")
    >>> open(os.path.join(d, "a.txt")).read()
    'one\\n'
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"mode: expected 'w' or 'wb', got {mode!r}")
    with atomic_path(path, mkdir=mkdir) as tmp:
        try:
            kw = {} if mode == "wb" else {"encoding": encoding, "newline": newline}
            with open(tmp, mode, **kw) as fh:
                yield fh
                fh.flush()
                os.fsync(fh.fileno())
        except OSError as exc:
            raise write_error(path, exc) from None


def write_text_atomic(path, text: str, *, encoding: str = "utf-8", mkdir: bool = True) -> Path:
    """Write ``text`` to ``path`` atomically.

    Parameters
    ----------
    path : str or Path
        Output file.
    text : str
        Content.
    encoding : str
        Text encoding.
    mkdir : bool
        Create missing parent folders first.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    TudorVisionError
        On any ``OSError``; the previous file stays intact.
    """
    with atomic_write(path, "w", encoding=encoding, mkdir=mkdir) as fh:
        fh.write(text)
    return Path(path)


def write_bytes_atomic(path, data: bytes, *, mkdir: bool = True) -> Path:
    """Write ``data`` to ``path`` atomically.

    Parameters
    ----------
    path : str or Path
        Output file.
    data : bytes
        Content.
    mkdir : bool
        Create missing parent folders first.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    TudorVisionError
        On any ``OSError``; the previous file stays intact.
    """
    with atomic_write(path, "wb", mkdir=mkdir) as fh:
        fh.write(data)
    return Path(path)
