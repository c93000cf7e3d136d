"""`dancesynth dance`: song in any common format + tiny trained models -> mp4 with the song's audio."""

from pathlib import Path

import av
import numpy as np
import pytest
import torch

torch.set_num_threads(1)

from apps.cli import main  # noqa: E402
from dancesynth.core.media import VideoWriter, decode_audio, probe_streams, probe_video  # noqa: E402
from dancesynth.core.skeleton import PoseSequence  # noqa: E402
from stage1_pose.train import train  # noqa: E402
from stage2_video.synthetic_person import appearance_preset, write_person_video  # noqa: E402
from stage2_video.train import TrainOptions, train_video  # noqa: E402

TINY_LSTM = dict(hidden=16, layers=1, dropout=0.0, window_frames=30, batch_size=4, epoch_windows=0)
TINY_VIDEO = {"width": 32, "height": 32, "ngf": 8, "n_downsample": 2, "n_blocks": 1, "ndf": 8, "batch_size": 4}
SR = 22050


@pytest.fixture(scope="module")
def models(tiny_stage1_dataset, tmp_path_factory) -> tuple[Path, Path]:
    """(pose run, video run), each trained for a moment: enough for complete checkpoints."""
    root = tmp_path_factory.mktemp("dance_models")
    pose_run = root / "pose"
    train("lstm", tiny_stage1_dataset, pose_run, overrides=TINY_LSTM, epochs=1, device="cpu")
    seq = PoseSequence.load(tiny_stage1_dataset / "poses" / "clip0.npz").slice_frames(0, 30)
    s = 64 / seq.height
    seq = PoseSequence(seq.keypoints * (s, s, 1), seq.fps, round(seq.width * s), 64)
    seq.save(root / "target.npz")
    write_person_video(seq, root / "target.mp4", appearance_preset("red_tee"))
    video_run = root / "video"
    train_video(root / "target.mp4", video_run, "small", TrainOptions(epochs=1, max_steps=2, val_frames=4),
                poses=root / "target.npz", device="cpu", overrides=TINY_VIDEO)
    return pose_run, video_run


def _song(path: Path, seconds: float = 3.0) -> Path:
    """A click track with a chord, encoded in the format the file extension names."""
    t = np.arange(int(seconds * SR)) / SR
    y = 0.2 * np.sin(2 * np.pi * 220 * t) + 0.5 * (np.mod(t, 0.5) < 0.02)
    codec = {".wav": "pcm_s16le", ".mp3": "libmp3lame", ".ogg": "libopus", ".m4a": "aac"}[path.suffix]
    with av.open(str(path), "w") as out:
        stream = out.add_stream(codec, rate={"aac": 44100, "libopus": 48000}.get(codec, SR), layout="mono")
        frame_format = stream.codec_context.format.name
        rate = stream.codec_context.sample_rate
        samples = np.interp(np.arange(int(seconds * rate)) / rate, t, y).astype(np.float32)
        if frame_format.startswith("s"):  # integer sample formats: s16, s32 (planar or not)
            bits = 16 if "16" in frame_format else 32
            samples = (samples * (2 ** (bits - 1) - 1)).astype(np.int16 if bits == 16 else np.int32)
        frame = av.AudioFrame.from_ndarray(samples[None], format=frame_format, layout="mono")
        frame.sample_rate = rate
        for packet in stream.encode(frame):
            out.mux(packet)
        for packet in stream.encode(None):
            out.mux(packet)
    return path


@pytest.mark.parametrize("ext", [".wav", ".mp3", ".ogg", ".m4a"])
def test_dance_writes_a_video_with_the_song_segment(models, tmp_path, capsys, ext):
    pose_run, video_run = models
    song = _song(tmp_path / f"song{ext}")
    out, side = tmp_path / "dance.mp4", tmp_path / "side.mp4"
    code = main(["dance", str(song), "--pose-model", str(pose_run), "--video-model", str(video_run),
                 "--out", str(out), "--start", "0.5", "--duration", "2", "--side-by-side", str(side),
                 "--device", "cpu"])
    assert code == 0, capsys.readouterr().err
    # The target's whole scene at the target video's resolution, not the model's 32-px crop.
    info, target = probe_video(out), probe_video(video_run.parent / "target.mp4")
    assert (info.width, info.height) == (target.width, target.height)
    streams = probe_streams(out)
    fps = info.fps
    assert abs(streams["video_duration"] - 2.0) <= 1 / fps
    assert abs(streams["audio_duration"] - streams["video_duration"]) <= 1 / fps
    assert (probe_video(side).width, probe_video(side).height) == (2 * target.width, target.height)
    # The muxed audio is the chosen segment of the song (the click train), not silence.
    assert np.sqrt(np.mean(decode_audio(out, 8000) ** 2)) > 0.05
    assert str(out) in capsys.readouterr().err


def test_crop_keeps_the_model_resolution_and_height_scales_the_scene(models, tmp_path):
    pose_run, video_run = models
    song = _song(tmp_path / "song.wav", seconds=2.0)
    common = ["--pose-model", str(pose_run), "--video-model", str(video_run), "--device", "cpu"]
    assert main(["dance", str(song), *common, "--out", str(tmp_path / "crop.mp4"), "--crop"]) == 0
    # The model's crop at the warped prior's scale (twice the 32-px network's resolution).
    assert (probe_video(tmp_path / "crop.mp4").width, probe_video(tmp_path / "crop.mp4").height) == (64, 64)
    assert main(["dance", str(song), *common, "--out", str(tmp_path / "h.mp4"), "--height", "128"]) == 0
    target, scaled = probe_video(video_run.parent / "target.mp4"), probe_video(tmp_path / "h.mp4")
    assert scaled.height == 128 and abs(scaled.width / scaled.height - target.width / target.height) < 0.02


