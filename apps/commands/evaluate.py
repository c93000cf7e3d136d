"""`dancesynth evaluate`: every stage-1 metric for trained models and baselines, one report."""

from __future__ import annotations

import argparse
import logging

from apps.arguments import non_negative_float, output_folder, positive_float, positive_int

NAME = "evaluate"
HELP = "evaluate stage-1 pose models on the held-out songs: FID, ACC, beat metrics, diversity, plots"
DESCRIPTION = """\
Generate dances for the test-split songs of a dataset with every model given, and score them together with
three reference rows: the real dances, a random real training dance on the wrong music, and a frozen mean pose.
Metrics (mean ± std over --trials seeds): FID and ACC from a style classifier (LSTM, hidden 200), beat
coverage and hit rate with two kinematic beat definitions (Dancing2Music offsets, velocity minima),
Bailando's Beat Align Score, diversity, multimodality, long-term FID over 4-s windows, and Ren et al.'s
cross-modal distance. The style classifier is trained once and cached in DATA/style_classifier/PRESET unless
--classifier gives one (train it with `dancesynth train-style-classifier`). A model's row is named after its
folder (PARENT/NAME when two folders share a name).

Writes into REPORT_DIR: report.md (table), report.json (every number, per trial), fid_over_time.png,
beat_alignment.png and videos/<row>.mp4 (skeleton previews with the song); with --grid-video also grid.mp4:
every row dancing to the same test song side by side (real dance first), flashing on each music beat.

examples:
  dancesynth evaluate --data data/builtin --models runs/dance_revolution runs/lstm --out reports/stage1
  dancesynth evaluate --data data/builtin --out reports/baselines --trials 2 --seconds 30
  dancesynth evaluate --data data/builtin --models runs/lstm --out reports/lstm --grid-video
"""

logger = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    # Defaults live in stage1_pose.evaluate.EvaluationOptions; None here means "use it" (keeps --help fast).
    parser.add_argument("--data", required=True, metavar="DIR", help="dataset folder (dancesynth make-dataset)")
    parser.add_argument("--models", nargs="*", default=[], metavar="RUN_DIR",
                        help="stage-1 run folders written by train-pose (none: baselines only)")
    parser.add_argument("--out", type=output_folder, required=True, metavar="REPORT_DIR",
                        help="folder for the report (created)")
    parser.add_argument("--trials", type=positive_int, help="seeds per model (default 3)")
    parser.add_argument("--seconds", type=positive_float, help="seconds of each test song to dance to (default 60)")
    parser.add_argument("--classifier", metavar="RUN_DIR", help="style classifier run (default: train/cache one)")
    parser.add_argument("--classifier-preset", choices=("paper", "small"),
                        help="preset when the classifier is trained here (default paper)")
    parser.add_argument("--tolerance", type=non_negative_float, dest="tolerance_frames",
                        help="beat hit tolerance in pose frames (default ±2)")
    parser.add_argument("--video-seconds", type=positive_float, help="length of the sample videos (default 10 s)")
    parser.add_argument("--grid-video", action="store_true",
                        help="also write grid.mp4: every row side by side on the first test song, beats flashing")
    parser.add_argument("--beat-snap", action="store_true", default=None,
                        help="score the models' dances retimed onto the song's beats, as `dance` and `generate` "
                             "make them (default: each method's own timing, as the papers score it)")
    parser.add_argument("--device", help="auto, cpu or cuda (default auto)")


def run(args: argparse.Namespace) -> None:
    from dancesynth.core.fileio import check_outputs
    from stage1_pose.evaluate import EvaluationOptions, markdown_table, run_evaluation

    for model in args.models or [None]:
        check_outputs({}, {"dataset": args.data, "style classifier": args.classifier, "pose model": model},
                      folders={"report folder": args.out})
    names = ("trials", "seconds", "device", "classifier", "classifier_preset", "tolerance_frames", "video_seconds",
             "grid_video", "beat_snap")
    options = EvaluationOptions(**{k: getattr(args, k) for k in names if getattr(args, k) is not None})
    rows = run_evaluation(args.data, args.models, args.out, options)
    logger.info(markdown_table(rows))
    grid = ", grid.mp4" if options.grid_video else ""
    logger.info(f"wrote {args.out}/report.md, report.json, fid_over_time.png, beat_alignment.png, videos/{grid}")
