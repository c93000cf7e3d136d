"""Media in and out, in-process through PyAV (FFmpeg), streaming so memory stays flat for any length.

Audio comes out as mono float32 samples at a requested rate; video frames come out as upright RGB uint8
``[H, W, 3]`` arrays; videos are written as H.264 yuv420p mp4 with optional AAC audio cut to the video's
duration. Every output is written under a temporary name and renamed when complete.
"""

from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import av
import numpy as np

from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import atomic_path, require_file

logger = logging.getLogger(__name__)

# Rates AAC audio is written at; any other rate is resampled to AAC_RATE. Low rates are avoided because a
# 1024-sample AAC frame would then last longer than a video frame, so the track could not end with the video.
AAC_RATES = (44100, 48000)
AAC_RATE = 44100
# Every command decodes songs at this rate (stage 1 resamples to what its features need), so a song gets the same
# dance whichever command makes it, and datasets store their songs at it.
SONG_SAMPLE_RATE = 22050
# RMS below this (full scale = 1) counts as silence.
SILENCE_RMS = 1e-4
# Float audio may overshoot full scale a little; samples beyond this are broken data, not loud music.
MAX_SAMPLE = 100.0
# Frames a worker reading its own stretch of a video (frame_stretches) is given at least: each decodes the video's
# earlier frames again to reach its stretch, and its per-video work (a pose graph's first search) starts anew.
MIN_STRETCH_FRAMES = 150


def _open_input(path: str | os.PathLike) -> av.container.InputContainer:
    path = require_file(path)
    try:
        return av.open(str(path))
    except (av.FFmpegError, UnicodeDecodeError) as e:
        raise DancesynthError(f"{path} is not a readable audio or video file ({e.strerror or e}); "
                              "convert it to a common format such as mp3, wav or mp4.") from e


def decode_audio(path: str | os.PathLike, sr: int) -> np.ndarray:
    """Decode the first audio stream of any FFmpeg-readable file to mono float32 ``[N]`` samples at ``sr`` Hz.

    Works for audio files (wav, mp3, ogg, m4a, flac, ...) and the audio track of a video. Channels are averaged
    (FFmpeg's own downmix would add them at -3 dB, making a centred stereo mix 41 % louder than its channels).
    """
    with _open_input(path) as container:
        if not container.streams.audio:
            raise DancesynthError(f"{path} has no audio stream; choose a file that contains sound.")
        # Planar float at the target rate, channel layout unchanged: one row per channel.
        resampler = av.AudioResampler(format="fltp", rate=int(sr))
        chunks: list[np.ndarray] = []
        try:
            for frame in container.decode(container.streams.audio[0]):
                frame.pts = None  # the resampler needs no timestamps and rejects inconsistent ones
                chunks.extend(out.to_ndarray().mean(axis=0) for out in resampler.resample(frame))
            chunks.extend(out.to_ndarray().mean(axis=0) for out in resampler.resample(None))
        except av.FFmpegError as e:
            raise DancesynthError(f"The audio in {path} is corrupt ({e}); re-export or re-download the file.") from e
    if not chunks or sum(len(c) for c in chunks) == 0:
        raise DancesynthError(f"{path} contains no audio samples; choose a file that contains sound.")
    samples = np.concatenate(chunks).astype(np.float32, copy=False)
    if not np.isfinite(samples).all() or np.abs(samples).max() > MAX_SAMPLE:
        raise DancesynthError(f"The audio in {path} has samples that are not finite or far beyond full scale; "
                              "re-export it as ordinary 16-bit or normalised float audio.")
    return samples


def load_song(path: str | os.PathLike, sr: int, min_seconds: float = 2.0) -> np.ndarray:
    """:func:`decode_audio`, then reject songs that are silent or shorter than ``min_seconds`` seconds."""
    samples = decode_audio(path, sr)
    seconds = len(samples) / sr
    if seconds < min_seconds:
        raise DancesynthError(f"{path} is only {seconds:.2f} s long; choose a song of at least {min_seconds:g} s.")
    if float(np.sqrt(np.mean(np.square(samples, dtype=np.float64)))) < SILENCE_RMS:
        raise DancesynthError(f"{path} is silent; choose a song with audible music.")
    return samples


