#!/usr/bin/env bash
# Regenerates docs/stage1_report: the built-in dataset (60 songs: 48 train / 6 val / 6 test), every stage-1
# method's `small` preset (Ren with its ST-GCN; the LSTM baseline for its 60 epochs, at most 10 min), then
# `dancesynth evaluate`.
# Usage: benchmarks/stage1_report.sh [WORK_DIR] [REPORT_DIR]   (about 1.5 h on one CPU core; finished steps are skipped)
set -euo pipefail
WORK=${1:-stage1_report_work}
REPORT=${2:-docs/stage1_report}
DS="$WORK/ds60"
RUNS="$WORK/runs"
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
VENV_BIN="$(dirname "$0")/../.venv/bin/dancesynth"
DANCESYNTH=${DANCESYNTH:-$([ -x "$VENV_BIN" ] && echo "$VENV_BIN" || echo dancesynth)}
ds() { "$DANCESYNTH" "$1" -q "${@:2}"; }
[ -f "$DS/manifest.json" ] || ds make-dataset --out "$DS" --clips 60 --seconds 60
for m in dance_revolution dancing2music; do
  [ -f "$RUNS/$m/latest.json" ] || ds train-pose --method "$m" --data "$DS" --out "$RUNS/$m" --preset small --preview-every 0
done
[ -f "$RUNS/stgcn/latest.json" ] || ds train-stgcn --data "$DS" --out "$RUNS/stgcn"
[ -f "$RUNS/ren/latest.json" ] || ds train-pose --method ren --data "$DS" --out "$RUNS/ren" --preset small \
  --preview-every 0 --set "stgcn_run=$RUNS/stgcn"
[ -f "$RUNS/lstm/latest.json" ] || ds train-pose --method lstm --data "$DS" --out "$RUNS/lstm" --preset small \
  --minutes 10 --preview-every 0
rm -rf "$REPORT.new"
"$DANCESYNTH" evaluate --data "$DS" --models "$RUNS/dance_revolution" "$RUNS/dancing2music" "$RUNS/ren" "$RUNS/lstm" \
  --out "$REPORT.new" --trials 3 --seconds 60 --device cpu --grid-video
[ -f "$REPORT/README.md" ] && cp "$REPORT/README.md" "$REPORT.new/"
rm -rf "$REPORT" && mv "$REPORT.new" "$REPORT"
