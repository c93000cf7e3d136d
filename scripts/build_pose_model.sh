#!/usr/bin/env bash
# Builds the package's default pose model (stage1_pose/pretrained/dance_revolution): the built-in dataset of
# 60 songs x 60 s, Dance Revolution's `small` preset (60 epochs, about 25 min on one CPU core), its quality
# check on held-out songs, then the weights-only export. The same dataset and run as benchmarks/stage1_report.sh,
# so a WORK folder of that script is reused.
# Usage: scripts/build_pose_model.sh [WORK_DIR]   (default stage1_report_work; finished steps are skipped)
set -euo pipefail
WORK=${1:-stage1_report_work}
DS="$WORK/ds60"
RUN="$WORK/runs/dance_revolution"
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
BIN="$(dirname "$0")/../.venv/bin"
[ -x "$BIN/dancesynth" ] || BIN="$(dirname "$(command -v dancesynth)")"
[ -f "$DS/manifest.json" ] || "$BIN/dancesynth" make-dataset -q --out "$DS" --clips 60 --seconds 60
[ -f "$RUN/latest.json" ] || "$BIN/dancesynth" train-pose -q --method dance_revolution --data "$DS" --out "$RUN" \
  --preset small --preview-every 0
"$BIN/dancesynth" check "$RUN" --data "$DS" --clips 3 --seconds 60 --seeds 0 1 --json "$RUN/check.json"
"$BIN/python" -m stage1_pose.pretrained "$RUN"
