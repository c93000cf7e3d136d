"""The stage-1 evaluation driver: every model and baseline on the held-out songs, every metric, one report.

Rows ("contenders"):
  * ``real dances`` - the test split's own dances (an upper reference; multimodality undefined);
  * ``random real dance`` - a random training dance paired with the test song (real motion, mismatched music:
    shows what the beat and cross-modal metrics give when the dance ignores the music);
  * ``mean pose (frozen)`` - the training set's mean pose held still (shows the metrics catching a frozen dance);
  * one row per model run folder (:func:`stage1_pose.generate.generate_dance`).
Each row is evaluated ``trials`` times with seeds 0..trials-1; table values are mean +- std over trials.
FID compares windows (the style classifier's ``window_frames``, 4 s) of the row's dances with the windows of
the training split's real dances. Physical plausibility: bone lengths against the median length of each bone over
the same dance (whether the dancer keeps one body; which body it is, stage 2 retargets onto the target person), joint
speed as a multiple of the real dances' speed on the same songs.
Report files: ``report.md``, ``report.json``, ``fid_over_time.png``, ``beat_alignment.png``, ``videos/<row>.mp4``
and, on request, ``grid.mp4`` (every row dancing to the first test song side by side, flashing on its beats).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dancesynth.core.checkpoint import load_meta, update_meta
from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import atomic_path
from dancesynth.core.motion import (
    bone_length_errors,
    kinematic_beats,
    legs_arms_speed_ratio,
    mean_jerk,
    mean_speed,
    reference_bone_lengths,
    upside_down_share,
    velocity_minimum_beats,
)
from dancesynth.core.progress import track
from dancesynth.core.skeleton import PoseSequence, resample
from stage1_pose import metrics
from stage1_pose.data.dataset import DanceDataset
from stage1_pose.music_features import num_pose_frames
from stage1_pose.style_classifier import LoadedStyleClassifier

MUSIC_FEATURE_KIND = "dancing2music"
REAL, RANDOM_REAL, FROZEN = "real dances", "random real dance", "mean pose (frozen)"


@dataclass
class HeldOutSong:
    """A held-out song cut to the evaluated length, with its real dance and beats.

    ``samples`` mono ``[N]`` at ``sr`` Hz; ``beats`` and ``downbeats`` in seconds (only those inside the cut);
    ``real`` the dance performed to it (``num_pose_frames`` frames); ``music`` a ``[E]`` summary music embedding.
    """

    id: str
    style: int
    samples: np.ndarray
    sr: int
    beats: np.ndarray
    real: PoseSequence
    music: np.ndarray
    downbeats: np.ndarray = field(default_factory=lambda: np.zeros(0))


@dataclass
class Reference:
    """The training split as metrics need it: dances, their classifier embeddings and music embeddings."""

    dances: list[PoseSequence]
    dance_features: np.ndarray
    window_features: np.ndarray
    music: np.ndarray


@dataclass
class Contender:
    """A table row: ``make(song_index, seed) -> PoseSequence`` of the song's length."""

    name: str
    make: Callable[[int, int], PoseSequence]
    stochastic: bool = True


@dataclass
class DanceScores:
    """Per-dance quantities the row metrics are aggregated from: classifier output, kinematic beats (frames),
    ``[T, B]`` relative bone-length errors, mean joint speed (px/s), legs/arms speed ratio, jerk (px/s^3) and the
    share of frames upside down."""

    predicted: int
    feature: np.ndarray
    windows: np.ndarray
    d2m_beats: np.ndarray
    vmin_beats: np.ndarray
    bone_errors: np.ndarray
    speed: float
    legs_arms: float
    jerk: float
    upside_down: float


@dataclass
class RowResult:
    """Metric name -> values over trials, multimodality over seeds, and the long-term FID curve."""

    name: str
    per_trial: dict[str, list[float]] = field(default_factory=dict)
    multimodality: float = float("nan")
    fid_curve: list[float] = field(default_factory=list)

    def summary(self) -> dict[str, dict[str, float]]:
        """Metric -> {"mean", "std"} over trials (NaN trials ignored)."""
        out = {}
        for k, v in self.per_trial.items():
            a = np.asarray(v, np.float64)
            ok = a[np.isfinite(a)]
            out[k] = {"mean": float(ok.mean()) if ok.size else float("nan"),
                      "std": float(ok.std()) if ok.size else float("nan"), "trials": int(ok.size)}
        return out


