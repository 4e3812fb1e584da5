"""``tudorvision joint move`` reports progress while it waits and says why the arm did not settle (issue 16).

A simulated elastic arm (core ``sim``) is served in a subprocess on loopback. Undamped, its links
oscillate for over a minute after a move: the command must print periodic status lines and, at the
timeout, one line naming the link oscillation in mm and the damping flag to try. With that flag the
same kind of move settles. A move cut short names the joint still on its way.
"""
from __future__ import annotations

import re

import pytest

from _subproc import start_cli, stop
from tudorvision.cli import main

pytest.importorskip("tudorvision.sim.arm", reason="simulated arm not available")

LINE = re.compile(r"^\s*\d+\.\d s  theta_deg( +-?\d+\.\d{3}){3}  to goal \d+\.\d{3} deg \(joint [123]\)  "
                  r"link-tip oscillation \d+\.\d/\d+\.\d mm  damping (off|proportional)$")


@pytest.fixture(scope="module")
def sim_port():
    proc, line = start_cli(["joint", "serve", "--port", "0", "--core", "sim", "--duration", "60"],
                           expect=["listening on udp 127.0.0.1:"])
    try:
        yield int(line.rsplit(":", 1)[1])
    finally:
        stop(proc)


def test_damped_move_settles_with_the_suggested_flag(sim_port, capsys):
    code = main(["joint", "move", "--port", str(sim_port), "--to", "0,80,0", "--timeout", "25",
                 "--damping", "proportional", "--progress", "0.5"])
    out, err = capsys.readouterr()
    assert code == 0, err
    lines = out.splitlines()
    assert lines[-1].startswith("settled at theta_deg 0.000 ")
    assert any(LINE.match(x) and x.endswith("damping proportional") for x in lines[:-1]), out


def test_undamped_move_reports_progress_and_the_oscillation(sim_port, capsys):
    code = main(["joint", "move", "--port", str(sim_port), "--to", "0,60,0", "--timeout", "3",
                 "--damping", "off", "--progress", "0.5"])
    out, err = capsys.readouterr()
    assert code == 1
    lines = out.splitlines()
    assert len(lines) >= 3, out                      # about one every 0.5 s over 3 s
    assert all(LINE.match(x) for x in lines), out
    assert lines[-1].endswith("damping off")
    err = err.strip()
    assert len(err.splitlines()) == 1
    m = re.fullmatch(r"tudorvision joint move: did not settle at 0,60,0 deg within 3 s: link oscillation "
                     r"(\d+\.\d) mm on link ([23]) \(after joint \2\), joints at the goal - damping is off; "
                     r"try --damping proportional \(or --joints-only\)", err)
    assert m, err
    assert float(m.group(1)) > 1.0                   # a 30 deg step leaves mm of tip oscillation


def test_move_cut_short_names_the_joint_on_its_way(sim_port, capsys):
    code = main(["joint", "move", "--port", str(sim_port), "--to", "40,80,0", "--timeout", "1.5",
                 "--speed", "5", "--progress", "0"])
    out, err = capsys.readouterr()
    assert code == 1
    assert out == ""                                 # --progress 0: quiet
    assert re.fullmatch(r"tudorvision joint move: did not settle at 40,80,0 deg within 1.5 s: joint 1 still "
                        r"\d+\.\d\d deg from the goal, moving at \d+\.\d deg/s; try a longer --timeout or a "
                        r"higher --speed\n", err), err


def test_robot_file_errors_are_one_line(tmp_path, capsys):
    bad = tmp_path / "robot.yaml"
    bad.write_text("name: [unclosed\n")
    assert main(["joint", "serve", "--port", "0", "--duration", "0.1", "--robot", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "robot.yaml" in err, err
