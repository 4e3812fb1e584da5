"""``tudorvision reproduce``: verdicts, the report, failed sections flagged, resuming, the CLI's errors."""
from __future__ import annotations

import json
from dataclasses import asdict

import pytest

from tudorvision.cli import main
from tudorvision.lab import reproduce as rp
from tudorvision.lab.reproduce import Row, Section, format_report, run_reproduce, verdict

CALLS = []


def good_section(out_dir, quick, seed):
    CALLS.append(("good", quick, seed))
    return {"rows": [asdict(Row("4.7", "mode", 2.0, 2.15 if quick else 1.95, "Hz", "within:0.10")),
                     asdict(Row("9.1", "error", 4.0, 1.2, "mm", "max:2"))],
            "figures": ["figures/x.png"], "notes": ["a note"]}


def bad_section(out_dir, quick, seed):
    CALLS.append(("bad", quick, seed))
    raise RuntimeError("plant exploded")


def appendix_section(out_dir, quick, seed):
    return {"rows": [asdict(Row("B.5", "band x", 2.0, 3.3, "mm", "max:2")),
                     asdict(Row("11.3", "delay", "–", None, "ms", "max:20"))]}


@pytest.fixture
def fake_sections(monkeypatch):
    CALLS.clear()
    secs = [Section("good", "4", "modes", good_section), Section("bad", "8", "damping", bad_section),
            Section("appx", "B.5", "rail", appendix_section)]
    monkeypatch.setattr(rp, "_sections", lambda: secs)
    return secs


@pytest.mark.parametrize("rule, seed, lab, expected", [
    ("within:0.10", 2.0, 2.2, "agrees (within 10 %)"),
    ("within:0.10", 2.0, 2.21, "differs by +10 %"),
    ("within:0.10", 0.03, 0.109, "differs by +263 %"),
    ("within:0", 3.0, 3.0, "agrees (within 0 %)"),
    ("within:0", 3.0, 2.0, "differs by -33 %"),
    ("max:2", 4.0, 2.0, "met"),
    ("max:2", 4.0, 2.01, "not met"),
    ("min:95", None, 94.9, "not met"),
    ("min:95", None, 95.0, "met"),
    ("info", 56.8, 81.4, "reported"),
    ("max:20", "–", None, "not measured"),
    ("within:0.1", 2.0, float("nan"), "not measured"),
])
def test_verdict_rules(rule, seed, lab, expected):
    assert verdict(Row("s", "q", seed, lab, "", rule)) == expected
    assert verdict(asdict(Row("s", "q", seed, lab, "", rule))) == expected


@pytest.mark.parametrize("rule", ["about:3", "max:", "max:two", "within"])
def test_verdict_rejects_bad_rules(rule):
    with pytest.raises(ValueError, match="rule"):
        verdict(Row("s", "q", 1.0, 1.0, "", rule))


def test_report_flags_failed_section_and_keeps_the_others(tmp_path, fake_sections):
    res = run_reproduce(tmp_path, quick=True, show_progress=False)
    assert not res["complete"]
    status = {s["name"]: s["status"] for s in res["sections"]}
    assert status == {"good": "done", "bad": "failed", "appx": "done"}
    assert [r["verdict"] for r in res["rows"]] == ["agrees (within 10 %)", "met",
                                                   "not met", "not measured"]
    md = (tmp_path / "reproduction.md").read_text()
    assert "**Incomplete**" in md and "bad" in md and "plant exploded" in md
    # chapters in order, appendix last, with the target of max/min rules
    assert md.index("## Chapter 4") < md.index("## Chapter 9") < md.index("## Chapter 11") < md.index("## Appendix B.5")
    assert "| 9.1 | error | 4 mm | 1.2 mm | met (target ≤ 2) |" in md
    assert "`figures/x.png`" in md and "good: a note" in md
    js = json.loads((tmp_path / "reproduction.json").read_text())
    assert js["rows"] == res["rows"] and js["quick"] == ["appx", "bad", "good"]


def test_rerun_resumes_done_sections_and_retries_failed(tmp_path, fake_sections):
    run_reproduce(tmp_path, quick=False, seed=3, show_progress=False)
    assert CALLS.count(("good", False, 3)) == 1 and CALLS.count(("bad", False, 3)) == 2   # one retry
    CALLS.clear()
    res = run_reproduce(tmp_path, quick=False, seed=3, show_progress=False)
    assert ("good", False, 3) not in CALLS and CALLS.count(("bad", False, 3)) == 2
    assert res["rows"][0]["lab"] == 1.95
    # a different mode is a different task
    CALLS.clear()
    run_reproduce(tmp_path, quick=True, seed=3, only=["good"], show_progress=False)
    assert CALLS == [("good", True, 3)]


