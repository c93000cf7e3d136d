"""Train the learned beat and downbeat tracker (:mod:`stage1_pose.beat_tracking`) on audio with exact grids that
needs no labelling, and write the networks the package ships (three, seeds 0, 1 and 2; the tracker averages them).

    .venv/bin/python benchmarks/beat_benchmark.py fetch        # once: packages, renderer, the benchmark's pieces
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/train_beat_tracker.py corpus   # renders the corpus (~9 min)
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/train_beat_tracker.py train --minutes 45 --seed 0 --no-train-split
        # writes stage1_pose/pretrained/beat_tracker/seed0, rendering what is missing first; then, from its weights:
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/train_beat_tracker.py train --minutes 15 --lr 5e-4 --seed 100 \
        --init stage1_pose/pretrained/beat_tracker/seed0 --out stage1_pose/pretrained/beat_tracker/seed0
        # and the same for seeds 1 and 2 (--seed 1, then --seed 101; --seed 2, then --seed 102)

The shipped networks were trained so: 45 minutes on the corpus without the benchmark's "train" split (400 songs),
then 15 minutes more, at a quarter of the learning rate, with it (423 songs).

It lives beside the benchmark because it reuses the benchmark's packages, renderer and loaders and needs the same
system tools (``fluidsynth``, ``fluid-soundfont-gm``; ``mma`` and the scores come from the fetched packages), which
users of the product do not have. The corpus (``--corpus``, default ``~/.cache/dancesynth/beat-train``) holds one
``.npz`` per song: log-mel frames (float16 ``[T, 64]``) and its beat and downbeat times in seconds.

Sources, none of them a test-half piece or made from one:

* MMA grooves (``mma``'s library, GPL-2.0+) at random tempi (log-uniform 60-190 BPM, and 80 more at 45-95 BPM):
  a song of about
  ``_MMA_SECONDS`` s of chords in one groove, written to MIDI by MMA (the benchmark's :func:`mma_song`), rendered by
  fluidsynth with a random gain, reverb room and level. Kept when its MIDI time signatures are x/4 with x in 2-4
  (the grid is then exact; MMA writes 6/8 loosely). Library files a test piece plays from are left out, grooves and
  all, and so are the benchmark's held-out grooves (``HOLDOUT``).
* MMA's example songs (``mma``'s documentation, GPL-2.0+) whose ``.mma`` plays no groove of those files, and the
  OpenTTD OpenMSX pieces the benchmark does not hold (GPL-2.0), rendered the same way, grids from their MIDI time
  signatures.
* The benchmark's dev half as it is (recordings and renderings); never its test half.
* The benchmark's "train" split (Freedoom's first WAD, BSD-3-Clause: songs composed for the game), rendered like
  MMA's example songs (random gain and room), those in 2-4/4; left out with ``--no-train-split``.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from beat_benchmark import (  # noqa: E402
    _MMA_EXAMPLES,
    _MMA_LIB,
    _OPENMSX,
    DEFAULT_CACHE,
    PIECES,
    SPLIT,
    Piece,
    load_audio,
    midi_grid,
    piece_midi,
    render_midi,
)

from stage1_pose.beat_tracking.train import TrainConfig  # noqa: E402

DEFAULT_CORPUS = Path.home() / ".cache" / "dancesynth" / "beat-train"
_MMA_SONGS = 240
_MMA_SECONDS = 30.0
_MMA_BPM = (60.0, 190.0)
# Slow songs went to double tempo or 3:2 with the first corpus alone (test half: slow F 0.52).
_MMA_SLOW_SONGS = 80
_MMA_SLOW_BPM = (45.0, 95.0)
_SEED = 0
# The train split's renders draw their own gains and rooms, so adding them changed no other song.
_TRAIN_SPLIT_SEED = 7


def _groove_names(path: Path) -> list[str]:
    """Grooves an MMA library file defines (``DefGroove NAME``)."""
    return re.findall(r"^\s*DefGroove\s+(\S+)", path.read_text(errors="replace"), re.MULTILINE | re.IGNORECASE)


def _library_files(split: str) -> set[str]:
    """MMA library files (package paths) that the benchmark's pieces of ``split`` play from."""
    return {p.path for p in PIECES if p.source == "mma" and SPLIT[p.id] == split}


def _simple_metre(mid: Path) -> bool:
    """True when every time signature of the MIDI file is 2/4, 3/4 or 4/4 (or it has none)."""
    import mido

    sigs = [m for track in mido.MidiFile(mid).tracks for m in track if m.type == "time_signature"]
    return all(m.denominator == 4 and m.numerator in (2, 3, 4) for m in sigs)


