"""``tudorvision seq info|check``: summaries, exit codes, one-line errors."""
import numpy as np
import pytest

import tudorvision.cli
from tudorvision.cli import main
from tudorvision.io import SequenceWriter


@pytest.fixture(autouse=True)
def _only_seq_commands(monkeypatch):
    """Build the real CLI with only this module's commands (others may be mid-development)."""
    monkeypatch.setattr(tudorvision.cli, "COMMAND_MODULES", ("tudorvision.cli.seq",))


def _seq(root, n=4):
    rng = np.random.default_rng(0)
    with SequenceWriter(root, kind="rgbd", rate_hz=30.0, depth_scale=1000.0, description="cli test") as w:
        for k in range(n):
            w.add_rgbd(k / 30, rng.integers(0, 255, (6, 8, 3), np.uint8), np.full((6, 8), 1.0 + k))
    return root


def test_seq_info_and_check_on_good_sequence(tmp_path, capsys):
    root = _seq(tmp_path / "s")
    assert main(["seq", "info", str(root)]) == 0
    out = capsys.readouterr().out
    assert "kind         rgbd" in out and "frames       4 (4 readable)" in out
    assert "rate         30 Hz" in out and "depth scale  1000 units/m" in out and "problems     0" in out
    assert main(["seq", "check", str(root)]) == 0
    assert "OK (tudorvision, rgbd, 4 frames)" in capsys.readouterr().out


def test_seq_info_lists_problems_and_check_fails_with_one_line(tmp_path, capsys):
    root = _seq(tmp_path / "s")
    (root / "rgb" / "000002.png").write_bytes(b"junk")
    lines = (root / "depth.txt").read_text().splitlines()
    lines[-1] = "not-a-number depth/000003.png"
    (root / "depth.txt").write_text("\n".join(lines) + "\n")
    assert main(["seq", "info", str(root)]) == 2
    out = capsys.readouterr().out
    assert "problems     3" in out          # bad line, its rgb partner left alone, corrupt image
    assert "malformed timestamp 'not-a-number'" in out and "cannot decode" in out
    assert main(["seq", "check", str(root)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err
    assert err.startswith("tudorvision seq: error: ") and "depth.txt:" in err


def test_seq_check_missing_path_and_bare_command(tmp_path, capsys):
    assert main(["seq", "check", str(tmp_path / "absent")]) == 2
    assert "no such file or directory" in capsys.readouterr().err
    assert main(["seq"]) == 2
    with pytest.raises(SystemExit):
        main(["seq", "info"])            # argparse: SEQ is required