# Table columns: key, header, scale (x100 for percentages), decimals.
COLUMNS: tuple[tuple[str, str, float, int], ...] = (
    ("fid", "FID ↓", 1.0, 2),
    ("acc", "ACC %", 100.0, 1),
    ("coverage_d2m", "Beat cov. % (D2M)", 100.0, 1),
    ("hit_rate_d2m", "Beat hit % (D2M)", 100.0, 1),
    ("coverage_vmin", "Beat cov. % (vel-min)", 100.0, 1),
    ("hit_rate_vmin", "Beat hit % (vel-min)", 100.0, 1),
    ("beat_align", "BAS", 1.0, 3),
    ("diversity", "Diversity", 1.0, 2),
    ("cross_modal", "Cross-modal dist. ↓", 1.0, 2),
    ("bone_error", "Bone len. err. % ↓", 100.0, 1),
    ("bone_error_p99", "Bone len. err. p99 % ↓", 100.0, 1),
    ("upside_down", "Upside down % ↓", 100.0, 1),
    ("speed_vs_real", "Speed / real", 1.0, 2),
    ("legs_arms", "Legs/arms speed", 1.0, 2),
    ("jerk", "Jerk px/s³", 1.0, 0),
)


def music_embedding(features: np.ndarray) -> np.ndarray:
    """``[T, D]`` per-frame music features -> ``[2 D]`` (mean and std over time): a song summary."""
    f = np.asarray(features, np.float64)
    return np.concatenate([f.mean(axis=0), f.std(axis=0)])


def fit_length(seq: PoseSequence, frames: int) -> PoseSequence:
    """Cut ``seq`` to ``frames`` frames, looping it when it is shorter."""
    return seq.replace(seq.keypoints[np.arange(frames) % len(seq)].copy())


def load_songs(ds: DanceDataset, seconds: float, split: str = "test") -> list[HeldOutSong]:
    """The songs of ``split`` cut to at most ``seconds`` seconds, with their dances, beats and music embeddings."""
    songs = []
    for clip in ds.clips(split):
        samples = ds.load_audio(clip)[: int(round(seconds * ds.sample_rate))]
        real = ds.load_poses(clip)
        frames = min(num_pose_frames(len(samples), ds.sample_rate, real.fps), len(real))
        beats, downbeats = (ds.load_beats(clip)[key] for key in ("beats", "downbeats"))
        music = np.asarray(ds.load_features(clip, MUSIC_FEATURE_KIND)[:frames])
        songs.append(HeldOutSong(clip.id, ds.style_index(clip), samples, ds.sample_rate,
                                 beats[beats < frames / real.fps], real.slice_frames(0, frames),
                                 music_embedding(music), downbeats[downbeats < frames / real.fps]))
    if not songs:
        raise DancesynthError(f"The dataset {ds.root} has no {split} clips to evaluate on; "
                              "re-create it with more `--clips`.")
    return songs


def load_reference(ds: DanceDataset, clf: LoadedStyleClassifier) -> Reference:
    """Embed every training dance (whole dance and consecutive windows) and summarise its music."""
    dances, feats, windows, music = [], [], [], []
    for clip in track(ds.clips("train"), desc="reference dances", unit="clip"):
        dance = ds.load_poses(clip)
        _, f, w = clf.embed(dance)
        dances.append(dance)
        feats.append(f)
        windows.append(w)
        music.append(music_embedding(ds.load_features(clip, MUSIC_FEATURE_KIND)))
    if len(dances) < 2:
        raise DancesynthError(f"The dataset {ds.root} needs at least two training clips for the reference "
                              "statistics; re-create it with more `--clips`.")
    return Reference(dances, np.stack(feats), np.concatenate(windows), np.stack(music))


def baseline_contenders(songs: list[HeldOutSong], ref: Reference) -> list[Contender]:
    """The real, random-real (mismatched music) and frozen mean-pose rows."""
    frames = [len(s.real) for s in songs]
    mean_pose = np.mean([d.keypoints.mean(axis=0) for d in ref.dances], axis=0)
    template = ref.dances[0]

    def random_real(i: int, seed: int) -> PoseSequence:
        pick = np.random.default_rng([seed, i]).integers(len(ref.dances))
        return fit_length(ref.dances[pick], frames[i])

    def frozen(i: int, seed: int) -> PoseSequence:
        return template.replace(np.repeat(mean_pose[None], frames[i], axis=0))

    return [Contender(REAL, lambda i, seed: songs[i].real, stochastic=False),
            Contender(RANDOM_REAL, random_real), Contender(FROZEN, frozen, stochastic=False)]


