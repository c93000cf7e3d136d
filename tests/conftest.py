"""Shared fixtures: a tiny stage-1 dataset whose music features are pre-cached, so no test waits for librosa, drum
loops with known beats, and a tiny target video with the config of an appearance model small enough to train in a
second."""

import os

os.environ.setdefault("NUMBA_CACHE_DIR", os.path.join(os.path.dirname(__file__), "..", ".venv", "numba-cache"))
if "PYTEST_XDIST_WORKER" in os.environ:
    # Parallel test processes writing librosa's compiled kernels into one numba cache at once crash (segfault on a
    # fresh install): each gets its own.
    os.environ["NUMBA_CACHE_DIR"] = os.path.join(os.environ["NUMBA_CACHE_DIR"], os.environ["PYTEST_XDIST_WORKER"])

from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402
import soundfile  # noqa: E402

from dancesynth.core.draw import draw_pose  # noqa: E402
from dancesynth.core.media import write_video  # noqa: E402
from dancesynth.core.skeleton import PoseSequence  # noqa: E402
from stage1_pose.data.dataset import Clip, clip_paths, create_layout, write_beats, write_manifest  # noqa: E402
from stage1_pose.music_features import cache_name, feature_dim  # noqa: E402

FPS, SR, SECONDS = 15.0, 8000, 8.0


def write_tiny_stage1_dataset(root: Path, splits=("train", "train", "train", "val", "test"),
                              styles=("hiphop",), more_features=()) -> Path:
    """Clips of 8 s: a click track at 120 BPM, a body swaying on the beat, random cached features of the
    ``dance_revolution`` kind and the kinds in ``more_features``; clip i of ``splits`` has the style
    ``styles[i % len(styles)]``."""
    rng = np.random.default_rng(0)
    more_rng = np.random.default_rng(1)
    create_layout(root)
    frames = int(SECONDS * FPS)
    t = np.arange(frames) / FPS
    base = rng.uniform(-60, 60, (25, 2)) + (640, 360)
    clips = []
    for i, split in enumerate(splits):
        cid = f"clip{i}"
        paths = clip_paths(cid)
        song = np.zeros(int(SECONDS * SR), np.float32)
        for beat in np.arange(0, SECONDS, 0.5):
            k = int(beat * SR)
            song[k:k + 400] += np.sin(np.arange(400) * 0.3) * np.exp(-np.arange(400) / 80)
        soundfile.write(root / paths["audio"], song, SR)
        sway = 40 * np.sin(2 * np.pi * t + i)[:, None, None] * rng.uniform(0.5, 1.5, (1, 25, 1))
        kp = np.concatenate([base + sway, np.ones((frames, 25, 1))], axis=-1)
        PoseSequence(kp, FPS, 1280, 720).save(root / paths["poses"])
        write_beats(root / paths["beats"], np.arange(0, SECONDS, 0.5), np.arange(0, SECONDS, 2.0), 120.0, "exact")
        feats = root / "features" / "dance_revolution"
        feats.mkdir(parents=True, exist_ok=True)
        np.save(feats / f"{cid}.npy", rng.standard_normal((frames, feature_dim("dance_revolution"))).astype(np.float32))
        for kind in more_features:
            folder = root / "features" / cache_name(kind)
            folder.mkdir(parents=True, exist_ok=True)
            np.save(folder / f"{cid}.npy", more_rng.standard_normal((frames, feature_dim(kind))).astype(np.float32))
        clips.append(Clip(cid, f"song{i}", styles[i % len(styles)], split, **paths))
    write_manifest(root, FPS, SR, list(styles), clips)
    return root


@pytest.fixture(scope="session")
def stage1_dataset_writer():
    """:func:`write_tiny_stage1_dataset`, for tests that need a dataset of their own shape (test modules cannot
    import it: another folder's conftest may hold the name ``conftest`` in ``sys.modules``)."""
    return write_tiny_stage1_dataset


@pytest.fixture(scope="session")
def tiny_stage1_dataset(tmp_path_factory) -> Path:
    """Path of a read-only tiny dataset (5 clips of 8 s: 3 train, 1 val, 1 test)."""
    return write_tiny_stage1_dataset(tmp_path_factory.mktemp("tiny_stage1") / "data")