@dataclass(frozen=True)
class VideoInfo:
    """What :func:`probe_video` learns about a video.

    Attributes:
        fps: frames per second.
        width, height: size of the upright frames :func:`read_frames` yields, in pixels.
        num_frames: frame count as the container declares it, or estimated from duration x fps (may be off by a few).
        duration: seconds.
        rotation: degrees counter-clockwise the container asks players to rotate the stored frames by.
    """

    fps: float
    width: int
    height: int
    num_frames: int
    duration: float
    rotation: int


def _upright(image: np.ndarray, rotation: int) -> np.ndarray:
    """Rotate a stored frame by ``rotation`` degrees counter-clockwise (a multiple of 90) to display it upright."""
    quarter_turns = int(round(rotation / 90.0)) % 4
    return np.ascontiguousarray(np.rot90(image, k=quarter_turns)) if quarter_turns else image


def _video_stream(container: av.container.InputContainer, path: str | os.PathLike) -> av.video.stream.VideoStream:
    if not container.streams.video:
        raise DancesynthError(f"{path} has no video stream; choose a video file.")
    return container.streams.video[0]


def _decoded_frames(path: str | os.PathLike, limit: int | None = None) -> Iterator[av.VideoFrame]:
    """Decoded frames of the first video stream (at most ``limit``); at least one, else DancesynthError.

    Reading to the end, a video that yields clearly fewer frames than its header declares (a truncated
    download or copy still decodes up to the cut) is logged as a warning.
    """
    with _open_input(path) as container:
        stream = _video_stream(container, path)
        stream.thread_type = "AUTO"
        declared = int(stream.frames)
        count = 0
        try:
            for frame in container.decode(stream):
                count += 1
                yield frame
                if count == limit:
                    return
        except av.FFmpegError as e:
            raise DancesynthError(f"The video {path} is corrupt after {count} frames ({e}); "
                                  "re-encode or re-download it.") from e
        if count == 0:
            raise DancesynthError(f"{path} contains no video frames; choose another video.")
        # Decoders may drop a frame or two of an edited stream; more than that missing means data is gone.
        if count < declared - max(2, declared // 50):
            logger.warning(f"{path} decoded only {count} of the {declared} frames its header declares; the file "
                           "looks truncated (an interrupted download or copy), so only those frames are used.")


def probe_video(path: str | os.PathLike) -> VideoInfo:
    """Frame rate, upright size, frame count, duration and rotation of the first video stream.

    Decodes only the first frame (to read the rotation the container declares). For a variable-frame-rate
    video ``fps`` is the average rate.
    """
    with _open_input(path) as container:
        stream = _video_stream(container, path)
        rate = stream.average_rate or stream.guessed_rate or stream.base_rate
        if not rate:
            raise DancesynthError(f"{path} declares no frame rate; re-encode it with a constant frame rate.")
        fps = float(rate)
        if stream.duration is not None and stream.time_base is not None:
            duration = float(stream.duration * stream.time_base)
        elif container.duration is not None:
            duration = container.duration / av.time_base
        else:
            duration = 0.0
        num_frames = int(stream.frames) or int(round(duration * fps))
    (first,) = _decoded_frames(path, limit=1)
    rotation = int(first.rotation)
    width, height = first.width, first.height
    if int(round(rotation / 90.0)) % 2:
        width, height = height, width
    return VideoInfo(fps=fps, width=width, height=height, num_frames=num_frames, duration=duration, rotation=rotation)


def frame_stretches(frames: int, workers: int) -> list[range]:
    """Consecutive ranges of frame indices covering ``range(frames)``, for ``workers`` that each read their own
    stretch of a video (:func:`read_frames` with ``start``) side by side: ``workers`` of them, fewer where a stretch
    would hold under :data:`MIN_STRETCH_FRAMES` frames (at least one)."""
    count = max(1, min(workers, frames // MIN_STRETCH_FRAMES))
    bounds = np.linspace(0, frames, count + 1).round().astype(int)
    return [range(a, b) for a, b in zip(bounds[:-1], bounds[1:])]


def read_frames(path: str | os.PathLike, start: int = 0) -> Iterator[np.ndarray]:
    """Stream the frames of a video from frame index ``start`` on as upright RGB uint8 ``[H, W, 3]`` arrays, one
    at a time (the frames before ``start`` are decoded, since compressed frames depend on earlier ones, but not
    converted).

    The rotation the container declares (display-matrix side data, as phones write) is applied.
    """
    for index, frame in enumerate(_decoded_frames(path)):
        if index >= start:
            yield _upright(frame.to_ndarray(format="rgb24"), frame.rotation)


def _as_channels_first(audio: np.ndarray) -> np.ndarray:
    """Mono ``[N]`` or ``[N, C]`` (C <= 2) float samples -> C-contiguous ``[C, N]`` float32."""
    audio = np.asarray(audio, dtype=np.float32)
    if audio.ndim == 1:
        audio = audio[:, None]
    if audio.ndim != 2 or audio.shape[1] not in (1, 2):
        raise ValueError(f"audio must be [N] (mono) or [N, 2] (stereo) samples, got shape {audio.shape}")
    return np.ascontiguousarray(audio.T)


def _resample(samples: np.ndarray, sr: int, target_sr: int) -> np.ndarray:
    """Resample ``[C, N]`` float32 samples (C = 1 or 2) from ``sr`` to ``target_sr`` Hz with FFmpeg's resampler."""
    layout = "mono" if samples.shape[0] == 1 else "stereo"
    frame = av.AudioFrame.from_ndarray(np.ascontiguousarray(samples), format="fltp", layout=layout)
    frame.sample_rate = int(sr)
    resampler = av.AudioResampler(format="fltp", layout=layout, rate=int(target_sr))
    parts = [out.to_ndarray() for out in (*resampler.resample(frame), *resampler.resample(None))]
    return np.concatenate(parts, axis=1) if parts else np.zeros((samples.shape[0], 0), np.float32)


class _AudioTrack:
    """Feeds an AAC stream progressively so the muxer can interleave it with the video as it goes.

    Samples past the end of ``audio`` are silence, so the track can be made as long as the video. Only whole
    AAC frames are encoded, because the encoder pads a partial last frame with silence that players would play;
    the final length is rounded to the nearest whole frame (at most 512 samples = 11.6 ms off at 44.1 kHz).
    """

    FRAME_SAMPLES = 1024  # samples per AAC frame

    def __init__(self, container: av.container.OutputContainer, audio: np.ndarray, sr: int) -> None:
        samples = _as_channels_first(audio)
        self.rate = int(sr) if int(sr) in AAC_RATES else AAC_RATE
        self.samples = samples if self.rate == sr else _resample(samples, sr, self.rate)
        self.layout = "mono" if samples.shape[0] == 1 else "stereo"
        self.stream = container.add_stream("aac", rate=self.rate, layout=self.layout)
        self.container = container
        self.sent = 0

    def feed_until(self, seconds: float, last: bool = False) -> None:
        """Encode whole AAC frames up to time ``seconds``; ``last`` rounds to the nearest frame instead of down."""
        position = seconds * self.rate / self.FRAME_SAMPLES
        stop = self.FRAME_SAMPLES * (int(round(position)) if last else int(np.floor(position)))
        if stop <= self.sent:
            return
        chunk = self.samples[:, self.sent:stop]
        if chunk.shape[1] < stop - self.sent:
            chunk = np.pad(chunk, ((0, 0), (0, stop - self.sent - chunk.shape[1])))
        frame = av.AudioFrame.from_ndarray(np.ascontiguousarray(chunk), format="fltp", layout=self.layout)
        frame.sample_rate = self.rate
        # Timestamps in samples let the encoder mark its priming delay, which the mp4 muxer writes as an edit list.
        frame.pts, frame.time_base = self.sent, Fraction(1, self.rate)
        self.sent = stop
        self.container.mux(self.stream.encode(frame))

    def finish(self, seconds: float) -> None:
        """Encode up to ``seconds`` (the video's duration) and flush the encoder."""
        self.feed_until(seconds, last=True)
        self.container.mux(self.stream.encode(None))


def _frame_rate(fps: float) -> Fraction:
    # NTSC-style rates (29.97 = 30000/1001) are represented exactly; others to 1/1000 of a frame.
    return Fraction(fps).limit_denominator(1001)


class VideoWriter:
    """Write RGB frames to an H.264 (yuv420p) mp4, optionally with AAC audio, atomically and streaming.

    Use as a context manager and call :meth:`write` once per frame. Odd widths/heights are padded by one
    pixel (edge colour) because yuv420p needs even sizes. With ``audio`` (mono ``[N]`` or ``[N, 2]`` float
    samples in [-1, 1] at ``audio_sr`` Hz) the audio track is cut or padded with silence to the video's
    duration (number of frames / fps), so players keep sound and picture in sync. If the with-block raises,
    no file appears under ``path``.
    """

    def __init__(self, path: str | os.PathLike, fps: float, width: int, height: int,
                 audio: np.ndarray | None = None, audio_sr: int | None = None, crf: int = 18,
                 preset: str = "veryfast") -> None:
        if (audio is None) != (audio_sr is None):
            raise ValueError("pass audio and audio_sr together")
        if not fps > 0 or width < 1 or height < 1:
            raise ValueError(f"invalid video geometry fps={fps} size={width}x{height}")
        self.path = Path(path)
        self.fps, self.width, self.height = float(fps), int(width), int(height)
        self.audio, self.audio_sr = audio, audio_sr
        self.crf, self.preset = crf, preset
        self.frames_written = 0
        self._stack: contextlib.ExitStack | None = None

    def __enter__(self) -> "VideoWriter":
        with contextlib.ExitStack() as stack:
            tmp = stack.enter_context(atomic_path(self.path))
            # The file is Python's, so it is closed even when FFmpeg fails to finish it (e.g. on a full disk).
            file = stack.enter_context(open(tmp, "wb"))
            self._container = stack.enter_context(av.open(file, mode="w", format="mp4"))
            rate = _frame_rate(self.fps)
            self._video = self._container.add_stream("libx264", rate=rate)
            self._video.width, self._video.height = self.width + self.width % 2, self.height + self.height % 2
            self._video.pix_fmt = "yuv420p"
            self._video.codec_context.time_base = 1 / rate
            self._video.options = {"crf": str(self.crf), "preset": self.preset}
            self._audio = None if self.audio is None else _AudioTrack(self._container, self.audio, self.audio_sr)
            self._stack = stack.pop_all()
        return self

    def write(self, frame: np.ndarray) -> None:
        """Append one RGB uint8 ``[height, width, 3]`` frame."""
        frame = np.asarray(frame)
        if frame.shape != (self.height, self.width, 3) or frame.dtype != np.uint8:
            raise ValueError(f"frame must be uint8 [{self.height}, {self.width}, 3], got {frame.dtype} {frame.shape}")
        if self.width % 2 or self.height % 2:
            frame = np.pad(frame, ((0, self.height % 2), (0, self.width % 2), (0, 0)), mode="edge")
        video_frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(frame), format="rgb24")
        video_frame.pts = self.frames_written
        self._container.mux(self._video.encode(video_frame))
        self.frames_written += 1
        if self._audio is not None:
            self._audio.feed_until(self.frames_written / self.fps)

    def __exit__(self, exc_type, exc, tb) -> bool:
        stack, self._stack = self._stack, None
        if exc_type is not None:
            return stack.__exit__(exc_type, exc, tb)
        with stack:  # an error while finishing still removes the temporary file
            if self.frames_written == 0:
                raise DancesynthError(f"No frames were produced for {self.path}; nothing to write.")
            self._container.mux(self._video.encode(None))
            if self._audio is not None:
                self._audio.finish(self.frames_written / self.fps)
        return False


def write_video(path: str | os.PathLike, frames: Iterable[np.ndarray], fps: float,
                audio: np.ndarray | None = None, audio_sr: int | None = None) -> Path:
    """Write RGB uint8 frames (all the same size) to an mp4 via :class:`VideoWriter`; returns ``path``.

    The frame size is taken from the first frame; ``frames`` may be a generator (streamed).
    """
    iterator = iter(frames)
    first = next(iterator, None)
    if first is None:
        raise DancesynthError(f"No frames were produced for {path}; nothing to write.")
    height, width = np.asarray(first).shape[:2]
    with VideoWriter(path, fps, width, height, audio=audio, audio_sr=audio_sr) as writer:
        writer.write(first)
        for frame in iterator:
            writer.write(frame)
    return Path(path)


def mux_audio(video_path: str | os.PathLike, audio_path: str | os.PathLike, out_path: str | os.PathLike,
              start_seconds: float = 0.0) -> Path:
    """Copy the video stream of ``video_path`` (no re-encoding) and add the song in ``audio_path`` from
    ``start_seconds`` seconds on, as AAC cut or padded to the video's duration. Written atomically."""
    info = probe_video(video_path)
    song = decode_audio(audio_path, AAC_RATE)
    start = int(round(max(start_seconds, 0.0) * AAC_RATE))
    if start >= len(song):
        raise DancesynthError(f"{audio_path} is only {len(song) / AAC_RATE:.1f} s long, so it cannot start at "
                              f"{start_seconds:g} s; choose an earlier start.")
    try:
        with _open_input(video_path) as source, atomic_path(out_path) as tmp, \
                av.open(str(tmp), mode="w", format="mp4") as target:
            in_video = source.streams.video[0]
            out_video = target.add_stream_from_template(in_video)
            track = _AudioTrack(target, song[start:], AAC_RATE)
            last_seconds = 0.0
            for packet in source.demux(in_video):
                if packet.dts is None:  # the demuxer's end-of-stream marker
                    continue
                if packet.pts is not None:
                    last_seconds = max(last_seconds, float((packet.pts + (packet.duration or 0)) * packet.time_base))
                    track.feed_until(min(last_seconds, info.duration or last_seconds))
                packet.stream = out_video
                target.mux(packet)
            track.finish(info.duration or last_seconds)
    except av.FFmpegError as e:
        raise DancesynthError(f"Could not copy the video of {video_path} into an mp4 ({e}); "
                              "re-encode it as an H.264 mp4 with any video converter first.") from e
    return Path(out_path)


def probe_streams(path: str | os.PathLike) -> dict:
    """Durations and codecs of the first video and audio streams, measured by decoding.

    Returns ``{"video_codec", "video_frames", "fps", "video_duration", "audio_codec", "audio_sample_rate",
    "audio_duration"}``; durations in seconds (video: frames / fps; audio: decoded samples / rate, i.e. what
    a player plays after the encoder delay is removed). Audio keys are None when there is no audio stream.
    """
    result: dict = {"video_codec": None, "video_frames": 0, "fps": None, "video_duration": None,
                    "audio_codec": None, "audio_sample_rate": None, "audio_duration": None}
    with _open_input(path) as container:
        if container.streams.video:
            stream = container.streams.video[0]
            result["video_codec"] = stream.codec_context.name
            result["fps"] = float(stream.average_rate or stream.guessed_rate)
            result["video_frames"] = sum(1 for _ in container.decode(stream))
            result["video_duration"] = result["video_frames"] / result["fps"]
    with _open_input(path) as container:
        if container.streams.audio:
            stream = container.streams.audio[0]
            result["audio_codec"] = stream.codec_context.name
            result["audio_sample_rate"] = stream.codec_context.sample_rate
            samples = sum(frame.samples for frame in container.decode(stream))
            result["audio_duration"] = samples / result["audio_sample_rate"]
    return result
