"""``tudorvision seq info|check``: inspect and validate recorded sequences."""
from __future__ import annotations

import sys

from .._checks import TudorVisionError
from .._progress import progress
from ..io.sequence import Sequence, open_sequence

__all__ = ["register", "scan_sequence"]


def register(subparsers) -> None:
    """Add the ``seq`` command with ``info`` and ``check`` to ``subparsers``."""
    p = subparsers.add_parser("seq", help="inspect and validate recorded sequences",
                              description="Inspect (info) or strictly validate (check) a recorded "
                                          "sequence: a sequence directory, a TUM RGB-D directory, an "
                                          "image folder or a video file.")
    sub = p.add_subparsers(dest="seq_command", metavar="ACTION")
    for name, func, text in (
            ("info", _info, "summary and a lenient scan listing every problem (exit 2 if any)"),
            ("check", _check, "strict validation: exit 2 with the first error as one line")):
        q = sub.add_parser(name, help=text, description=text)
        q.add_argument("sequence", metavar="SEQ", help="sequence directory, sequence.yaml or video file")
        q.add_argument("--depth-scale", type=float, default=None,
                       help="raw depth units per metre (overrides the sequence)")
        q.add_argument("--rate-hz", type=float, default=None,
                       help="frame rate for folders without timestamps (default 30)")
        q.add_argument("--index-only", action="store_true",
                       help="check the index files only, do not decode images")
        q.set_defaults(func=func)

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
    return open_sequence(args.sequence, strict=strict, depth_scale=args.depth_scale, rate_hz=args.rate_hz)


def _info(args) -> int:
    with _open(args, strict=False) as seq:
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


def _check(args) -> int:
    with _open(args, strict=True) as seq:
        n = scan_sequence(seq, decode=not args.index_only)
        print(f"{seq.path}: OK ({seq.layout}, {seq.kind}, {n} frames)")
    return 0
