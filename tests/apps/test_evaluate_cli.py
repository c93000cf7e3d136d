"""`dancesynth train-style-classifier` and `dancesynth evaluate` from the command line."""

import json

import numpy as np
import pytest
import torch

from apps.cli import main
from dancesynth.core import media


@pytest.fixture(autouse=True, scope="module")
def one_torch_thread():
    # Tiny LSTMs: thread synchronisation costs more than it saves (60x slower with 2 threads on a loaded 2-core box).
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def test_evaluate_a_tiny_lstm_end_to_end(tmp_path, capsys):
    data, clf, run, out = (tmp_path / n for n in ("data", "clf", "lstm", "report"))
    assert main(["make-dataset", "--out", str(data), "--clips", "4", "--seconds", "6"]) == 0
    assert main(["train-style-classifier", "--data", str(data), "--out", str(clf), "--preset", "small",
                 "--steps", "30", "--device", "cpu"]) == 0
    assert "accuracy on the test split's real dances" in capsys.readouterr().err
    assert main(["train-pose", "--method", "lstm", "--data", str(data), "--out", str(run), "--preset", "small",
                 "--epochs", "1", "--batch-size", "2", "--window", "30", "--preview-every", "0",
                 "--set", "epoch_windows=0", "--device", "cpu"]) == 0
    assert main(["evaluate", "--data", str(data), "--models", str(run), "--out", str(out), "--classifier", str(clf),
                 "--trials", "2", "--seconds", "6", "--video-seconds", "1", "--device", "cpu", "--grid-video"]) == 0
    printed = capsys.readouterr().err
    assert "| lstm |" in printed and "| real dances |" in printed
    rows = {r["name"]: r for r in json.loads((out / "report.json").read_text())["rows"]}
    assert set(rows) == {"real dances", "random real dance", "mean pose (frozen)", "lstm"}
    # One test song: diversity needs two, so it is reported as undefined rather than failing.
    assert rows["lstm"]["summary"]["diversity"]["trials"] == 0
    # The LSTM baseline is deterministic: the same song gives the same dance for every seed.
    assert rows["lstm"]["multimodality"] == pytest.approx(0.0, abs=1e-9)
    assert len(rows["lstm"]["per_trial"]["fid"]) == 2
    assert (out / "videos" / "lstm.mp4").is_file()
    # Grid: real dances, lstm, random real dance in the first row of 426 x 240 tiles, the frozen pose below.
    frames = list(media.read_frames(out / "grid.mp4"))
    assert len(frames) == 15 and frames[0].shape == (480, 1278, 3)
    inner = (slice(40, 230), slice(20, 406))  # a tile without its beat-flash border and label
    moved = [np.abs(frames[-1][r * 240:, c * 426:].astype(int)[inner] - frames[0][r * 240:, c * 426:][inner]).mean()
             for r, c in ((0, 0), (1, 0))]
    assert moved[0] > 1.0 and moved[1] < 0.5

    # --beat-snap scores the dances as `dance` makes them: only the model's row changes, and the report says so.
    snapped = tmp_path / "snapped"
    assert main(["evaluate", "--data", str(data), "--models", str(run), "--out", str(snapped), "--classifier",
                 str(clf), "--trials", "1", "--seconds", "6", "--video-seconds", "1", "--device", "cpu",
                 "--beat-snap"]) == 0
    again = {r["name"]: r for r in json.loads((snapped / "report.json").read_text())["rows"]}
    assert again["real dances"]["summary"] == rows["real dances"]["summary"]
    assert again["lstm"]["per_trial"]["fid"][0] != rows["lstm"]["per_trial"]["fid"][0]
    assert "retimed onto the beats" in (snapped / "report.md").read_text()


def test_errors_are_one_sentence_without_traceback(tmp_path, capsys):
    assert main(["evaluate", "--data", str(tmp_path / "nope"), "--out", str(tmp_path / "r")]) == 1
    err = capsys.readouterr().err
    assert "does not exist" in err and "make-dataset" in err and "Traceback" not in err
    assert not (tmp_path / "r").exists()
    assert main(["train-style-classifier", "--data", str(tmp_path / "nope"), "--out", str(tmp_path / "c")]) == 1
    assert "make-dataset" in capsys.readouterr().err
