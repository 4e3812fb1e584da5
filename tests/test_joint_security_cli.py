"""``tudorvision joint keygen`` and ``--key-file`` / ``--host`` on serve, status, move, payload."""
from __future__ import annotations

import os

import pytest

from _subproc import start_cli, stop
from tudorvision.cli import main


def test_keygen_writes_a_0600_key_and_refuses_to_overwrite(tmp_path, capsys):
    key = tmp_path / "joint.key"
    assert main(["joint", "keygen", "--out", str(key)]) == 0
    assert os.stat(key).st_mode & 0o777 == 0o600 and len(key.read_text().strip()) == 64
    assert main(["joint", "keygen", "--out", str(key)]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "exists" in err[0]


def test_serving_beyond_loopback_without_a_key_is_refused(capsys):
    assert main(["joint", "serve", "--port", "0", "--host", "0.0.0.0", "--duration", "0.1"]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--key-file" in err[0]


@pytest.fixture(scope="module")
def keyed_layer(tmp_path_factory):
    key = tmp_path_factory.mktemp("key") / "joint.key"
    from tudorvision.joint.protocol import write_key_file
    write_key_file(key)
    proc, line = start_cli(["joint", "serve", "--port", "0", "--duration", "20", "--key-file", key],
                           expect=["HMAC-SHA256", "127.0.0.1:"], timeout_s=15.0)
    try:
        yield int(line.rsplit(":", 1)[1]), str(key)
    finally:
        stop(proc)


def test_keyed_layer_answers_key_holders_only(keyed_layer, tmp_path, capsys):
    port, key = keyed_layer
    assert main(["joint", "status", "--port", str(port), "--key-file", key, "--timeout", "3"]) == 0
    assert "mode IDLE" in capsys.readouterr().out
    assert main(["joint", "status", "--port", str(port), "--timeout", "0.3"]) == 1
    assert "--key-file" in capsys.readouterr().err
    other = tmp_path / "other.key"
    assert main(["joint", "keygen", "--out", str(other)]) == 0
    assert main(["joint", "status", "--port", str(port), "--key-file", str(other), "--timeout", "0.3"]) == 1
    capsys.readouterr()
    assert main(["joint", "move", "--port", str(port), "--key-file", key, "--to", "5,85,5",
                 "--joints-only", "--timeout", "15"]) == 0
    assert main(["joint", "payload", "--port", str(port), "--key-file", key, "--kg", "0.2"]) == 0
    assert "payload 0.2 kg accepted" in capsys.readouterr().out
    assert main(["joint", "status", "--port", str(port), "--key-file", key, "--timeout", "3"]) == 0
    out = capsys.readouterr().out
    assert "unauthenticated=" in out and "tick_interval_ms p50" in out