def model_contender(run_dir: str | os.PathLike, ds: DanceDataset, songs: list[HeldOutSong], device: str,
                    name: str, beat_snap: bool = False) -> Contender:
    """The row ``name`` (see :func:`row_names`), generating with the stage-1 model saved in ``run_dir``.

    When the model runs at the dataset's frame rate, its input features come from the dataset's feature cache
    (computed once per song, cut to the song's frames) instead of being extracted again for every seed, with
    the dataset's beats of the song; otherwise features and beats come from the song's samples, as a user's song's
    would (the beats tracked once per song, for every seed). ``beat_snap`` scores the dances retimed onto the beats
    as ``dancesynth dance`` makes them, instead of the method's own.
    """
    from stage1_pose.beat_snap import DEFAULT_SNAP
    from stage1_pose.beats import SongBeats, song_beats
    from stage1_pose.generate import generate_dance, generate_from_features, load_pose_model

    model = load_pose_model(run_dir, device)
    clips = {c.id: c for c in ds.clips()}
    cached = model.fps == ds.fps
    snap = DEFAULT_SNAP if beat_snap else None
    tracked: dict[int, SongBeats] = {}  # song index -> its beats by the default tracker (the uncached path)

    def make(i: int, seed: int) -> PoseSequence:
        song = songs[i]
        if cached:
            features = np.asarray(ds.load_features(clips[song.id], model.feature_kind)[: len(song.real)])
            dance = generate_from_features(model, features, song.beats, seed=seed, snap=snap,
                                           downbeats=song.downbeats)
        else:
            if i not in tracked:  # generate_dance tracks float32 samples
                tracked[i] = song_beats(np.asarray(song.samples, np.float32), song.sr)
            # Beat and window metrics count frames, so every row is judged at the dataset's frame rate.
            dance = resample(generate_dance(model, song.samples, song.sr, seed=seed, snap=snap, beats=tracked[i]),
                             song.real.fps)
        return fit_length(dance, len(song.real))

    return Contender(name, make)


def row_names(model_dirs: list[str], taken: set[str]) -> list[str]:
    """Row names of the model folders, unique among themselves and ``taken`` (as file names too, since each row
    writes ``videos/<row>.mp4``): the folder's name; where rows share one, ``parent/name``; a number after that
    when even that repeats (one folder given twice)."""
    plain = [Path(d).name for d in model_dirs]
    shared = Counter(_file_name(n) for n in [*taken, *plain])
    used = {_file_name(n) for n in taken}
    names = []
    for run_dir, name in zip(model_dirs, plain):
        if shared[_file_name(name)] > 1:
            name = f"{Path(run_dir).resolve().parent.name}/{name}"
        unique, k = name, 2
        while _file_name(unique) in used:
            unique, k = f"{name} ({k})", k + 1
        used.add(_file_name(unique))
        names.append(unique)
    return names


def score_dance(dance: PoseSequence, clf: LoadedStyleClassifier) -> DanceScores:
    """Classifier embedding, both kinematic beat sets (frame indices) and the motion measures of one dance; bone
    lengths are compared with the dance's own median lengths (a body that keeps its proportions)."""
    pred, feat, windows = clf.embed(dance)
    xy = dance.xy
    return DanceScores(pred, feat, windows, np.asarray(kinematic_beats(xy, dance.fps)),
                       np.asarray(velocity_minimum_beats(xy, dance.fps)),
                       bone_length_errors(xy, reference_bone_lengths(xy)), mean_speed(xy, dance.fps),
                       legs_arms_speed_ratio(xy, dance.fps), mean_jerk(xy, dance.fps), upside_down_share(xy))


def _nanmean(values: list[float] | np.ndarray) -> float:
    """Mean of the finite values; NaN (without a warning) when there are none."""
    a = np.asarray(values, np.float64)
    return float(a[np.isfinite(a)].mean()) if np.isfinite(a).any() else float("nan")


