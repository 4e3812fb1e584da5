"""Hand-checked ball labels of real video frames: a small CSV format.

One row per labelled frame::

    video,frame,u_px,v_px,r_px,clean,method,note
    ball3.mp4,150,641.5,402.0,28.5,1,auto-checked,

``frame`` is the 0-based decode index, ``u_px``/``v_px`` the ball's image
centre (u right, v down, pixel centres at integers) and ``r_px`` its apparent
radius, all in pixels of the full frame. ``clean`` is 1 for a frame where the
whole ball is in view, mostly unoccluded and sharp (the frames a tracker must
find), 0 otherwise; a frame without a visible ball has ``clean`` 0 and empty
``u_px``, ``v_px``, ``r_px``. ``method`` says how the circle was made:
``auto-checked`` (the labelling helper's proposal, accepted after looking at
the zoomed crop), ``hand-corrected`` (set by hand from the zoomed grid) or
``none`` (no ball). Lines starting with ``#`` are comments.
"""
from __future__ import annotations

import csv
import io as _stdio
import math
from dataclasses import dataclass
from pathlib import Path

from .._checks import TudorVisionError
from .atomic import write_text_atomic

__all__ = ["BallLabel", "LABEL_COLUMNS", "LABEL_METHODS", "read_ball_labels", "write_ball_labels"]

LABEL_COLUMNS = ("video", "frame", "u_px", "v_px", "r_px", "clean", "method", "note")
LABEL_METHODS = ("auto-checked", "hand-corrected", "none")


@dataclass(frozen=True, kw_only=True)
class BallLabel:
    """One labelled frame.

    Parameters
    ----------
    video : str
        File name of the video (no folder).
    frame : int
        0-based decode index.
    u_px, v_px, r_px : float
        Ball centre (u right, v down) and apparent radius in pixels; NaN when
        no ball is visible.
    clean : bool
        The whole ball is in view, at most lightly occluded and not heavily
        blurred.
    method : str
        One of :data:`LABEL_METHODS`.
    note : str
        Free text (why a frame is not clean, what was corrected).

    Raises
    ------
    TudorVisionError
        Negative frame, unknown method, non-positive radius, a clean frame
        without a circle, or a circle given with ``method="none"``.

    Examples
    --------
    >>> BallLabel(video="b.mp4", frame=3, u_px=10.0, v_px=20.0, r_px=5.0, clean=True,
    ...           method="auto-checked").has_circle
    True
    """

    video: str
    frame: int
    u_px: float
    v_px: float
    r_px: float
    clean: bool
    method: str
    note: str = ""

    def __post_init__(self):
        where = f"{self.video} frame {self.frame}"
        if not self.video or "," in self.video:
            raise TudorVisionError(f"video: expected a file name without commas, got {self.video!r}")
        if int(self.frame) != self.frame or self.frame < 0:
            raise TudorVisionError(f"{where}: frame must be a non-negative integer")
        if self.method not in LABEL_METHODS:
            raise TudorVisionError(f"{where}: method must be one of {', '.join(LABEL_METHODS)}, "
                                   f"got {self.method!r}")
        vals = (self.u_px, self.v_px, self.r_px)
        given = [math.isfinite(x) for x in vals]
        if any(given) and not all(given):
            raise TudorVisionError(f"{where}: give all of u_px, v_px, r_px or none of them")
        if all(given) and self.r_px <= 0:
            raise TudorVisionError(f"{where}: r_px must be positive, got {self.r_px:g}")
        if self.clean and not all(given):
            raise TudorVisionError(f"{where}: a clean frame needs a circle (u_px, v_px, r_px)")
        if (self.method == "none") == all(given):
            raise TudorVisionError(f"{where}: method 'none' is for frames without a circle, and only for them")

    @property
    def has_circle(self) -> bool:
        """True when the frame has a labelled circle."""
        return math.isfinite(self.r_px)


