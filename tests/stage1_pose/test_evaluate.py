"""The evaluation driver end to end on a constructed dataset: real-dance and baseline rows, known answers,
and the physical-plausibility columns (zero bone-length error for the built-in real dances)."""

import dataclasses
import json
import shutil

import numpy as np
import pytest
import soundfile
import torch
from test_style_classifier import toy_dance

from dancesynth.core import media
from dancesynth.core.skeleton import JOINT_INDEX, PoseSequence
from stage1_pose.data.dataset import Clip, DanceDataset, clip_paths, create_layout, write_beats, write_manifest
from stage1_pose.data.styles import STYLES
from stage1_pose.data.synth_dance import synthesize_dance
from stage1_pose.evaluate import (
    COLUMNS,
    FROZEN,
    RANDOM_REAL,
    REAL,
    Contender,
    EvaluationOptions,
    HeldOutSong,
    evaluate_contender,
    fit_length,
    load_reference,
    obtain_classifier,
    run_evaluation,
)
from stage1_pose.train import train

SR = 22050
SECONDS = 8.0
BPM = 150.0  # 2.5 beats per second, the toy "bounce" style's frequency


@pytest.fixture(autouse=True, scope="module")
def one_torch_thread():
    # Tiny LSTMs: thread synchronisation costs more than it saves (60x slower with 2 threads on a loaded 2-core box).
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def click_track(seconds: float) -> tuple[np.ndarray, np.ndarray]:
    beats = np.arange(0.2, seconds, 60.0 / BPM)
    y = np.zeros(int(seconds * SR), np.float32)
    t = np.arange(int(0.03 * SR)) / SR
    click = (0.6 * np.sin(2 * np.pi * 80 * t) * np.exp(-t / 0.01)).astype(np.float32)
    for b in beats:
        i = int(b * SR)
        y[i:i + len(click)] += click[: len(y) - i]
    return y, beats


def build_dataset(root):
    """Two training songs and one test song per toy style (wave, bounce, sway)."""
    create_layout(root)
    styles = ["wave", "bounce", "sway"]
    samples, beats = click_track(SECONDS)
    clips = []
    for k in range(9):
        style = k % 3
        cid = f"clip{k}"
        paths = clip_paths(cid)
        soundfile.write(root / paths["audio"], samples, SR)
        toy_dance(style, seed=k, frames=int(SECONDS * 15)).save(root / paths["poses"])
        write_beats(root / paths["beats"], beats, beats[::4], BPM, "exact")
        clips.append(Clip(cid, cid, styles[style], "test" if k >= 6 else "train", **paths))
    write_manifest(root, 15.0, SR, styles, clips)
    return root


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    data = build_dataset(tmp_path_factory.mktemp("data"))
    out = tmp_path_factory.mktemp("report")
    options = EvaluationOptions(trials=2, seconds=SECONDS, device="cpu", classifier_preset="small",
                                video_seconds=2.0, plot_seconds=SECONDS, grid_video=True)
    rows = run_evaluation(data, [], out, options)
    return data, out, {r.name: r for r in rows}, options


def test_report_files_and_rows(report):
    data, out, rows, _ = report
    for name in ("report.md", "report.json", "fid_over_time.png", "beat_alignment.png"):
        assert (out / name).stat().st_size > 0
    assert len(list((out / "videos").glob("*.mp4"))) == 3
    text = (out / "report.md").read_text()
    for name in (REAL, RANDOM_REAL, FROZEN):
        assert f"| {name} |" in text
    saved = json.loads((out / "report.json").read_text())
    assert [r["name"] for r in saved["rows"]] == [REAL, RANDOM_REAL, FROZEN]
    assert saved["rows"][0]["multimodality"] is None  # undefined for the real dances, strict JSON null
    # The classifier was trained once and cached under the dataset folder.
    assert (data / "style_classifier" / "small" / "latest.json").is_file()


def test_grid_video_shows_every_row_to_the_first_test_song_with_its_audio(report):
    _, out, rows, _ = report
    streams = media.probe_streams(out / "grid.mp4")
    info = media.probe_video(out / "grid.mp4")
    # Three rows in one row of three 426 x 240 tiles, 2 s at 15 fps, with the song.
    assert streams["video_frames"] == 30 and (info.width, info.height) == (1278, 240)
    assert streams["audio_codec"] == "aac" and abs(streams["audio_duration"] - 2.0) <= 1 / 15


def test_model_folders_of_one_name_keep_their_own_rows_and_sample_videos(report, tmp_path):
    data, _, _, options = report
    first, second = tmp_path / "a" / "lstm", tmp_path / "b" / "lstm"
    train("lstm", data, first, overrides=dict(hidden=16, layers=1, window_frames=30, batch_size=4, epoch_windows=0),
          epochs=1, device="cpu")
    shutil.copytree(first, second)
    out = tmp_path / "report"
    options = dataclasses.replace(options, trials=1, grid_video=False)
    rows = run_evaluation(data, [str(first), str(second)], out, options)
    assert [r.name for r in rows] == [REAL, RANDOM_REAL, FROZEN, "a/lstm", "b/lstm"]
    assert (out / "videos" / "a_lstm.mp4").is_file() and (out / "videos" / "b_lstm.mp4").is_file()
    assert len(list((out / "videos").glob("*.mp4"))) == 5


