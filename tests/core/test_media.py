"""Media round trips: audio decoding of common formats, video writing with synced audio, clear errors."""

import wave

import av
import numpy as np
import pytest

from dancesynth.core import media
from dancesynth.core.errors import DancesynthError

SR = 22050


def tone(seconds: float, sr: int = SR, amplitude: float = 0.3) -> np.ndarray:
    t = np.arange(int(seconds * sr)) / sr
    return (amplitude * np.sin(2 * np.pi * 440 * t)).astype(np.float32)


def write_audio_file(path, samples: np.ndarray, sr: int, codec: str, fmt: str, sample_format: str) -> None:
    """Encode a tiny stereo audio file with PyAV (so the test needs no fixture files)."""
    with av.open(str(path), mode="w", format=fmt) as container:
        stream = container.add_stream(codec, rate=sr, layout="stereo")
        frame = av.AudioFrame.from_ndarray(np.stack([samples, samples]), format="fltp", layout="stereo")
        frame.sample_rate = sr
        frame.pts = 0
        frame = av.AudioResampler(format=sample_format, layout="stereo", rate=sr).resample(frame)
        for f in frame:
            container.mux(stream.encode(f))
        container.mux(stream.encode(None))


@pytest.mark.parametrize("ext,codec,fmt,sample_format", [
    ("wav", "pcm_s16le", "wav", "s16"), ("mp3", "libmp3lame", "mp3", "fltp"), ("ogg", "libopus", "ogg", "flt"),
    ("m4a", "aac", "ipod", "fltp"), ("flac", "flac", "flac", "s16"),
])
def test_decode_audio_formats(tmp_path, ext, codec, fmt, sample_format):
    sr = 48000 if codec == "libopus" else 44100
    path = tmp_path / f"song.{ext}"
    write_audio_file(path, tone(0.5, sr), sr, codec, fmt, sample_format)
    samples = media.decode_audio(path, 16000)
    assert samples.dtype == np.float32 and samples.ndim == 1
    assert abs(len(samples) / 16000 - 0.5) < 0.06  # codec priming/padding only
    rms = float(np.sqrt(np.mean(samples[2000:6000] ** 2)))
    assert rms == pytest.approx(0.3 / np.sqrt(2), rel=0.1)  # stereo averaged to mono, level kept


def test_video_with_audio_is_in_sync(tmp_path):
    fps, frames = 15, 23
    song = tone(5.0)  # longer than the video: must be cut
    path = media.write_video(tmp_path / "out.mp4", (np.full((31, 41, 3), i * 10, np.uint8) for i in range(frames)),
                             fps, audio=song, audio_sr=SR)
    streams = media.probe_streams(path)
    assert streams["video_codec"] == "h264" and streams["audio_codec"] == "aac"
    assert streams["video_frames"] == frames
    assert abs(streams["audio_duration"] - streams["video_duration"]) <= 1 / fps
    info = media.probe_video(path)
    assert (info.width, info.height, info.fps, info.rotation) == (42, 32, 15.0, 0)  # odd sizes padded to even
    decoded = list(media.read_frames(path))
    assert len(decoded) == frames and decoded[0].shape == (32, 42, 3) and decoded[0].dtype == np.uint8
    assert abs(int(decoded[-1][10, 10, 0]) - (frames - 1) * 10) <= 3


def test_short_audio_is_padded_and_mux_audio(tmp_path):
    fps = 30
    video = media.write_video(tmp_path / "v.mp4", (np.zeros((32, 32, 3), np.uint8) for _ in range(60)), fps,
                              audio=tone(0.5), audio_sr=SR)
    streams = media.probe_streams(video)
    assert abs(streams["audio_duration"] - 2.0) <= 1 / fps
    song = tmp_path / "song.wav"
    write_audio_file(song, tone(3.0, 44100), 44100, "pcm_s16le", "wav", "s16")
    out = media.mux_audio(video, song, tmp_path / "muxed.mp4", start_seconds=2.0)
    streams = media.probe_streams(out)
    assert streams["video_frames"] == 60 and abs(streams["audio_duration"] - 2.0) <= 1 / fps
    audio = media.decode_audio(out, 8000)
    assert np.abs(audio[:4000]).max() > 0.2 and np.abs(audio[-2000:]).max() < 0.01  # song ends after 1 s
    with pytest.raises(DancesynthError, match="cannot start at 5 s"):
        media.mux_audio(video, song, tmp_path / "late.mp4", start_seconds=5.0)