def trial_metrics(scores: list[DanceScores], songs: list[HeldOutSong], ref: Reference, fps: float,
                  tolerance_frames: float) -> dict[str, float]:
    """Every per-trial metric of one row (one dance per song)."""
    music_frames = [s.beats * fps for s in songs]
    windows = np.concatenate([s.windows for s in scores])
    out = {
        "fid": metrics.frechet_distance(windows, ref.window_features) if len(windows) >= 2 else float("nan"),
        "acc": metrics.style_accuracy(np.array([s.predicted for s in scores]), np.array([s.style for s in songs])),
        "beat_align": float(np.nanmean([metrics.beat_align_score(s.beats, d.vmin_beats / fps)
                                        for d, s in zip(scores, songs)])),
        "diversity": (metrics.diversity(np.stack([s.feature for s in scores])) if len(scores) >= 2
                      else float("nan")),
        "cross_modal": metrics.cross_modal_distance(np.stack([s.feature for s in scores]),
                                                    np.stack([s.music for s in songs]), ref.music,
                                                    ref.dance_features),
    }
    bones = np.concatenate([d.bone_errors for d in scores]).ravel()
    bones = bones[np.isfinite(bones)]
    real_speed = np.mean([mean_speed(s.real.xy, fps) for s in songs])
    out["bone_error"] = float(bones.mean()) if bones.size else float("nan")
    out["bone_error_p99"] = float(np.percentile(bones, 99)) if bones.size else float("nan")
    out["speed_vs_real"] = float(np.mean([d.speed for d in scores]) / real_speed) if real_speed > 0 else float("nan")
    out["legs_arms"] = _nanmean([d.legs_arms for d in scores])
    out["jerk"] = _nanmean([d.jerk for d in scores])
    out["upside_down"] = _nanmean([d.upside_down for d in scores])
    for tag in ("d2m", "vmin"):
        kin = [getattr(d, f"{tag}_beats") for d in scores]
        out[f"coverage_{tag}"] = float(np.nanmean([metrics.beat_coverage(k, m) for k, m in zip(kin, music_frames)]))
        hits = [metrics.beat_hit_rate(k, m, tolerance_frames) for k, m in zip(kin, music_frames)]
        out[f"hit_rate_{tag}"] = _nanmean(hits)
    return out


def evaluate_contender(contender: Contender, songs: list[HeldOutSong], ref: Reference, clf: LoadedStyleClassifier,
                       trials: int, tolerance_frames: float,
                       on_dance: Callable[[str, int, int, PoseSequence], None] | None = None) -> RowResult:
    """All metrics of one row over ``trials`` seeds. ``on_dance(row, song_index, seed, dance)`` sees every dance."""
    result = RowResult(contender.name)
    n_trials = trials if contender.stochastic else 1
    all_scores: list[list[DanceScores]] = []
    bar = track(total=n_trials * len(songs), desc=contender.name, unit="dance")
    for seed in range(n_trials):
        scores = []
        for i in range(len(songs)):
            dance = contender.make(i, seed)
            if on_dance is not None:
                on_dance(contender.name, i, seed, dance)
            scores.append(score_dance(dance, clf))
            bar.update()
        all_scores.append(scores)
        for k, v in trial_metrics(scores, songs, ref, songs[0].real.fps, tolerance_frames).items():
            result.per_trial.setdefault(k, []).append(v)
    bar.close()
    if contender.stochastic and n_trials >= 2:
        result.multimodality = metrics.multimodality(
            np.stack([[all_scores[t][i].feature for t in range(n_trials)] for i in range(len(songs))]))
    elif contender.name != REAL:
        result.multimodality = 0.0
    # One curve per trial (one dance per song), then the mean: pooling trials would give stochastic rows more
    # distinct samples per window than deterministic ones, and FID falls with sample count.
    n_windows = min(s.windows.shape[0] for trial in all_scores for s in trial)
    curves = [metrics.fid_over_time(np.stack([s.windows[:n_windows] for s in trial]), ref.window_features)
              for trial in all_scores]
    result.fid_curve = np.mean(curves, axis=0).tolist()
    return result


def _cell(stats: dict[str, float], scale: float, decimals: int) -> str:
    if not np.isfinite(stats["mean"]):
        return "–"
    mean = f"{stats['mean'] * scale:.{decimals}f}"
    return mean if stats["trials"] < 2 else f"{mean} ± {stats['std'] * scale:.{decimals}f}"


