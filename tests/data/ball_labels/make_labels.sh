#!/bin/sh
# Re-creates labels.csv from the videos with the review decisions recorded below
# (see README.md). Run from the repository root; sheets go to /tmp for review.
set -e
V=../shared/realdata/ball_videos
OUT=tests/data/ball_labels/labels.csv
L=".venv/bin/python -m tudorvision.cli label balls"
rm -f "$OUT"
$L $V/ball2.mp4 --frames 0:36:12,36:972:12,972:1004:12 --pick 660=424,81 --out "$OUT" --sheet /tmp/ball_labels/ball2.png \
   --unclean 240="partly out of frame (bottom)" --unclean 576="partly out of frame (top)" \
   --unclean 648="partly out of frame (bottom)" --unclean 960="partly out of frame (right)" \
   --set 300=125,127,32.5 --note 300="proposal too large (hand blob); rim read off the 3x grid"
$L $V/ball3.mp4 --frames 84:440:6 --pick 180=904,96 --out "$OUT" --sheet /tmp/ball_labels/ball3.png \
   --none 120 --none 132 --none 138 --none 144 --none 438 \
   --note 120="no ball (proposal on the wall)" --note 132="no ball (proposal on the wall)" \
   --note 138="no ball (proposal on the wall)" --note 144="no ball (proposal on the wall)" \
   --note 438="ball leaving at the right edge, only a sliver visible" \
   --unclean 156="partly out of frame (right)" --unclean 276="partly out of frame (top)" \
   --unclean 282="partly out of frame (top)" --unclean 288="partly out of frame (top)" \
   --set 162=1182,86,35 --note 162="proposal 2 px small at the pale top rim; rim read off the 5x grid"
$L $V/ball4.mp4 --frames 100:118:6,118:440:6,442:480:6 --pick 210=940,355 --out "$OUT" --sheet /tmp/ball_labels/ball4.png \
   --unclean 118="partly out of frame (right)" --unclean 184="heavy motion blur" \
   --unclean 424="heavy motion blur" --unclean 430="heavy motion blur" --unclean 436="heavy motion blur"