def test_failed_write_leaves_no_file(tmp_path):
    path = tmp_path / "x.mp4"
    with pytest.raises(RuntimeError):
        with media.VideoWriter(path, 15, 16, 16) as writer:
            writer.write(np.zeros((16, 16, 3), np.uint8))
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_rotated_phone_video_comes_out_upright(tmp_path):
    path = tmp_path / "portrait.mp4"
    with av.open(str(path), mode="w") as container:
        stream = container.add_stream("libx264", rate=15)
        stream.width, stream.height, stream.pix_fmt = 64, 32, "yuv420p"
        stream.set_display_rotation(-90)  # what a phone held upright writes: show the frame turned clockwise
        for i in range(3):
            stored = np.zeros((32, 64, 3), np.uint8)
            stored[:, :8] = 255  # a white stripe on the stored frame's left edge ...
            frame = av.VideoFrame.from_ndarray(stored, format="rgb24")
            frame.pts = i
            container.mux(stream.encode(frame))
        container.mux(stream.encode(None))
    info = media.probe_video(path)
    assert (info.width, info.height, info.rotation) == (32, 64, -90)
    upright = next(media.read_frames(path))
    assert upright.shape == (64, 32, 3)
    assert upright[:6].mean() > 200 and upright[12:].mean() < 30  # ... is on top once turned clockwise


def test_frames_read_from_a_later_index_are_the_same_frames(tmp_path):
    path = tmp_path / "counting.mp4"
    media.write_video(path, [np.full((16, 16, 3), 20 * i, np.uint8) for i in range(8)], 15.0)
    every = list(media.read_frames(path))
    later = list(media.read_frames(path, start=5))
    assert len(later) == 3 and all(np.array_equal(a, b) for a, b in zip(later, every[5:]))
    assert list(media.read_frames(path, start=8)) == []


def test_frame_stretches_cover_every_frame_once_and_are_long_enough():
    for frames, workers in ((0, 2), (1, 4), (149, 2), (300, 2), (1571, 2), (1571, 3), (10_000, 4)):
        parts = media.frame_stretches(frames, workers)
        assert [t for part in parts for t in part] == list(range(frames))
        assert 1 <= len(parts) <= workers
        assert len(parts) == 1 or min(map(len, parts)) >= media.MIN_STRETCH_FRAMES
    assert len(media.frame_stretches(1571, 2)) == 2


def test_upright_applies_rotation():
    image = np.arange(6, dtype=np.uint8).reshape(2, 3, 1)
    assert media._upright(image, 0) is image
    assert media._upright(image, 90).shape == (3, 2, 1)
    assert media._upright(image, -90)[0, 0, 0] == image[1, 0, 0]  # clockwise quarter turn
    np.testing.assert_array_equal(media._upright(image, 180), image[::-1, ::-1])


def test_errors(tmp_path):
    with pytest.raises(DancesynthError, match="does not exist"):
        media.decode_audio(tmp_path / "missing.mp3", SR)
    corrupt = tmp_path / "corrupt.mp3"
    corrupt.write_bytes(np.random.default_rng(0).bytes(4000))
    with pytest.raises(DancesynthError, match="not a readable"):
        media.decode_audio(corrupt, SR)
    silent = tmp_path / "silent.wav"
    write_audio_file(silent, np.zeros(SR * 3, np.float32), SR, "pcm_s16le", "wav", "s16")
    with pytest.raises(DancesynthError, match="silent"):
        media.load_song(silent, SR)
    short = tmp_path / "short.wav"
    write_audio_file(short, tone(0.5), SR, "pcm_s16le", "wav", "s16")
    with pytest.raises(DancesynthError, match="long"):
        media.load_song(short, SR)
    empty = tmp_path / "empty.wav"
    with wave.open(str(empty), "wb") as f:  # a valid header with zero samples
        f.setnchannels(1)
        f.setsampwidth(2)
        f.setframerate(SR)
    with pytest.raises(DancesynthError):
        media.load_song(empty, SR)
    with pytest.raises(DancesynthError, match="no video stream"):
        media.probe_video(short)
    with pytest.raises(DancesynthError, match="No frames"):
        with media.VideoWriter(tmp_path / "none.mp4", 15, 16, 16):
            pass
    assert not (tmp_path / "none.mp4").exists()
    no_frames = tmp_path / "noframes.mp4"
    with av.open(str(no_frames), mode="w") as container:
        container.add_stream("libx264", rate=15)
    with pytest.raises(DancesynthError):
        list(media.read_frames(no_frames))


def test_a_truncated_video_that_still_decodes_part_of_its_frames_is_a_warning(tmp_path, caplog, truncated_video):
    frames = [np.random.default_rng(i).integers(0, 255, (32, 32, 3), dtype=np.uint8) for i in range(60)]
    cut = truncated_video(frames, tmp_path / "cut.mp4")
    with caplog.at_level("WARNING", logger="dancesynth"):
        assert len(list(media.read_frames(tmp_path / "whole_cut.mp4"))) == 60
        assert not caplog.records
        decoded = len(list(media.read_frames(cut)))
    assert 0 < decoded < 60
    assert [r.getMessage() for r in caplog.records] == [
        f"{cut} decoded only {decoded} of the 60 frames its header declares; the file looks truncated (an "
        "interrupted download or copy), so only those frames are used."]