def markdown_table(rows: list[RowResult]) -> str:
    """The report table: one row per contender, mean ± std over trials per column."""
    header = ["Method"] + [c[1] for c in COLUMNS] + ["Multimodality"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for r in rows:
        s = r.summary()
        cells = [_cell(s[key], scale, dec) for key, _, scale, dec in COLUMNS]
        mm = f"{r.multimodality:.2f}" if np.isfinite(r.multimodality) else "–"
        lines.append("| " + " | ".join([r.name] + cells + [mm]) + " |")
    return "\n".join(lines)


def _json_safe(value):
    """NaN / infinity (undefined metrics) -> None, so report.json is strict JSON (null)."""
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_json_safe(v) for v in value]
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def write_report(out_dir: Path, rows: list[RowResult], info: dict) -> None:
    """``report.md`` (settings + table + legend) and ``report.json`` (every number) in ``out_dir``."""
    data = {"settings": info, "rows": [{"name": r.name, "summary": r.summary(), "per_trial": r.per_trial,
                                        "multimodality": r.multimodality, "fid_over_time": r.fid_curve}
                                       for r in rows]}
    with atomic_path(out_dir / "report.json") as tmp:
        tmp.write_text(json.dumps(_json_safe(data), indent=1, allow_nan=False))
    settings = "\n".join(f"- {k}: {v}" for k, v in info.items())
    text = (f"# Stage-1 evaluation\n\n{settings}\n\n{markdown_table(rows)}\n\n"
            "Mean ± std over trials (seeds; deterministic rows are evaluated once). ↓ = lower is better; for the "
            "other columns the real dances are the target, not the maximum. D2M = Dancing2Music kinematic-offset "
            "beats, vel-min = local minima of smoothed joint speed (Bailando); a kinematic beat hits when a music "
            "beat is within "
            f"±{info['tolerance_frames']} frames. BAS σ = {metrics.DEFAULT_BAS_SIGMA_SECONDS} s. "
            "Multimodality is over seeds for the same song (– where undefined). Bone-length error: |length − the "
            "median length of that bone over the same dance| / that median, mean and 99th percentile over "
            "frames and bones; upside down: share of frames with the neck below the mid-hip; speed: mean joint "
            "speed / the real dances' on the same songs; legs/arms: mean "
            "speed of knees, ankles and feet / of elbows and wrists; jerk: mean |d³x/dt³| of the joints.\n\n"
            "![FID over time](fid_over_time.png)\n\n![Beat alignment](beat_alignment.png)\n")
    with atomic_path(out_dir / "report.md") as tmp:
        tmp.write_text(text)


@dataclass(frozen=True)
class EvaluationOptions:
    """What :func:`run_evaluation` does. ``seconds`` and ``video_seconds`` are seconds of each song."""

    trials: int = 3
    seconds: float = 60.0
    device: str = "auto"
    classifier: str | None = None
    classifier_preset: str = "paper"
    tolerance_frames: float = metrics.DEFAULT_TOLERANCE_FRAMES
    video_seconds: float = 10.0
    plot_seconds: float = 12.0
    grid_video: bool = False
    beat_snap: bool = False


def obtain_classifier(ds: DanceDataset, options: EvaluationOptions) -> tuple[LoadedStyleClassifier, str]:
    """The classifier given by ``options.classifier``, else the one cached in ``DATA/style_classifier/PRESET``
    (trained there first when missing or trained on other clips). Returns it and the folder it lives in."""
    from dancesynth.core.device import resolve_device
    from stage1_pose.style_classifier import KIND, load_style_classifier, train_on_dataset

    device = resolve_device(options.device)
    if options.classifier is not None:
        return load_style_classifier(options.classifier, device), str(options.classifier)
    run_dir = ds.root / "style_classifier" / options.classifier_preset
    key = hashlib.sha1(",".join(sorted(c.id for c in ds.clips("train"))).encode()).hexdigest()
    meta_path = run_dir / "latest.json"
    if meta_path.is_file() and json.loads(meta_path.read_text()).get("train_key") == key:
        return load_style_classifier(run_dir, device), str(run_dir)
    shutil.rmtree(run_dir, ignore_errors=True)  # trained on other clips, or cut short: trained anew
    clf, _ = train_on_dataset(ds.root, run_dir, options.classifier_preset, device=options.device)
    update_meta(run_dir, KIND, {"train_key": key})
    return clf, str(run_dir)