@pytest.mark.parametrize("options, extra", [([], "--side-by-side"), (["--crop"], "--skeleton-preview")])
def test_render_of_a_pose_file_gives_the_frames_dance_gives_the_same_poses(models, tmp_path, monkeypatch, options,
                                                                           extra):
    import apps.pipeline

    pose_run, video_run = models
    # Another canvas, a larger person, another frame rate: every step of the shared pipeline has work to do.
    target = PoseSequence.load(video_run.parent / "target.npz").slice_frames(0, 20)
    poses = PoseSequence(target.keypoints * np.array([2, 2, 1], np.float32), 10.0, 2 * target.width,
                         2 * target.height)
    poses.save(tmp_path / "poses.npz")
    monkeypatch.setattr(apps.pipeline, "generate_dance", lambda *args, **kwargs: poses)
    # The frames as handed to the encoder: x264 need not encode the same frames to the same bits twice.
    written: dict[str, list[np.ndarray]] = {}
    write = VideoWriter.write

    def recorded_write(self: VideoWriter, frame: np.ndarray) -> None:
        written.setdefault(self.path.name, []).append(frame.copy())
        write(self, frame)

    monkeypatch.setattr(VideoWriter, "write", recorded_write)
    song = _song(tmp_path / "song.wav", seconds=2.0)
    for command, inputs in (("dance", [str(song), "--pose-model", str(pose_run), "--video-model", str(video_run)]),
                            ("render", [str(tmp_path / "poses.npz"), "--audio", str(song), "--model", str(video_run)])):
        assert main([command, *inputs, "--out", str(tmp_path / f"{command}.mp4"), *options,
                     extra, str(tmp_path / f"{command}_extra.mp4"), "--device", "cpu"]) == 0
    frames = round(2.0 * probe_video(video_run.parent / "target.mp4").fps)  # 2 s at the target video's fps
    for name in ("{}.mp4", "{}_extra.mp4"):
        danced, rendered = written[name.format("dance")], written[name.format("render")]
        assert len(danced) == len(rendered) == frames == probe_video(tmp_path / name.format("render")).num_frames
        assert all(np.array_equal(a, b) for a, b in zip(danced, rendered))


def test_without_a_pose_model_the_shipped_one_dances(models, tmp_path):
    _, video_run = models
    song = _song(tmp_path / "song.wav", seconds=2.0)
    assert main(["dance", str(song), "--video-model", str(video_run), "--out", str(tmp_path / "d.mp4"),
                 "--device", "cpu"]) == 0
    assert abs(probe_streams(tmp_path / "d.mp4")["video_duration"] - 2.0) <= 1 / 15


def test_dance_from_a_folder_of_runs_picks_the_method(models, tmp_path):
    pose_run, video_run = models
    song = _song(tmp_path / "song.wav")
    runs = tmp_path / "runs"
    runs.mkdir()
    (runs / "lstm").symlink_to(pose_run, target_is_directory=True)
    assert main(["dance", str(song), "--pose-model", str(runs), "--video-model", str(video_run),
                 "--out", str(tmp_path / "a.mp4"), "--device", "cpu"]) == 0
    assert main(["dance", str(song), "--pose-model", str(runs), "--method", "ren", "--video-model",
                 str(video_run), "--out", str(tmp_path / "b.mp4")]) == 1


def test_bad_inputs_are_one_sentence_errors_and_leave_no_file(models, tmp_path, capsys):
    pose_run, video_run = models
    song = _song(tmp_path / "song.wav")
    out = tmp_path / "x.mp4"
    cases = [
        ([str(tmp_path / "missing.mp3"), "--pose-model", str(pose_run), "--video-model", str(video_run)],
         "does not exist"),
        ([str(song), "--pose-model", str(video_run), "--video-model", str(video_run)], "pose model"),
        ([str(song), "--pose-model", str(pose_run), "--video-model", str(pose_run)], "appearance model"),
        ([str(song), "--pose-model", str(pose_run), "--video-model", str(video_run), "--start", "9"],
         "outside the song"),
        ([str(song), "--pose-model", str(pose_run)], "one of the arguments --target --video-model is required"),
        ([str(song), "--target", str(song), "--video-model", str(video_run)], "not allowed with"),
        ([str(song), "--method", "ren", "--video-model", str(video_run)], "built-in pose model is dance_revolution"),
        ([str(song), "--video-model", str(video_run), "--train-minutes", "5"], "apply to --target only"),
        ([str(song), "--video-model", str(video_run), "--crop", "--height", "64"], "use one of them"),
        ([str(song), "--video-model", str(video_run), "--height", "10"], "must be 16 to 4320"),
    ]
    for args, words in cases:
        assert main(["dance", *args, "--out", str(out)]) == 1
        err = capsys.readouterr().err
        assert err.startswith("dancesynth dance: error:") and "Traceback" not in err
        assert words in err, err
        assert list(tmp_path.glob("x*")) == []
