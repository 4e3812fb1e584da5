"""``tudorvision seq info|check|import``: inspect, validate and import recorded sequences.

``seq import SRC --out DIR`` turns anything :func:`tudorvision.io.open_sequence`
reads (a ROS bag, a live stream, a TUM folder, ``left/`` + ``right/``
folders, ...) into the project's sequence layout; ``seq info`` on a bag
also lists its topics, types and message counts.
"""
from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from .._checks import TudorVisionError
from .._progress import progress
from ..io import DEFAULT_MAX_PIXELS

if TYPE_CHECKING:
    from ..io.sequence import Sequence

__all__ = ["register", "scan_sequence", "add_sequence_options", "sequence_options", "problem_lines",
           "partial_flags"]


def _pixels(text: str) -> int:
    try:
        value = int(float(text))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a pixel count like 100000000, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a non-negative pixel count, got {text!r}")
    return value


def add_sequence_options(parser) -> None:
    """Add ``--allow-outside``, ``--max-pixels``, ``--topics``, ``--max-frames`` and ``--timeout`` to a command.

    Every command that reads a sequence takes these, so bags (``--topics``)
    and live sources (``--max-frames``, ``--timeout``) work everywhere.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    """
    parser.add_argument("--allow-outside", action="store_true",
                        help="follow index lines naming absolute paths or files outside the sequence "
                             "folder (../x.png); refused by default")
    parser.add_argument("--max-pixels", type=_pixels, default=DEFAULT_MAX_PIXELS, metavar="N",
                        help=f"refuse images whose header declares more than N pixels, before decoding "
                             f"(default {DEFAULT_MAX_PIXELS}; 0 = no limit)")
    parser.add_argument("--topics", metavar="STREAM=TOPIC,...",
                        help="ROS bags: image topics, left=/a,right=/b or rgb=/c,depth=/d or image=/e "
                             "(default: found automatically when unambiguous; 'seq info BAG' lists them)")
    parser.add_argument("--max-frames", type=_count, default=None, metavar="N",
                        help="live sources (/dev/videoN, rtsp://, http://): stop after N frames "
                             "(default: until the stream ends or Ctrl-C)")
    parser.add_argument("--timeout", type=float, default=5.0, metavar="S",
                        help="live sources: longest wait for a frame, seconds (default 5)")


