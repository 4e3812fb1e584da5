"""``tudorvision --help`` and every ``tudorvision <cmd> [<sub>] --help`` build the parser without loading
scipy, OpenCV, Open3D or matplotlib (issue 16: ``--help`` took 1.4-3.7 s because the parser imported them).

Each check runs in a fresh interpreter and inspects ``sys.modules`` after the help was printed; the
first one also reads ``python -X importtime -m tudorvision --help``.
"""
from __future__ import annotations

import subprocess
import sys
import textwrap

HEAVY = ("scipy", "cv2", "open3d", "matplotlib", "rerun", "filterpy")


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                          timeout=60)


def test_top_level_help_imports_no_heavy_package():
    res = subprocess.run([sys.executable, "-X", "importtime", "-m", "tudorvision", "--help"],
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "usage: tudorvision" in res.stdout
    loaded = {line.split("|")[-1].strip().split(".")[0] for line in res.stderr.splitlines()
              if line.startswith("import time:")}
    assert "tudorvision" in loaded          # the importtime trace was read
    assert not loaded & set(HEAVY), sorted(loaded & set(HEAVY))


def test_every_subcommand_help_imports_no_heavy_package():
    res = _run(f"""
        import argparse, contextlib, io, sys
        from tudorvision.cli import build_parser

        def walk(parser, prefix):
            sub = next((a for a in parser._actions if isinstance(a, argparse._SubParsersAction)), None)
            if sub is None:
                yield prefix
                return
            for name, child in sub.choices.items():
                yield from walk(child, prefix + [name])

        paths = list(walk(build_parser(), []))
        for path in paths:
            out = io.StringIO()
            with contextlib.redirect_stdout(out):
                try:
                    build_parser().parse_args(path + ["--help"])
                except SystemExit as stop:
                    assert stop.code == 0, path
            assert "usage: tudorvision" in out.getvalue(), path
        heavy = sorted(m for m in {HEAVY!r} if m in sys.modules)
        print(len(paths), heavy)
        """)
    assert res.returncode == 0, res.stderr[-2000:]
    n, heavy = res.stdout.strip().split(" ", 1)
    assert int(n) >= 25          # every command group and its subcommands were walked
    assert heavy == "[]", f"--help loaded {heavy}"


def test_commands_still_load_what_they_need():
    # the lazy package attributes resolve (a command imports its heavy modules when it runs)
    res = _run("""
        import sys
        import tudorvision.io as io, tudorvision.joint as joint
        assert "cv2" not in sys.modules and "scipy" not in sys.modules
        assert io.open_sequence.__name__ == "open_sequence" and "cv2" in sys.modules
        assert joint.StrainDamper.__name__ == "StrainDamper" and "scipy" in sys.modules
        for mod in (io, joint):
            for name in mod.__all__:
                getattr(mod, name)
            assert set(mod.__all__) <= set(dir(mod))
        try:
            io.no_such_name
        except AttributeError as err:
            print("ok", err)
        """)
    assert res.returncode == 0, res.stderr[-2000:]
    assert res.stdout.startswith("ok module 'tudorvision.io' has no attribute 'no_such_name'")
