"""The stereo accuracy benchmark's render cache is keyed by the lab's sources.

Renders cached under an older lab (before the soft plant became the default)
were once scored as the current lab's: docs/benchmarks.md, "Virtual lab static
stereo accuracy 0.39 -> 0.50 mm: cause".
"""
import os
import shutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_stereo_accuracy as bench  # noqa: E402


def _copy_lab(dst: Path) -> Path:
    for rel in bench.LAB_SOURCES:
        src = ROOT / rel
        if src.is_dir():
            shutil.copytree(src, dst / rel, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            (dst / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst / rel)
    return dst


def test_fingerprint_follows_the_lab_sources(tmp_path):
    here = bench.lab_fingerprint(str(ROOT))
    copy = _copy_lab(tmp_path / "tree")
    assert bench.lab_fingerprint(str(copy)) == here            # same sources, same key
    model = copy / "tudorvision" / "sim" / "model.py"
    model.write_text(model.read_text() + "\n# plant changed\n")
    assert bench.lab_fingerprint(str(copy)) != here            # a sim change renders anew
    record = copy / "tudorvision" / "lab" / "record.py"
    model.write_text(model.read_text().replace("\n# plant changed\n", ""))
    assert bench.lab_fingerprint(str(copy)) == here
    record.write_text(record.read_text() + "\n")
    assert bench.lab_fingerprint(str(copy)) != here


def test_render_dir_names_the_lab(tmp_path, monkeypatch):
    calls = []
    monkeypatch.setattr(bench, "record", lambda kind, out, opts: calls.append(Path(out)))
    out = bench.render(tmp_path, "stereo-static", 3, ".png", False, 4)
    assert out.name == f"stereo-static_seed3_png_4_lab{bench.lab_fingerprint()}"
    assert calls == [out]
    assert os.path.dirname(out) == str(tmp_path)