def _float(text: str, what: str) -> float:
    text = text.strip()
    if text == "":
        return math.nan
    try:
        value = float(text)
    except ValueError:
        raise TudorVisionError(f"{what}: expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise TudorVisionError(f"{what}: expected a finite number, got {text!r}")
    return value


def read_ball_labels(path) -> list[BallLabel]:
    """Read a ball label CSV.

    Parameters
    ----------
    path : str or Path
        CSV with the header :data:`LABEL_COLUMNS`; ``#`` lines are comments.

    Returns
    -------
    list of BallLabel
        In file order.

    Raises
    ------
    TudorVisionError
        Missing file, wrong header, a malformed row (message names the line),
        or a (video, frame) pair labelled twice.

    Examples
    --------
    >>> import tempfile, os
    >>> p = os.path.join(tempfile.mkdtemp(), "l.csv")
    >>> _ = write_ball_labels(p, [BallLabel(video="b.mp4", frame=0, u_px=1.0, v_px=2.0, r_px=3.0,
    ...                                     clean=True, method="hand-corrected")])
    >>> read_ball_labels(p)[0].r_px
    3.0
    """
    path = Path(path)
    if not path.is_file():
        raise TudorVisionError(f"{path}: label file not found")
    lines = path.read_text(encoding="utf-8").splitlines()
    rows = [(n, line) for n, line in enumerate(lines, start=1) if line.strip() and not line.startswith("#")]
    if not rows:
        raise TudorVisionError(f"{path}: no header line")
    n0, header = rows[0]
    if tuple(h.strip() for h in header.split(",")) != LABEL_COLUMNS:
        raise TudorVisionError(f"{path}:{n0}: expected the header {','.join(LABEL_COLUMNS)}")
    out, seen = [], {}
    for n, line in rows[1:]:
        fields = next(csv.reader([line]))
        where = f"{path}:{n}"
        if len(fields) != len(LABEL_COLUMNS):
            raise TudorVisionError(f"{where}: expected {len(LABEL_COLUMNS)} fields, got {len(fields)}")
        video, frame, u, v, r, clean, method, note = (f.strip() for f in fields)
        try:
            frame_i = int(frame)
        except ValueError:
            raise TudorVisionError(f"{where}: frame: expected an integer, got {frame!r}") from None
        if clean not in ("0", "1"):
            raise TudorVisionError(f"{where}: clean: expected 0 or 1, got {clean!r}")
        try:
            lab = BallLabel(video=video, frame=frame_i, u_px=_float(u, f"{where}: u_px"),
                            v_px=_float(v, f"{where}: v_px"), r_px=_float(r, f"{where}: r_px"),
                            clean=clean == "1", method=method, note=note)
        except TudorVisionError as exc:
            raise TudorVisionError(f"{where}: {exc}") from None
        key = (lab.video, lab.frame)
        if key in seen:
            raise TudorVisionError(f"{where}: {video} frame {frame_i} already labelled on line {seen[key]}")
        seen[key] = n
        out.append(lab)
    return out


def _num(x: float) -> str:
    return "" if not math.isfinite(x) else f"{x:.2f}".rstrip("0").rstrip(".")


def write_ball_labels(path, labels, *, comment: str | None = None) -> Path:
    """Write ball labels as CSV (atomically), sorted by video and frame.

    Parameters
    ----------
    path : str or Path
        Output file.
    labels : iterable of BallLabel
    comment : str, optional
        Written first, each line prefixed with ``# ``.

    Returns
    -------
    Path

    Raises
    ------
    TudorVisionError
        A (video, frame) pair given twice, or the file cannot be written.
    """
    labels = sorted(labels, key=lambda lab: (lab.video, lab.frame))
    keys = [(lab.video, lab.frame) for lab in labels]
    if len(set(keys)) != len(keys):
        dup = next(k for k in keys if keys.count(k) > 1)
        raise TudorVisionError(f"labels: {dup[0]} frame {dup[1]} given twice")
    buf = _stdio.StringIO()
    if comment:
        for line in comment.splitlines():
            buf.write(f"# {line}\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(LABEL_COLUMNS)
    for lab in labels:
        w.writerow([lab.video, lab.frame, _num(lab.u_px), _num(lab.v_px), _num(lab.r_px), int(lab.clean),
                    lab.method, lab.note])
    return write_text_atomic(path, buf.getvalue())
