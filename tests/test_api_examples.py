"""``docs/api_examples.md`` (stereo, RGB-D, servo, catch, adapter on the sample data) passes as a doctest.

Runs ``python -m doctest -v docs/api_examples.md`` from the repository root, as the page tells users to.
"""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_api_examples_doctest_passes():
    res = subprocess.run([sys.executable, "-m", "doctest", "-v", "docs/api_examples.md"], cwd=ROOT,
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-2000:]
    m = re.search(r"(\d+) passed and 0 failed", res.stdout)
    assert m and int(m.group(1)) >= 40, res.stdout[-500:]
    text = (ROOT / "docs" / "api_examples.md").read_text()
    for api in ("track_stereo", "points_cam_from_depth", "VisualServo", "BallisticPredictor", "JointAdapter"):
        assert api in text, api
