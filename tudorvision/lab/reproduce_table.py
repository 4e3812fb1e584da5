"""The side-by-side table of ``tudorvision reproduce``: rows, verdicts, sections and the Markdown report.

A section of the reproduction returns rows; each row holds the seed's value,
the lab's value and a rule that gives the verdict:

* ``"within:0.10"``: the lab within 10 % of the seed's value;
* ``"max:T"`` / ``"min:T"``: a target (the issue's or the seed's) the lab must not
  exceed / must reach;
* ``"info"``: reported beside the seed, no verdict (a different quantity or no
  number in the seed).

Pure functions; :mod:`tudorvision.lab.reproduce` runs the sections.
"""
from __future__ import annotations

import math
import re
from dataclasses import asdict, dataclass
from typing import Callable

__all__ = ["Row", "Section", "verdict", "row_chapter", "format_report"]


@dataclass(frozen=True)
class Row:
    """One line of the side-by-side table.

    Parameters
    ----------
    section : str
        The seed's section, figure or table (``"4.7, fig. 4.6"``).
    quantity : str
        What is compared, in words.
    seed : float, str or None
        The seed's value (a number, or text where the seed gives a range or words).
    lab : float or None
        The lab's value (``None``: not measured; the verdict says so).
    unit : str
        Unit of ``seed`` and ``lab``.
    rule : str
        ``"within:F"`` (relative tolerance ``F`` of the seed's value), ``"max:T"``,
        ``"min:T"`` or ``"info"``.
    note : str
        Conditions or the reason for a difference.
    """

    section: str
    quantity: str
    seed: float | str | None
    lab: float | None
    unit: str = ""
    rule: str = "info"
    note: str = ""


def verdict(row: Row | dict) -> str:
    """The verdict of a row under its rule.

    Parameters
    ----------
    row : Row or dict
        The row (a dict with the same keys, as read back from a record).

    Returns
    -------
    str
        ``"agrees (within 10 %)"``, ``"differs by +23 %"``, ``"met"``, ``"not met"``,
        ``"reported"`` or ``"not measured"``.

    Raises
    ------
    ValueError
        On a rule that is not one of the documented forms.

    Examples
    --------
    >>> verdict(Row("4.7", "f", 2.0, 2.1, "Hz", "within:0.10"))
    'agrees (within 10 %)'
    >>> verdict(Row("4.7", "f", 2.0, 2.5, "Hz", "within:0.10"))
    'differs by +25 %'
    >>> verdict(Row("9.1", "mean error", 4.0, 0.9, "mm", "max:2"))
    'met'
    """
    r = row if isinstance(row, dict) else asdict(row)
    rule, lab = str(r["rule"]), r["lab"]
    kind, _, arg = rule.partition(":")
    if kind not in ("within", "max", "min", "info"):
        raise ValueError(f"rule: expected within:F, max:T, min:T or info, got {rule!r}")
    if lab is None or (isinstance(lab, float) and not math.isfinite(lab)):
        return "not measured"
    if kind == "info":
        return "reported"
    try:
        x = float(arg)
    except ValueError:
        raise ValueError(f"rule: {rule!r} needs a number after the colon") from None
    lab = float(lab)
    if kind == "max":
        return "met" if lab <= x else "not met"
    if kind == "min":
        return "met" if lab >= x else "not met"
    seed = float(r["seed"])
    rel = lab / seed - 1.0 if seed != 0 else math.inf
    if abs(rel) <= x + 1e-12:
        return f"agrees (within {100 * x:g} %)"
    return f"differs by {100 * rel:+.0f} %"


@dataclass(frozen=True)
class Section:
    """One experiment of the reproduction.

    Parameters
    ----------
    name : str
        Short name (``--only``), letters, digits and ``-``.
    chapter : str
        The seed's chapter or appendix (``"4"``, ``"B.5"``).
    title : str
        What it reproduces, in words.
    fn : callable
        Module-level ``fn(out_dir: str, quick: bool, seed: int) -> dict`` with ``rows`` (list of
        :class:`Row` as dicts), optional ``figures`` (paths relative to ``out_dir``) and ``notes``
        (list of str).
    minutes_quick : float
        Rough wall time with ``--quick`` on one core, minutes (for the plan printed first).
    minutes_full : float
        Rough wall time of the full run, minutes.
    """

    name: str
    chapter: str
    title: str
    fn: Callable
    minutes_quick: float = 1.0
    minutes_full: float = 10.0


