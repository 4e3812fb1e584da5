"""``calib stereo`` on OpenCV's own stereo sample pairs, checked against the ``stereo_calib`` sample.

The reference below re-implements the procedure of OpenCV's
``samples/cpp/stereo_calib.cpp`` (4.6) independently of
:mod:`tudorvision.stereo.calibrate`: board search at scale 1 then 2
(``INTER_LINEAR_EXACT``), ``cornerSubPix`` with the sample's fixed 11 px
half-window, ``initCameraMatrix2D`` and one ``stereoCalibrate`` with the
sample's flags (including ``RATIONAL_MODEL`` with k3..k5 fixed, so k6 is
free), and the sample's mean epipolar error. Square size 1 as in the sample,
so T is in squares.

Known, stated differences (docs/stereo.md): our corner refinement shrinks the
half-window to 0.45 of the corner spacing; on pair 02 (steep board, 22 px
spacing) the sample's 23 px window pulls six corners by up to 6 px, so our
RMS is lower. The project's calibration format holds 5 plumb-bob
coefficients, so ``--mode opencv-sample`` keeps k6 = 0.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from tudorvision.cli import main
from tudorvision.stereo.calibrate import find_board_corners

DATA = Path(__file__).resolve().parent / "data" / "opencv_stereo"
IDS = ["01", "02", "03", "04", "05", "06", "07", "08", "09", "11", "12", "13", "14"]
BOARD = (9, 6)
SAMPLE_FLAGS = (cv2.CALIB_FIX_ASPECT_RATIO | cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_USE_INTRINSIC_GUESS
                | cv2.CALIB_SAME_FOCAL_LENGTH | cv2.CALIB_RATIONAL_MODEL
                | cv2.CALIB_FIX_K3 | cv2.CALIB_FIX_K4 | cv2.CALIB_FIX_K5)

pytestmark = pytest.mark.skipif(not (DATA / "left01.jpg").is_file(),
                                reason=f"{DATA}: OpenCV sample images not present")


def _sample_corners(grey):
    """The sample's corner search: scale 1 then 2, then an 11 px half-window cornerSubPix."""
    for scale in (1, 2):
        img = grey if scale == 1 else cv2.resize(grey, None, fx=scale, fy=scale,
                                                 interpolation=cv2.INTER_LINEAR_EXACT)
        found, corners = cv2.findChessboardCorners(
            img, BOARD, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
        if found:
            corners = (corners / scale).astype(np.float32)
            break
    else:
        return None
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 30, 0.01)
    return cv2.cornerSubPix(grey, corners, (11, 11), (-1, -1), crit)


def _sample_solve(corners_left, corners_right, size):
    """initCameraMatrix2D + stereoCalibrate with the sample's flags; square size 1."""
    j, k = np.mgrid[0:BOARD[1], 0:BOARD[0]]
    obj = np.column_stack([k.ravel(), j.ravel(), np.zeros(k.size)]).astype(np.float32)
    objs = [obj] * len(corners_left)
    pl = [np.asarray(c, np.float32).reshape(-1, 1, 2) for c in corners_left]
    pr = [np.asarray(c, np.float32).reshape(-1, 1, 2) for c in corners_right]
    K1 = cv2.initCameraMatrix2D(objs, pl, size, 0)
    K2 = cv2.initCameraMatrix2D(objs, pr, size, 0)
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-5)
    rms, K1, D1, K2, D2, R, T, E, F = cv2.stereoCalibrate(objs, pl, pr, K1, np.zeros(8), K2, np.zeros(8),
                                                         size, flags=SAMPLE_FLAGS, criteria=crit)
    # mean epipolar error as the sample computes it (undistorted points, both directions)
    err, n = 0.0, 0
    for a, b in zip(pl, pr):
        ua = cv2.undistortPoints(a, K1, D1, P=K1).reshape(-1, 2)
        ub = cv2.undistortPoints(b, K2, D2, P=K2).reshape(-1, 2)
        la = cv2.computeCorrespondEpilines(ua.reshape(-1, 1, 2), 1, F).reshape(-1, 3)
        lb = cv2.computeCorrespondEpilines(ub.reshape(-1, 1, 2), 2, F).reshape(-1, 3)
        err += np.sum(np.abs(ub[:, 0] * la[:, 0] + ub[:, 1] * la[:, 1] + la[:, 2])
                      + np.abs(ua[:, 0] * lb[:, 0] + ua[:, 1] * lb[:, 1] + lb[:, 2]))
        n += len(a)
    return {"rms": rms, "K1": K1, "K2": K2, "D1": D1.ravel(), "T": T.ravel(), "R": R, "epi": err / n}


@pytest.fixture(scope="module")
def reference():
    greys = {(side, i): cv2.imread(str(DATA / f"{side}{i}.jpg"), cv2.IMREAD_GRAYSCALE)
             for side in ("left", "right") for i in IDS}
    size = greys[("left", IDS[0])].shape[::-1]
    sample = {k: _sample_corners(g) for k, g in greys.items()}
    ours = {k: find_board_corners(g, BOARD) for k, g in greys.items()}
    pairs = [i for i in IDS if sample[("left", i)] is not None and sample[("right", i)] is not None]
    ref = _sample_solve([sample[("left", i)] for i in pairs], [sample[("right", i)] for i in pairs], size)
    same_corners = _sample_solve([ours[("left", i)] for i in pairs], [ours[("right", i)] for i in pairs], size)
    return {"pairs": pairs, "size": size, "ref": ref, "same_corners": same_corners,
            "sample_corners": sample, "our_corners": ours}


