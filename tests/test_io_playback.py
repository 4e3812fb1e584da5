"""Live-rate playback: pacing and frame dropping (fake clock for exact counts, real clock for bounds)."""
import numpy as np
import pytest

from tudorvision.io import SequenceWriter, open_sequence


class FakeClock:
    """Deterministic wall clock: sleeping and consumer work advance it."""

    def __init__(self):
        self.now = 100.0
        self.slept = []

    def __call__(self):
        return self.now

    def sleep(self, dt):
        self.slept.append(dt)
        self.now += dt


def _mono(root, n, rate_hz):
    with SequenceWriter(root, kind="mono", rate_hz=rate_hz) as w:
        for k in range(n):
            w.add_mono(5.0 + k / rate_hz, np.full((4, 4), k, np.uint8))
    return open_sequence(root)


def test_fast_consumer_gets_every_frame_on_time(tmp_path):
    seq = _mono(tmp_path / "m", 10, 10.0)
    clock = FakeClock()
    pb = seq.play(clock=clock, sleep=clock.sleep)
    got = [p.frame.index for p in pb]
    assert got == list(range(10))
    assert pb.dropped == 0 and pb.max_latency_s == 0.0
    assert clock.now - 100.0 == pytest.approx(0.9)          # paced to the recording
    assert len(clock.slept) == 9


def test_slow_consumer_drops_frames(tmp_path):
    seq = _mono(tmp_path / "m", 20, 10.0)
    clock = FakeClock()
    pb = seq.play(clock=clock, sleep=clock.sleep)
    got, lat = [], []
    for played in pb:
        got.append((played.frame.index, played.dropped))
        lat.append(played.latency_s)
        assert played.frame.image[0, 0] == played.frame.index
        clock.now += 0.25                       # 2.5 frame periods of work per frame
    # frame k is due 0.1 k s after the start; each request comes 0.25 s after the last
    assert [i for i, _ in got] == [0, 2, 5, 7, 10, 12, 15, 17, 19]   # always the newest due frame
    assert [d for _, d in got] == [0, 1, 2, 1, 2, 1, 2, 1, 1]
    assert (pb.delivered, pb.dropped, pb.skipped) == (9, 11, 0)
    # latency: how long the delivered frame had been due (decoding takes no fake time)
    assert np.allclose(lat, [0, 0.05, 0, 0.05, 0, 0.05, 0, 0.05, 0.1], atol=1e-9)
    assert pb.max_latency_s == pytest.approx(0.1)


def test_real_clock_slow_consumer_drops(tmp_path):
    import time
    n = 30
    seq = _mono(tmp_path / "m", n, 200.0)
    pb = seq.play()
    for played in pb:
        time.sleep(0.02)                        # 4 frame periods per frame
        assert played.latency_s >= 0.0
    assert pb.delivered + pb.dropped + pb.skipped == n
    assert pb.delivered <= n // 4 + 2 and pb.dropped >= n - (n // 4 + 2)


def test_defective_frames_are_skipped_and_reported_in_lenient_playback(tmp_path):
    seq = _mono(tmp_path / "m", 6, 10.0)
    (tmp_path / "m" / "image" / "000003.png").write_bytes(b"broken")
    lenient = open_sequence(tmp_path / "m", strict=False)
    clock = FakeClock()
    pb = lenient.play(clock=clock, sleep=clock.sleep)
    assert [p.frame.index for p in pb] == [0, 1, 2, 4, 5]
    assert pb.skipped == 1 and pb.dropped == 0
    assert len(lenient.report) == 1 and lenient.report[0].frame == 3
    strict = seq.play(clock=clock, sleep=clock.sleep)
    from tudorvision._checks import TudorVisionError
    with pytest.raises(TudorVisionError, match=r"image\.txt:\d+ \(000003\.png\): corrupt"):
        list(strict)


def test_speed_factor_and_bad_speed(tmp_path):
    seq = _mono(tmp_path / "m", 5, 10.0)
    clock = FakeClock()
    assert len(list(seq.play(speed=2.0, clock=clock, sleep=clock.sleep))) == 5
    assert clock.now - 100.0 == pytest.approx(0.2)
    with pytest.raises(ValueError, match="speed"):
        seq.play(speed=0.0)
