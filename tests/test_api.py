"""The public Python API: `import dancesynth` is cheap, and its functions do what the commands do."""

import subprocess
import sys

import numpy as np
import pytest
import soundfile

import dancesynth
from dancesynth.core.errors import DancesynthError
from dancesynth.core.skeleton import PoseSequence

TINY_LSTM = dict(hidden=16, layers=1, dropout=0.0, window_frames=30, batch_size=4, epoch_windows=0)
SR = 22050


def test_import_is_cheap_and_exposes_the_api():
    script = ("import sys, dancesynth\n"
              "print(dancesynth.dance, dancesynth.__version__)\n"
              "print(sorted(m for m in ('torch', 'numpy', 'cv2', 'librosa', 'apps.pipeline') if m in sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout
    first, second = out.strip().splitlines()
    assert first.startswith("<function dance") and first.endswith(dancesynth.__version__)
    assert second == "[]"
    assert {"dance", "generate", "train_pose", "train_video", "extract_poses", "render"} <= set(dir(dancesynth))


def test_train_pose_then_generate_end_to_end(tiny_stage1_dataset, tmp_path, drum_loop):
    run = tmp_path / "run"
    meta = dancesynth.train_pose("lstm", data=tiny_stage1_dataset, out=run, overrides=TINY_LSTM, epochs=1,
                                 preview_every=0, device="cpu")
    assert (meta["method"], meta["epoch"]) == ("lstm", 1)
    samples, _ = drum_loop(120, 3.0, SR)
    song = tmp_path / "song.wav"
    soundfile.write(song, samples, SR)
    out = tmp_path / "dance.npz"
    poses = dancesynth.generate(song, model=run, out=out, seed=1, device="cpu")
    assert len(poses) == 45 and poses.fps == 15.0  # 3 s at the model's 15 fps
    np.testing.assert_array_equal(PoseSequence.load(out).keypoints, poses.keypoints)
    with np.load(out) as saved:  # the song's beats and downbeats (seconds) travel with the dance
        assert len(saved["beats"]) >= 4 and np.all(np.isin(saved["downbeats"], saved["beats"]))
    dsp = dancesynth.generate(song, model=run, out=tmp_path / "dsp.npz", seed=1, device="cpu", beats="dsp")
    with np.load(tmp_path / "dsp.npz") as saved:
        assert np.array_equal(saved["downbeats"], saved["beats"][::4]) and len(dsp) == 45


def test_a_video_named_as_another_format_is_refused_before_any_work(tmp_path):
    # The command line refuses these names while parsing; the API refuses them too, before it loads anything.
    song = tmp_path / "song.wav"
    soundfile.write(song, np.zeros(SR, np.float32), SR)
    calls = [lambda: dancesynth.dance(song, out=tmp_path / "d.webm", video_model=tmp_path / "no_model"),
             lambda: dancesynth.render(tmp_path / "p.npz", model=tmp_path / "no_model", out=tmp_path / "r.mp4",
                                       side_by_side=tmp_path / "s.gif"),
             lambda: dancesynth.generate(song, out=tmp_path / "p.npz", preview=tmp_path / "p.avi"),
             lambda: dancesynth.extract_poses(tmp_path / "v.mp4", preview=tmp_path / "o")]
    for call in calls:
        with pytest.raises(DancesynthError, match=r"would hold an MP4 video; give it a name ending in \.mp4\.$"):
            call()
    assert [p.name for p in tmp_path.iterdir()] == ["song.wav"]


def test_numbers_and_choices_are_checked_as_the_command_line_checks_them(tmp_path):
    # The same options define both; the API says which argument is wrong in one sentence, before any work.
    song = tmp_path / "song.wav"
    soundfile.write(song, np.zeros(SR, np.float32), SR)
    out = tmp_path / "d.mp4"
    calls = {r"seed: must be at most 2147483647, got '1180591620717411303424'\.$": lambda: dancesynth.generate(
                 song, out=tmp_path / "p.npz", seed=2**70),
             r"seed: must be 0 or more, got '-1'\.$": lambda: dancesynth.generate(song, seed=-1),
             r"seed: must be a whole number, got '2.5'\.$": lambda: dancesynth.generate(song, seed=2.5),
             r"beats: 'nope' is not one of combined, learned, dsp\.$": lambda: dancesynth.dance(
                 song, out=out, video_model=tmp_path / "run", beats="nope"),
             r"start: must be a finite number, got 'nan'\.$": lambda: dancesynth.dance(
                 song, out=out, video_model=tmp_path / "run", start=float("nan")),
             r"height: must be 16 to 4320 pixels, got '-3'\.$": lambda: dancesynth.render(
                 tmp_path / "p.npz", model=tmp_path / "run", out=out, height=-3),
             r"max_missing: must be between 0 and 1, got '1.5'\.$": lambda: dancesynth.extract_poses(
                 tmp_path / "v.mp4", max_missing=1.5),
             r"method: 'nope' is not one of dance_revolution, ": lambda: dancesynth.train_pose(
                 "nope", data=tmp_path, out=tmp_path / "run")}
    for message, call in calls.items():
        with pytest.raises(DancesynthError, match=message):
            call()
    assert [p.name for p in tmp_path.iterdir()] == ["song.wav"]