def test_only_selects_and_rejects_unknown(tmp_path, fake_sections):
    res = run_reproduce(tmp_path, only=["appx"], show_progress=False)
    assert res["complete"] and [s["name"] for s in res["sections"]] == ["appx"]
    with pytest.raises(ValueError, match="unknown section"):
        run_reproduce(tmp_path, only=["nope"], show_progress=False)


def test_cli_exit_codes_and_messages(tmp_path, fake_sections, capsys):
    assert main(["reproduce", "--out", str(tmp_path / "a"), "--only", "good,appx", "--scheduler", "serial"]) == 0
    out = capsys.readouterr().out
    assert "4 rows" in out and "reproduction.md" in out
    assert main(["reproduce", "--out", str(tmp_path / "b"), "--scheduler", "serial"]) == 3
    err = capsys.readouterr().err
    assert "incomplete" in err and "bad (failed)" in err
    assert main(["reproduce", "--out", str(tmp_path / "c"), "--only", "good,nope"]) == 2
    assert "--only: unknown section(s) nope" in capsys.readouterr().err
    assert main(["reproduce", "--quick"]) == 2
    assert "--out: required" in capsys.readouterr().err


def test_real_sections_are_registered_with_module_level_functions():
    from tudorvision.lab.reproduce_sections import SECTIONS
    names = [s.name for s in SECTIONS]
    assert len(set(names)) == len(names)
    for s in SECTIONS:
        assert s.fn.__module__.startswith("tudorvision.lab.") and "." not in s.fn.__qualname__
    chapters = {s.chapter for s in SECTIONS}
    assert {"4", "9", "10", "11", "B.5"} <= chapters


def test_the_report_names_the_numerical_packages_it_ran_with(tmp_path, fake_sections):
    import numpy
    import scipy
    res = run_reproduce(tmp_path, only=["good"], show_progress=False)
    assert res["packages"]["numpy"] == numpy.__version__ and res["packages"]["scipy"] == scipy.__version__
    on_disk = json.loads((tmp_path / "reproduction.json").read_text())
    assert on_disk["packages"] == res["packages"]
    md = (tmp_path / "reproduction.md").read_text()
    line = next(x for x in md.splitlines() if x.startswith("Packages: "))
    assert f"numpy {numpy.__version__}" in line and f"scipy {scipy.__version__}" in line


def test_format_report_of_a_quick_run_says_so():
    res = {"quick": ["good"], "seed": 0, "complete": True, "scheduler": "serial", "workers": 1, "wall_s": 1.0,
           "machine": "x86_64", "python": "3.11", "sections": [{"name": "good", "quick": True, "chapter": "4", "title": "t", "status": "done", "error": None, "figures": [], "notes": [], "duration_s": 1.0}],
           "rows": [{**asdict(Row("4.7", "m", 2.0, 1.9, "Hz", "within:0.10")), "chapter": "4", "verdict": "agrees"}]}
    md = format_report(res)
    assert "quick" in md and "| 4.7 | m | 2 Hz | 1.9 Hz | agrees |" in md


def test_quick_sections_mix_and_report_mode(tmp_path, fake_sections):
    res = run_reproduce(tmp_path, quick=["good"], only=["good", "appx"], show_progress=False)
    assert CALLS == [("good", True, 0)]
    assert {s["name"]: s["quick"] for s in res["sections"]} == {"good": True, "appx": False}
    md = (tmp_path / "reproduction.md").read_text()
    assert "full, except good run small" in md
    with pytest.raises(ValueError, match="quick-sections"):
        run_reproduce(tmp_path, quick=["nope"], show_progress=False)


def test_sections_record_the_code_they_ran_with(tmp_path, fake_sections, monkeypatch):
    monkeypatch.setattr(rp, "code_version", lambda: "9.9 (git abc1234)")
    res = run_reproduce(tmp_path, only=["good"], show_progress=False)
    assert res["sections"][0]["code"] == "9.9 (git abc1234)"
    rec = json.loads(next((tmp_path / "runs").glob("reproduce-good-*.json")).read_text())
    assert rec["code"] == "9.9 (git abc1234)" and rec["status"] == "done" and "ran_now" not in rec
    monkeypatch.setattr(rp, "code_version", lambda: "10.0 (git def5678)")
    res = run_reproduce(tmp_path, only=["good"], show_progress=False)      # resumed: the earlier code
    assert res["sections"][0]["code"] == "9.9 (git abc1234)"
    assert "| 9.9 (git abc1234) |" in (tmp_path / "reproduction.md").read_text()