def make_drum_loop(bpm: float, seconds: float, sr: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Kick on every beat, a loud noise hi-hat half-way between beats; returns (samples, kick times in s)."""
    rng = np.random.default_rng(seed)
    y = np.zeros(int(seconds * sr))
    t = np.arange(int(0.15 * sr)) / sr
    kick = np.sin(2 * np.pi * (60 + 100 * np.exp(-t * 30)) * t) * np.exp(-t * 20)
    hat = rng.standard_normal(int(0.05 * sr)) * np.exp(-np.arange(int(0.05 * sr)) / sr * 80)
    beats = np.arange(0.0, seconds - 0.2, 60.0 / bpm)
    for b in beats:
        for start, sound, gain in ((b, kick, 1.0), (b + 30.0 / bpm, hat, 1.5)):
            i = int(start * sr)
            part = sound[:max(0, len(y) - i)]
            y[i:i + len(part)] += gain * part
    return (0.4 * y / np.abs(y).max()).astype(np.float32), beats


@pytest.fixture
def drum_loop():
    """:func:`make_drum_loop`: ``drum_loop(bpm, seconds, sr)`` -> (samples, kick times in seconds)."""
    return make_drum_loop


def write_truncated_video(frames: list[np.ndarray], path: Path, fps: float = 15.0) -> Path:
    """An mp4 of ``frames`` with its index first (as phones and web videos store it), cut after the packet of the
    middle frame: it still opens and decodes up to the cut, like an interrupted download."""
    import av

    from dancesynth.core.media import write_video

    whole = path.with_name(f"whole_{path.name}")
    write_video(whole, frames, fps)
    with av.open(str(whole)) as src, av.open(str(path), "w", options={"movflags": "faststart"}) as dst:
        stream = dst.add_stream_from_template(src.streams.video[0])
        for packet in src.demux(src.streams.video[0]):
            if packet.dts is not None:
                packet.stream = stream
                dst.mux(packet)
    with av.open(str(path)) as video:
        ends = sorted(p.pos + p.size for p in video.demux(video.streams.video[0]) if p.size)
    path.write_bytes(path.read_bytes()[:ends[len(ends) // 2]])
    return path


@pytest.fixture
def truncated_video():
    """:func:`write_truncated_video`: ``truncated_video(frames, path, fps=15)`` -> path."""
    return write_truncated_video


TINY_APPEARANCE = {"width": 32, "height": 32, "ngf": 8, "n_downsample": 2, "n_blocks": 1, "ndf": 8, "batch_size": 4}


def swaying_poses(frames: int = 24, width: int = 64, height: int = 64) -> PoseSequence:
    """A stick figure swaying left and right, its whole body visible."""
    t = np.arange(frames)[:, None]
    base = np.array([[0, -22], [0, -16], [-6, -16], [-10, -8], [-12, 0], [6, -16], [10, -8], [12, 0], [0, 0],
                     [-4, 0], [-5, 10], [-5, 20], [4, 0], [5, 10], [5, 20], [-1, -23], [1, -23], [-2, -22],
                     [2, -22], [7, 22], [8, 22], [4, 21], [-7, 22], [-8, 22], [-4, 21]], np.float32)
    kp = np.ones((frames, 25, 3), np.float32)
    kp[..., 0] = width / 2 + base[:, 0] + 6 * np.sin(t / 3)
    kp[..., 1] = height / 2 + base[:, 1]
    kp[:, [4, 7], 1] += 6 * np.cos(t / 2)  # waving wrists
    return PoseSequence(kp, 15.0, width, height)


@pytest.fixture(scope="session")
def tiny_config() -> dict:
    """Config overrides for a network small enough to train in a second."""
    return dict(TINY_APPEARANCE)


@pytest.fixture(scope="session")
def make_poses():
    """:func:`swaying_poses`, for tests that need pose sequences of their own."""
    return swaying_poses


@pytest.fixture(scope="session")
def tiny_target(tmp_path_factory) -> tuple[Path, Path]:
    """(video.mp4, poses.npz): each frame shows the skeleton thickly drawn on a grey background."""
    folder = tmp_path_factory.mktemp("target")
    seq = swaying_poses()
    frames = [draw_pose(np.full((seq.height, seq.width, 3), 90, np.uint8), kp, thickness=3) for kp in seq.keypoints]
    video, poses = folder / "target.mp4", folder / "poses.npz"
    write_video(video, frames, seq.fps)
    seq.save(poses)
    return video, poses