def _read_opencv_yml(path, *names):
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    assert fs.isOpened(), path
    out = {n: fs.getNode(n).mat() for n in names}
    fs.release()
    return out


@pytest.fixture(scope="module")
def cli_sample_mode(reference, tmp_path_factory):
    out = tmp_path_factory.mktemp("ocv_sample")
    rc = main(["calib", "stereo", "--dir", str(DATA), "--board", "9x6", "--square", "1",
               "--mode", "opencv-sample", "--out", str(out / "stereo.yaml"),
               "--export-opencv", str(out)])
    assert rc == 0
    return out


def test_reference_uses_all_13_pairs(reference):
    # the sample finds the board in every pair of its list
    assert reference["pairs"] == IDS


def test_cli_opencv_sample_mode_matches_stereo_calib_sample(reference, cli_sample_mode, capsys):
    ref = reference["ref"]
    intr = _read_opencv_yml(cli_sample_mode / "intrinsics.yml", "M1", "D1", "M2", "D2")
    extr = _read_opencv_yml(cli_sample_mode / "extrinsics.yml", "R", "T", "R1", "R2", "P1", "P2", "Q")
    M1, M2, T = intr["M1"], intr["M2"], extr["T"].ravel()
    # SAME_FOCAL_LENGTH and FIX_ASPECT_RATIO hold in ours too
    assert M1[0, 0] == pytest.approx(M2[0, 0], rel=1e-9)
    # focal lengths within 1 % of the sample (measured 0.24 %), principal points within 3 px
    assert M1[0, 0] == pytest.approx(ref["K1"][0, 0], rel=0.01)
    assert M1[1, 1] == pytest.approx(ref["K1"][1, 1], rel=0.01)
    np.testing.assert_allclose(M1[:2, 2], ref["K1"][:2, 2], atol=3.0)
    np.testing.assert_allclose(M2[:2, 2], ref["K2"][:2, 2], atol=3.0)
    # baseline within 0.5 % (measured 0.22 %), direction within 0.5 deg, rotation within 0.5 deg
    assert np.linalg.norm(T) == pytest.approx(np.linalg.norm(ref["T"]), rel=0.005)
    cosang = T @ ref["T"] / (np.linalg.norm(T) * np.linalg.norm(ref["T"]))
    assert np.degrees(np.arccos(min(1.0, cosang))) < 0.5
    dR = extr["R"] @ ref["R"].T
    assert np.degrees(np.arccos(np.clip((np.trace(dR) - 1) / 2, -1, 1))) < 0.5
    # the first radial coefficient has the sample's sign and size (barrel, about -0.2)
    assert intr["D1"].ravel()[0] == pytest.approx(ref["D1"][0], abs=0.1)
    # rectification is consistent with the exported extrinsics: P2's tx = -f * baseline
    assert extr["P2"][0, 3] == pytest.approx(-extr["P2"][0, 0] * np.linalg.norm(T), rel=0.01)


def test_rms_no_worse_than_sample_and_explained_by_corners(reference, capsys):
    ref, same = reference["ref"], reference["same_corners"]
    rc = main(["calib", "stereo", "--dir", str(DATA), "--board", "9x6", "--square", "1", "--mode", "opencv-sample"])
    out = capsys.readouterr().out
    assert rc == 0
    assert "views used: 13, skipped: 0" in out
    rms = float(out.split("overall RMS reprojection error:")[1].split("px")[0])
    epi = float(out.split("mean epipolar error:")[1].split("px")[0])
    # sample: RMS 0.60 px, epipolar 0.5 px; ours is lower, never higher
    assert 0.2 < rms <= ref["rms"] + 0.02
    assert epi <= ref["epi"] + 0.02
    # with our corners the sample's own solve (k6 free) gives nearly our RMS: the difference
    # comes from the corners, not from the solve
    assert rms == pytest.approx(same["rms"], abs=0.02)
    # ... and the corners differ where the sample's 23 px window spans a neighbouring square
    worst = {}
    for key, c in reference["sample_corners"].items():
        worst[key] = float(np.max(np.linalg.norm(c.reshape(-1, 2) - reference["our_corners"][key], axis=1)))
    assert worst[("left", "02")] > 2.0
    assert np.median(list(worst.values())) < 0.1


def test_default_mode_consistent_baseline(reference, capsys):
    rc = main(["calib", "stereo", "--dir", str(DATA), "--board", "9x6", "--square", "0.025"])
    out = capsys.readouterr().out
    assert rc == 0
    baseline_m = float(out.split("baseline:")[1].split("m")[0])
    # the board's squares are unknown upstream; in units of squares the baselines agree to 0.5 %
    assert baseline_m / 0.025 == pytest.approx(np.linalg.norm(reference["ref"]["T"]), rel=0.005)