def _count(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive whole number, got {text!r}")
    return value


def sequence_options(args) -> dict:
    """Keyword arguments of :func:`tudorvision.io.open_sequence` from :func:`add_sequence_options`.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments (missing options take their defaults).

    Returns
    -------
    dict
        ``allow_outside``, ``max_pixels`` (None for no limit), ``topics``,
        ``max_frames`` and ``timeout_s``.
    """
    mp = getattr(args, "max_pixels", DEFAULT_MAX_PIXELS)
    return {"allow_outside": bool(getattr(args, "allow_outside", False)), "max_pixels": mp or None,
            "topics": getattr(args, "topics", None), "max_frames": getattr(args, "max_frames", None),
            "timeout_s": getattr(args, "timeout", None) or 5.0}


def problem_lines(seq) -> list[str]:
    """One line per defect a lenient sequence skipped: ``skipped frame I: FILE: reason``.

    Parameters
    ----------
    seq : Sequence
        A sequence after reading (its :attr:`~tudorvision.io.Sequence.report`).

    Returns
    -------
    list of str
    """
    out = []
    for p in seq.report:
        what = f"skipped frame {p.frame}" if p.frame is not None else "skipped"
        out.append(f"{what}: {p}")
    return out


def partial_flags(n_done: int, interrupted: str | None, problems: list[str], *, limit: int = 50) -> list[str]:
    """Comment lines that flag a partial output; also printed on stderr.

    Parameters
    ----------
    n_done : int
        Frames whose rows were written.
    interrupted : str or None
        Why the run stopped early (Ctrl-C, an error), or None.
    problems : list of str
        Defects skipped (from :func:`problem_lines`).
    limit : int
        Most problem lines kept; the rest are counted.

    Returns
    -------
    list of str
        Without the ``#``; empty for a complete run without defects.

    Examples
    --------
    >>> partial_flags(3, "interrupted (Ctrl-C)", [])
    ['interrupted after 3 frames: interrupted (Ctrl-C)']
    """
    lines = []
    if interrupted:
        lines.append(f"interrupted after {n_done} frames: {interrupted}")
    if problems:
        lines.append(f"partial: {len(problems)} defect(s) skipped")
        lines += problems[:limit]
        if len(problems) > limit:
            lines.append(f"... and {len(problems) - limit} more")
    for line in lines:
        print(line, file=sys.stderr)
    return lines


def register(subparsers) -> None:
    """Add the ``seq`` command with ``info``, ``check`` and ``import`` to ``subparsers``."""
    p = subparsers.add_parser("seq", help="inspect, validate and import recorded sequences",
                              description="Inspect (info), strictly validate (check) or import (import) a "
                                          "sequence: a sequence directory, a TUM RGB-D directory, left/ + "
                                          "right/ or rgb/ + depth/ folders, an image folder, a video file, a "
                                          "ROS 1 bag, a ROS 2 bag folder or .mcap file, or a live source "
                                          "(/dev/videoN, rtsp://, http://; two joined by a comma for stereo).")
    sub = p.add_subparsers(dest="seq_command", metavar="ACTION")
    for name, func, text in (
            ("info", _info, "summary and a lenient scan listing every problem (exit 2 if any)"),
            ("check", _check, "strict validation: exit 2 with the first error as one line")):
        q = sub.add_parser(name, help=text, description=text)
        q.add_argument("sequence", metavar="SEQ", help="sequence directory, sequence.yaml, video file, bag "
                                                        "or live source")
        q.add_argument("--depth-scale", type=float, default=None,
                       help="raw depth units per metre (overrides the sequence)")
        q.add_argument("--rate-hz", type=float, default=None,
                       help="frame rate for folders without timestamps (default 30)")
        q.add_argument("--index-only", action="store_true",
                       help="check the index files only, do not decode images")
        add_sequence_options(q)
        q.set_defaults(func=func)
    q = sub.add_parser("import", help="convert a bag, live stream or foreign folder to a sequence directory",
                       description="Write SRC (anything 'seq info' reads) as a sequence directory in the "
                                   "project's layout: lossless PNG images by default (pixel-exact), the "
                                   "source's timestamps, and its calibration (e.g. a bag's CameraInfo). Frames "
                                   "that cannot be decoded are skipped and listed (exit 2); on Ctrl-C or an "
                                   "error the directory is flagged incomplete (INCOMPLETE marker).")
    q.add_argument("sequence", metavar="SRC", help="bag, .mcap, sequence folder, video or live source")
    q.add_argument("--out", required=True, metavar="DIR", help="sequence directory to write (empty or absent)")
    q.add_argument("--overwrite", action="store_true", help="replace a previous recording in --out")
    q.add_argument("--image-ext", choices=(".png", ".jpg"), default=".png",
                   help="colour image format (default .png: lossless)")
    q.add_argument("--depth-scale", type=float, default=None, help="raw depth units per metre of the source")
    q.add_argument("--rate-hz", type=float, default=None, help="frame rate for sources without timestamps")
    q.add_argument("--strict", action="store_true", help="stop at the first undecodable frame")
    add_sequence_options(q)
    q.set_defaults(func=_import)

    def _help(args) -> int:
        p.print_help()
        return 2

    p.set_defaults(func=_help)


def scan_sequence(seq: Sequence, *, decode: bool = True, show_progress: bool | None = None) -> int:
    """Read every frame and side file of ``seq`` (decoding images when ``decode``).

    Strict sequences raise on the first defect; lenient ones add to
    ``seq.report``. Returns the number of frames read successfully.
    """
    ok = 0
    if decode:
        for i in progress(range(len(seq)), desc="scanning", enabled=show_progress):
            if seq.load_or_report(i) is not None:
                ok += 1
    else:
        ok = len(seq)
    for action in (lambda: seq.calibration,
                   lambda: seq.joints() if seq.joints_path is not None else None,
                   lambda: [seq.groundtruth(n) for n in seq.groundtruth_names]):
        try:
            action()
        except TudorVisionError as exc:
            if seq.strict:
                raise
            from ..io.sequence import Problem
            seq.record_problem(Problem(str(exc).split(": ", 1)[0], str(exc).split(": ", 1)[-1]))
    return ok


def _open(args, strict):
    from ..io.sequence import open_sequence
    opts = sequence_options(args)
    if args.func in (_info, _check) and opts["max_frames"] is None:
        opts["max_frames"] = 30                  # a live source has no end: look at 30 frames
    return open_sequence(args.sequence, strict=strict, depth_scale=args.depth_scale, rate_hz=args.rate_hz,
                         **opts)


def _topic_table(path) -> None:
    from ..io.bags import bag_topics

    tops = bag_topics(path)
    width = max([len(t.name) for t in tops] + [5])
    twidth = max([len(t.msgtype) for t in tops] + [4])
    print(f"{'topic':<{width}}  {'type':<{twidth}}  count")
    for t in tops:
        print(f"{t.name:<{width}}  {t.msgtype:<{twidth}}  {t.count}")


def _info(args) -> int:
    from ..io.bags import is_bag

    if is_bag(args.sequence):
        _topic_table(args.sequence)
        try:
            seq = _open(args, strict=False)
        except TudorVisionError as exc:
            if "--topics" not in str(exc):
                raise
            print(f"\n{exc}")                   # ambiguous topics: the table is the answer
            return 0
        print()
    else:
        seq = _open(args, strict=False)
    with seq:
        good = scan_sequence(seq, decode=not args.index_only)
        out = sys.stdout
        size = ", ".join(f"{s} {w}x{h}" for s, (w, h) in (seq.size or {}).items()) or "not declared"
        try:
            cal = seq.calibration
            cal_text = "none" if cal is None else f"cameras {', '.join(cal.cameras) or '-'}" + \
                (f"; transforms {', '.join(cal.transforms)}" if cal.transforms else "")
        except TudorVisionError:
            cal_text = "unreadable (see problems)"
        rate = f"{seq.rate_hz:g} Hz" if seq.rate_hz else "unknown"
        rows = [("sequence", str(seq.path)), ("layout", seq.layout), ("kind", seq.kind),
                ("frames", f"{len(seq)}" + ("" if args.index_only else f" ({good} readable)")),
                ("rate", rate), ("duration", f"{seq.duration_s:.3f} s"),
                ("streams", ", ".join(seq.streams)), ("size", size)]
        if seq.kind == "rgbd":
            rows.append(("depth scale", f"{seq.depth_scale:g} units/m"))
        rows += [("calibration", cal_text), ("groundtruth", ", ".join(seq.groundtruth_names) or "none")]
        if seq.description:
            rows.append(("description", seq.description.strip().splitlines()[0]))
        for note in seq.notes:
            rows.append(("note", note))
        rows.append(("problems", str(len(seq.report))))
        for k, v in rows:
            print(f"{k:<12} {v}", file=out)
        for p in seq.report:
            print(f"  {p}", file=out)
        return 2 if seq.report else 0


def _import(args) -> int:
    from ..io.live import StreamEnded
    from ..io.writer import SequenceWriter

    seq = _open(args, strict=args.strict)
    live = seq.layout == "live"
    with seq:
        meta = {"source": str(args.sequence), "source_layout": seq.layout}
        if seq.meta.get("topics"):
            meta["source_topics"] = dict(seq.meta["topics"])
        writer = SequenceWriter(args.out, kind=seq.kind, rate_hz=seq.rate_hz or 30.0,
                                depth_scale=seq.depth_scale or 1000.0, calibration=seq.calibration,
                                image_ext=args.image_ext, description=f"imported from {args.sequence}",
                                meta=meta, overwrite=args.overwrite)
        ended = None
        with writer:
            frames = range(len(seq))
            for i in progress(iter(frames) if live else frames, desc="importing"):
                try:
                    f = seq.load_or_report(i)
                except StreamEnded as exc:
                    ended = str(exc)
                    break
                if f is None:
                    continue
                if seq.kind == "stereo":
                    writer.add_stereo(f.t, f.left, f.right)
                elif seq.kind == "rgbd":
                    writer.add_rgbd(f.t, f.rgb, f.depth_raw)
                else:
                    writer.add_mono(f.t, f.image)
            if seq.report:
                writer.meta["skipped_frames"] = problem_lines(seq)[:50]
            if seq.joints_path is not None:
                log = seq.joints()
                for t, th in zip(log.t, log.theta_rad):
                    writer.add_joints(t, th)
        flags = partial_flags(writer.frame_count, None, problem_lines(seq))
    if ended:
        print(ended)
    print(f"wrote {args.out} ({seq.kind}, {writer.frame_count} frames, {seq.layout} source"
          f"{', calibration.yaml' if seq.calibration is not None else ''})")
    return 2 if flags else 0


def _check(args) -> int:
    with _open(args, strict=True) as seq:
        n = scan_sequence(seq, decode=not args.index_only)
        print(f"{seq.path}: OK ({seq.layout}, {seq.kind}, {n} frames)")
    return 0