def _fmt(v, unit: str = "") -> str:
    if v is None:
        return "–"
    if isinstance(v, str):
        return v
    v = float(v)
    if not math.isfinite(v):
        return "–"
    a = abs(v)
    s = f"{v:.3g}" if a < 100 else f"{v:.0f}"
    return f"{s} {unit}".strip()


def format_report(result: dict) -> str:
    """Markdown of a reproduction run: one table per chapter, then the sections' status and notes.

    Parameters
    ----------
    result : dict
        What :func:`run_reproduce` returns (or its ``reproduction.json``).

    Returns
    -------
    str
        The report (``reproduction.md``).
    """
    lines = ["# Reproduction of the seed's experiments in the lab", ""]
    small = result["quick"]
    names = [s["name"] for s in result["sections"]]
    if small and set(names) <= set(small):
        mode = "quick (`--quick`: small versions, numbers are indicative)"
    elif small:
        mode = f"full, except {', '.join(small)} run small (`--quick-sections`: numbers indicative)"
    else:
        mode = "full"
    lines += [f"Mode: {mode}; seed {result['seed']}; scheduler {result['scheduler']} ({result['workers']} worker(s));"
              f" {result['wall_s']:.0f} s wall in this call (sections found done are not re-run; their own times are"
              f" at the end); {result['machine']}, Python {result['python']}.", ""]
    if result.get("packages"):
        lines += ["Packages: " + ", ".join(f"{k} {v}" for k, v in result["packages"].items())
                  + " (the lab's numbers move slightly between their builds: compare throw by throw only on the same).",
                  ""]
    if not result["complete"]:
        bad = [s["name"] for s in result["sections"] if s["status"] != "done"]
        lines += [f"**Incomplete**: section(s) {', '.join(bad)} did not finish (see the end); the rows below "
                  "are those of the finished sections.", ""]
    chapters: dict = {}
    for r in result["rows"]:
        chapters.setdefault(r["chapter"], []).append(r)
    for ch in sorted(chapters, key=_chapter_key):
        lines += [f"## {'Appendix' if ch[0].isalpha() else 'Chapter'} {ch}", "",
                  "| section | quantity | seed | lab | verdict | note |", "|---|---|---|---|---|---|"]
        for r in chapters[ch]:
            rule = r["rule"]
            target = "" if rule == "info" or rule.startswith("within") else \
                f" (target {'≤' if rule.startswith('max') else '≥'} {rule.split(':', 1)[1]})"
            lines.append(f"| {r['section']} | {r['quantity']} | {_fmt(r['seed'], r['unit'])} | "
                         f"{_fmt(r['lab'], r['unit'])} | {r['verdict']}{target} | {r.get('note', '')} |")
        lines.append("")
    lines += ["## Sections", "", "| section | chapter | what | size | status | wall | code | figures |",
              "|---|---|---|---|---|---|---|---|"]
    for s in result["sections"]:
        st = s["status"] + (f": {s['error'].splitlines()[-1]}" if s.get("error") else "")
        wall = "–" if s["duration_s"] is None else f"{s['duration_s']:.0f} s"
        lines.append(f"| {s['name']} | {s['chapter']} | {s['title']} | {'quick' if s.get('quick') else 'full'} | "
                     f"{st} | {wall} | {s.get('code') or '–'} | "
                     f"{', '.join(f'`{f}`' for f in s['figures'])} |")
    notes = [(s["name"], n) for s in result["sections"] for n in s["notes"]]
    if notes:
        lines += ["", "Notes:", ""] + [f"- {name}: {n}" for name, n in notes]
    return "\n".join(lines) + "\n"


def row_chapter(section: str, default: str) -> str:
    """The chapter (``"4"``) or appendix (``"B.5"``) a row's section names, else ``default``.

    Parameters
    ----------
    section : str
        The row's section (``"4.7, fig. 4.6"``, ``"B.5, fig. B.3"``).
    default : str
        The chapter of the experiment that made the row.

    Returns
    -------
    str
        The chapter.

    Examples
    --------
    >>> row_chapter("10.5, table 10.1", "9"), row_chapter("B.5, fig. B.3", "B"), row_chapter("intro", "9")
    ('10', 'B.5', '9')
    """
    m = re.match(r"\s*([A-Z]\.\d+|\d+)", section)
    return m.group(1) if m else default


def _chapter_key(ch: str):
    head = ch.split(".")[0]
    return (1, ch) if head.isalpha() else (0, float(head))