def test_real_dances_are_recognised_and_closer_to_training_data_than_a_frozen_pose(report):
    _, _, rows, _ = report
    real, frozen = rows[REAL].summary(), rows[FROZEN].summary()
    assert real["acc"]["mean"] == 1.0
    assert real["fid"]["mean"] < frozen["fid"]["mean"]
    assert len(rows[REAL].fid_curve) == int(SECONDS * 15) // 30


def test_frozen_dance_has_no_kinematic_beats_and_no_multimodality(report):
    _, _, rows, _ = report
    frozen = rows[FROZEN].summary()
    assert frozen["coverage_d2m"]["mean"] == pytest.approx(0.0, abs=0.05)
    assert frozen["beat_align"]["mean"] == pytest.approx(0.0, abs=0.05)
    assert rows[FROZEN].multimodality == 0.0
    assert np.isnan(rows[REAL].multimodality)
    assert rows[RANDOM_REAL].multimodality > 0.0
    assert frozen["diversity"]["mean"] == 0.0


def test_plausibility_columns_in_the_report_with_known_answers_for_the_reference_rows(report):
    _, out, rows, _ = report
    header = (out / "report.md").read_text().splitlines()
    saved = json.loads((out / "report.json").read_text())
    for key, title, _, _ in COLUMNS[-6:]:
        assert any(line.startswith("| Method |") and title in line for line in header)
        assert all(key in r["summary"] for r in saved["rows"])
    real, frozen = rows[REAL].summary(), rows[FROZEN].summary()
    assert real["speed_vs_real"]["mean"] == pytest.approx(1.0)
    assert real["legs_arms"]["mean"] > 0 and real["jerk"]["mean"] > 0
    assert frozen["speed_vs_real"]["mean"] == 0.0 and frozen["jerk"]["mean"] == 0.0
    assert np.isnan(frozen["legs_arms"]["mean"])  # nothing moves: the ratio is undefined
    assert rows[FROZEN].per_trial["bone_error"][0] == pytest.approx(0.0, abs=1e-6)  # one body, held still
    assert real["upside_down"]["mean"] == 0.0 and frozen["upside_down"]["mean"] == 0.0


def test_built_in_real_dances_have_zero_bone_length_error(report):
    data, _, _, options = report
    ds = DanceDataset(data)
    clf, _ = obtain_classifier(ds, options)  # cached by the report fixture
    ref = load_reference(ds, clf)
    beats = np.arange(0.2, SECONDS, 0.5)
    songs = [HeldOutSong(f"built-in {name}", k, np.zeros(int(SECONDS * SR), np.float32), SR, beats,
                         synthesize_dance(STYLES[name], beats, int(SECONDS * 15), np.random.default_rng(k)),
                         ref.music[k]) for k, name in enumerate(sorted(STYLES))]
    row = evaluate_contender(Contender(REAL, lambda i, seed: songs[i].real, stochastic=False), songs, ref, clf,
                             trials=1, tolerance_frames=2).summary()
    # Zero up to float32 pixel rounding (the report shows 0.0 %).
    assert row["bone_error"]["mean"] == pytest.approx(0.0, abs=1e-4)
    assert row["bone_error_p99"]["mean"] == pytest.approx(0.0, abs=1e-4)
    assert row["speed_vs_real"]["mean"] == pytest.approx(1.0)
    # The same dances with the right forearm twice as long in every third frame: a body that does not keep its length.
    elbow, wrist = JOINT_INDEX["RElbow"], JOINT_INDEX["RWrist"]

    def stretched(i: int, seed: int) -> PoseSequence:
        kp = songs[i].real.keypoints.copy()
        kp[::3, wrist, :2] += kp[::3, wrist, :2] - kp[::3, elbow, :2]
        return songs[i].real.replace(kp)

    row = evaluate_contender(Contender("stretched", stretched, stochastic=False), songs, ref, clf,
                             trials=1, tolerance_frames=2).summary()
    assert row["bone_error_p99"]["mean"] == pytest.approx(1.0, abs=0.01)  # +100 % on 1 of 24 bones in 1/3 of frames
    assert row["bone_error"]["mean"] == pytest.approx(1 / 72, abs=0.003)


def test_fit_length_cuts_and_loops():
    seq = toy_dance(0, 0, frames=10)
    assert len(fit_length(seq, 4)) == 4
    looped = fit_length(seq, 25)
    np.testing.assert_array_equal(looped.keypoints[20:], seq.keypoints[:5])