def _render_options(rng: np.random.Generator) -> tuple[float, list[str]]:
    """A random fluidsynth gain and reverb: the same notes heard at other levels and in other rooms."""
    return float(rng.uniform(0.15, 0.5)), [f"synth.reverb.room-size={rng.uniform(0.0, 0.9):.2f}",
                                           f"synth.reverb.level={rng.uniform(0.0, 0.9):.2f}"]


def _save(path: Path, samples: np.ndarray, beats: np.ndarray, downbeats: np.ndarray) -> None:
    from stage1_pose.beat_tracking.spectrogram import mel_frames

    end = len(samples) / 22050
    beats, downbeats = beats[beats < end], downbeats[downbeats < end]
    tmp = path.with_suffix(".part.npz")
    np.savez(tmp, mel=mel_frames(samples, 22050).astype(np.float16), beats=beats, downbeats=downbeats)
    tmp.rename(path)
    print(f"{path.stem:50s} {len(samples) / 22050:6.1f} s {len(beats):4d} beats", flush=True)


def _midi_item(out: Path, mid: Path, tmp: Path, render_options: tuple[float, list[str]],
               max_seconds: float = 120.0) -> None:
    gain, options = render_options
    samples = render_midi(mid, tmp, gain, 22050, options)[:int(max_seconds * 22050)]
    beats, downbeats, _ = midi_grid(mid)
    _save(out, samples, beats, downbeats)


def _groove_songs(cache: Path, corpus: Path, grooves: list[tuple[Path, str]], rng: np.random.Generator, count: int,
                  bpm_range: tuple[float, float], prefix: str, skip: set[Path]) -> list[Path]:
    """``count`` songs of grooves drawn from ``grooves`` (library file, name) at log-uniform tempi in ``bpm_range``,
    rendered into ``corpus`` as ``<prefix>-<library>-<groove>.npz`` where missing; the files of those in 2-4/4,
    leaving out those drawn from a library file in ``skip``."""
    pkgs = cache / "pkgs"
    files = []
    for n in sorted(rng.choice(len(grooves), size=min(count, len(grooves)), replace=False)):
        lib, groove = grooves[n]
        bpm = float(np.exp(rng.uniform(*np.log(bpm_range))))
        gain_options = _render_options(rng)
        if lib in skip:
            continue
        out = corpus / f"{prefix}-{lib.parent.name}-{groove}.npz"
        if not out.exists():
            piece = Piece(out.stem, (), "mma", str(lib.relative_to(pkgs / "mma")), "GPL-2.0-or-later", "mma",
                          groove, round(bpm, 1))
            with tempfile.TemporaryDirectory() as tmp:
                try:
                    mid = piece_midi(cache, piece, Path(tmp), _MMA_SECONDS)
                except subprocess.CalledProcessError:  # a groove MMA cannot play on its own is skipped
                    print(f"{out.stem}: MMA failed", flush=True)
                    continue
                if not _simple_metre(mid):
                    continue
                samples = render_midi(mid, Path(tmp), gain_options[0], 22050, gain_options[1])
                beats, downbeats, _ = midi_grid(mid)
                _save(out, samples, beats, downbeats)
        files.append(out)
    return files