def _beat_figure(songs: list[HeldOutSong], dances: dict[str, PoseSequence], out_dir: Path, seconds: float) -> None:
    from dancesynth.core.motion import kinematic_offsets
    from dancesynth.core.plots import plot_beat_alignment
    from stage1_pose.beats import onset_strength

    song = songs[0]
    fps = song.real.fps
    n = min(len(song.real), int(round(seconds * fps)))
    panels = {}
    for name, dance in dances.items():
        xy = dance.xy[:n]
        panels[name] = (kinematic_offsets(xy, fps), kinematic_beats(xy, fps), velocity_minimum_beats(xy, fps))
    onset = onset_strength(song.samples[: int(round(n / fps * song.sr))], song.sr, fps)
    plot_beat_alignment(onset, song.beats[song.beats < n / fps], fps, panels, out_dir / "beat_alignment.png",
                        f"test song {song.id}: music onset strength and kinematic offset strength")


def run_evaluation(data_dir: str | os.PathLike, model_dirs: list[str], out_dir: str | os.PathLike,
                   options: EvaluationOptions) -> list[RowResult]:
    """Evaluate the baselines and every model in ``model_dirs`` on the test split of ``data_dir``.

    Writes ``report.md``, ``report.json``, ``fid_over_time.png``, ``beat_alignment.png``,
    ``videos/<row>.mp4`` (first test song, ``video_seconds`` long, with the song) and with ``options.grid_video``
    ``grid.mp4`` (the same clips side by side: real dances, the models, then the other baselines) into ``out_dir``.
    """
    from dancesynth.core.draw import write_grid_video, write_skeleton_video
    from dancesynth.core.plots import plot_fid_over_time

    if options.trials < 1 or options.seconds <= 0:
        raise DancesynthError("--trials must be at least 1 and --seconds positive.")
    ds = DanceDataset(data_dir)
    for run_dir in model_dirs:  # a wrong folder fails now, not after the classifier is trained
        load_meta(run_dir, "stage1")
    out_dir = Path(out_dir)
    try:
        (out_dir / "videos").mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise DancesynthError(f"Could not create the report folder {out_dir} ({e.strerror or e}); "
                              "choose another --out.") from e
    clf, clf_dir = obtain_classifier(ds, options)
    if list(clf.styles) != list(ds.styles):
        raise DancesynthError(f"The style classifier knows styles {clf.styles} but the dataset has {list(ds.styles)}; "
                              "train one on this dataset with `dancesynth train-style-classifier`.")
    songs = load_songs(ds, options.seconds)
    ref = load_reference(ds, clf)
    baselines = baseline_contenders(songs, ref)
    models = [model_contender(m, ds, songs, options.device, name, options.beat_snap)
              for m, name in zip(model_dirs, row_names(model_dirs, {c.name for c in baselines}))]
    contenders = baselines + models
    samples: dict[str, PoseSequence] = {}

    def keep_first(row: str, i: int, seed: int, dance: PoseSequence) -> None:
        if i == 0 and seed == 0:
            samples[row] = dance

    rows = [evaluate_contender(c, songs, ref, clf, options.trials, options.tolerance_frames, keep_first)
            for c in contenders]
    fps = songs[0].real.fps
    window_seconds = clf.window_frames / fps
    info = {"dataset": str(data_dir), "test songs": len(songs), "seconds per song": options.seconds,
            "trials": options.trials, "style classifier": clf_dir, "classifier window (s)": window_seconds,
            "tolerance_frames": options.tolerance_frames, "fps": fps, "models": ", ".join(model_dirs) or "none",
            "models' timing": "retimed onto the beats (--beat-snap)" if options.beat_snap else "their own"}
    write_report(out_dir, rows, info)
    plot_fid_over_time({r.name: r.fid_curve for r in rows}, window_seconds, out_dir / "fid_over_time.png")
    _beat_figure(songs, samples, out_dir, options.plot_seconds)
    song = songs[0]
    n_video = int(round(options.video_seconds * fps))
    clips = {name: dance.slice_frames(0, n_video) for name, dance in samples.items()}
    for name, clip in track(clips.items(), desc="sample videos", unit="video"):
        audio = song.samples[: int(round(len(clip) / fps * song.sr))]
        write_skeleton_video(clip, out_dir / "videos" / f"{_file_name(name)}.mp4", audio=audio, audio_sr=song.sr,
                             size=(640, 360))
    if options.grid_video:
        # The real dance first so every model is read against it, the mismatched/frozen baselines last.
        names = [c.name for c in [baselines[0], *models, *baselines[1:]]]
        write_grid_video([clips[name] for name in names], names, out_dir / "grid.mp4", beats=song.beats,
                         audio=song.samples, audio_sr=song.sr)
    return rows


def _file_name(row: str) -> str:
    """A row name as a safe file name (letters, digits, ``-`` and ``_``)."""
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in row).strip("_")