def build_corpus(cache: Path, corpus: Path, train_split: bool = True) -> list[Path]:
    """Render every corpus song not yet in ``corpus`` and return all of their files (the benchmark's "train" split
    among them unless ``train_split`` is False)."""
    corpus.mkdir(parents=True, exist_ok=True)
    pkgs = cache / "pkgs"
    rng = np.random.default_rng(_SEED)
    test_libs, holdout_libs = _library_files("test"), _library_files("holdout")
    unheard = {g.lower() for lib in test_libs | holdout_libs for g in _groove_names(pkgs / "mma" / lib)}
    libraries = sorted(p for p in (pkgs / "mma" / _MMA_LIB).glob("*/*.mma")
                       if str(p.relative_to(pkgs / "mma")) not in test_libs)
    grooves = [(lib, g) for lib in libraries for g in _groove_names(lib)]
    # The held-out grooves are skipped after the draw (the shipped corpus holds none of them), so the draws and the
    # corpus stay those the shipped networks trained on.
    skip = {pkgs / "mma" / lib for lib in holdout_libs}
    files = _groove_songs(cache, corpus, grooves, rng, _MMA_SONGS, _MMA_BPM, "mma", skip)
    # Slow songs again, from their own seed so the pass above draws what it drew before.
    files += _groove_songs(cache, corpus, grooves, np.random.default_rng(_SEED + 1), _MMA_SLOW_SONGS, _MMA_SLOW_BPM,
                           "mma-slow", skip)
    benchmark_files = {p.path for p in PIECES}
    midi_songs: list[tuple[Path, Path]] = []  # (corpus file, MIDI file) of the songs rendered as they are
    for mma in sorted((pkgs / "mma" / _MMA_EXAMPLES).glob("*/*.mma")):
        mid = mma.with_suffix(".mid")
        used = {g.lower() for g in re.findall(r"^\s*Groove\s+(\S+)", mma.read_text(errors="replace"),
                                               re.MULTILINE | re.IGNORECASE)}
        if not mid.exists() or used & unheard or str(mid.relative_to(pkgs / "mma")) in benchmark_files:
            continue
        midi_songs.append((corpus / f"example-{mma.parent.name}-{mma.stem}.npz", mid))
    for mid in sorted((pkgs / "openttd-openmsx" / _OPENMSX).glob("*.mid")):
        if str(mid.relative_to(pkgs / "openttd-openmsx")) not in benchmark_files:
            midi_songs.append((corpus / f"openmsx-{mid.stem}.npz", mid))
    for out, mid in midi_songs:
        if not out.exists() and _simple_metre(mid):
            with tempfile.TemporaryDirectory() as tmp:
                _midi_item(out, mid, Path(tmp), _render_options(rng))
        files.append(out)
    for piece in PIECES:
        if SPLIT[piece.id] != "dev":
            continue
        out = corpus / f"dev-{piece.id}.npz"
        if not out.exists():
            info = json.loads((cache / "audio" / f"{piece.id}.json").read_text())
            _save(out, load_audio(cache / "audio" / f"{piece.id}.flac"), np.array(info["beats"]),
                  np.array(info["downbeats"]))
        files.append(out)
    rng = np.random.default_rng(_TRAIN_SPLIT_SEED)
    train_pieces = sorted((p for p in PIECES if SPLIT[p.id] == "train"), key=lambda p: p.id) if train_split else []
    for piece in train_pieces:
        out = corpus / f"{piece.id}.npz"
        with tempfile.TemporaryDirectory() as tmp:
            mid = piece_midi(cache, piece, Path(tmp))
            if not _simple_metre(mid):
                continue
            render_options = _render_options(rng)  # drawn for every song, so a missing one renders as at first
            if not out.exists():
                _midi_item(out, mid, Path(tmp), render_options)
        files.append(out)
    return [f for f in files if f.exists()]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("command", choices=("corpus", "train"))
    parser.add_argument("--cache", type=Path, default=DEFAULT_CACHE, help="the benchmark's cache (after fetch)")
    parser.add_argument("--corpus", type=Path, default=DEFAULT_CORPUS)
    parser.add_argument("--out", type=Path, default=None,
                        help="train: the network's folder (default stage1_pose/pretrained/beat_tracker/seed<SEED>)")
    parser.add_argument("--minutes", type=float, default=45.0, help="train: wall-clock training budget")
    parser.add_argument("--preset", default="small")
    parser.add_argument("--seed", type=int, default=0, help="train: the initial weights' and excerpts' seed")
    parser.add_argument("--lr", type=float, default=TrainConfig.lr, help="train: Adam's learning rate at the start")
    parser.add_argument("--init", type=Path, default=None,
                        help="train: a trained network's folder to go on training (its log is kept in the new one)")
    parser.add_argument("--no-train-split", action="store_true",
                        help="leave the benchmark's \"train\" split (Freedoom's first WAD) out of the corpus")
    args = parser.parse_args()
    if not (args.cache / "pkgs" / "mma").is_dir():
        raise SystemExit(f"No packages in {args.cache}: run `beat_benchmark.py fetch` first.")
    files = build_corpus(args.cache, args.corpus, not args.no_train_split)
    print(f"corpus: {len(files)} songs in {args.corpus}", flush=True)
    if args.command == "train":
        from stage1_pose.beat_tracking.model import load_model
        from stage1_pose.beat_tracking.tracker import PRETRAINED
        from stage1_pose.beat_tracking.train import load_corpus, save, train

        out = args.out or PRETRAINED / f"seed{args.seed}"
        init, before = None, {}
        if args.init is not None:
            init = load_model(args.init)
            before = {"init": json.loads((args.init / "config.json").read_text())["training"]}
        model, log = train(load_corpus(files), args.preset,
                           TrainConfig(minutes=args.minutes, seed=args.seed, lr=args.lr), out, init)
        save(model, out, {"corpus_songs": len(files), **log, **before})
        print(f"wrote {out}", flush=True)


if __name__ == "__main__":
    main()
