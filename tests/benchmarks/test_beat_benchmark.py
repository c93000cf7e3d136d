"""The beat benchmark's ground truth (beat and bar grids from MIDI time signatures), its fixed split and scores."""

import importlib.util
import struct
import sys
import zlib
from collections import Counter
from pathlib import Path

import mido
import numpy as np
import pytest

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "beat_benchmark.py"
_SPEC = importlib.util.spec_from_file_location("beat_benchmark", _PATH)
bb = importlib.util.module_from_spec(_SPEC)
sys.modules["beat_benchmark"] = bb  # dataclasses look their module up while the class is made
_SPEC.loader.exec_module(bb)
_TRAIN_SPEC = importlib.util.spec_from_file_location("train_beat_tracker", _PATH.with_name("train_beat_tracker.py"))
train_beat_tracker = importlib.util.module_from_spec(_TRAIN_SPEC)
_TRAIN_SPEC.loader.exec_module(train_beat_tracker)

# The first benchmark's pieces: the project's tracker was tuned on them, so they may only be in dev.
TUNED_ON = ("metal-armygeddon", "metal-chaos_god", "metal-mutilated_mime", "rock-escape_from_chaosland",
            "rock-feelings", "rock-metal_madness", "rock-war_of_freedom", "jazz-blues-city_blues",
            "jazz-blues-say_what", "jazz-blues-slow_neasy", "jazz-blues-mosey_along", "jazz-blues-no_work_song",
            "soundtrack-chemistry_lab", "soundtrack-harp_harmony", "soundtrack-mighty_giant_run",
            "soundtrack-keep_on_rolling", "latin-bossa_nova", "latin-rhumba", "latin-rhumba_crescendo",
            "latin-bolero")


def test_four_four_by_default():
    beats, downbeats = bb.bar_grid([], 480, 480 * 8)
    assert beats.tolist() == [480.0 * k for k in range(9)]
    assert downbeats.tolist() == [0.0, 1920.0, 3840.0]


def test_six_eight_counts_dotted_quarters():
    beats, downbeats = bb.bar_grid([(0, 6, 8)], 480, 720 * 4)
    assert beats.tolist() == [0.0, 720.0, 1440.0, 2160.0, 2880.0]
    assert downbeats.tolist() == [0.0, 1440.0, 2880.0]
    assert bb.beat_unit(3, 4, 480) == (480.0, 3)
    assert bb.beat_unit(2, 2, 480) == (960.0, 2)


def test_pickup_is_counted_back_from_the_first_full_bar():
    # A 3/8 pickup (1.5 quarters) before 4/4: its one full beat sits half a quarter in, and it has no downbeat.
    beats, downbeats = bb.bar_grid([(0, 3, 8), (720, 4, 4)], 480, 720 + 1920)
    assert beats.tolist()[:3] == [240.0, 720.0, 1200.0]
    assert downbeats.tolist() == [720.0, 2640.0]


def test_metre_change_starts_a_bar():
    beats, downbeats = bb.bar_grid([(0, 4, 4), (1920, 3, 4)], 480, 1920 + 1440 * 2 - 1)
    assert downbeats.tolist() == [0.0, 1920.0, 3360.0]
    assert np.all(np.diff(beats) == 480)


def test_midi_grid_follows_tempo_and_time_signature(tmp_path):
    mid = mido.MidiFile(ticks_per_beat=96)
    track = mido.MidiTrack()
    mid.tracks.append(track)
    # 3/4 at 120 BPM for one bar, then 60 BPM; a note on every quarter for two bars.
    track.append(mido.MetaMessage("time_signature", numerator=3, denominator=4, time=0))
    track.append(mido.MetaMessage("set_tempo", tempo=500000, time=0))
    for k in range(6):
        if k == 3:
            track.append(mido.MetaMessage("set_tempo", tempo=1000000, time=0))
        track.append(mido.Message("note_on", note=60, velocity=90, time=0))
        track.append(mido.Message("note_off", note=60, velocity=0, time=96))
    mid.save(tmp_path / "waltz.mid")
    beats, downbeats, onsets = bb.midi_grid(tmp_path / "waltz.mid")
    np.testing.assert_allclose(beats, [0.0, 0.5, 1.0, 1.5, 2.5, 3.5, 4.5])
    np.testing.assert_allclose(downbeats, [0.0, 1.5, 4.5])
    np.testing.assert_allclose(onsets, beats[:6])
    # An MMA 6/8 groove that counts eighths as MIDI quarters: three of them a beat, two beats a bar.
    beats, downbeats, _ = bb.midi_grid(tmp_path / "waltz.mid", grid=(3, 2))
    np.testing.assert_allclose(beats, [0.0, 1.5, 4.5])
    np.testing.assert_allclose(downbeats, [0.0, 4.5])


def test_split_is_fixed_complete_and_balanced_by_kind():
    ids = [p.id for p in bb.PIECES]
    assert len(ids) == len(set(ids))
    assert set(bb.SPLIT) == set(ids) and set(bb.SPLIT.values()) == {"dev", "test", "holdout", "train"}
    assert all(bb.SPLIT[i] == "dev" for i in TUNED_ON)
    halves = [p for p in bb.PIECES if bb.SPLIT[p.id] in ("dev", "test")]
    assert len(halves) >= 40
    for main in {p.kinds[0] for p in halves}:
        counts = Counter(bb.SPLIT[p.id] for p in halves if p.kinds[0] == main)
        tuned = sum(p.kinds[0] == main for p in halves if p.id in TUNED_ON)
        assert abs(counts["dev"] - counts["test"]) <= 1 or counts["dev"] == tuned, main
    covered = [k for k in bb.KINDS if {bb.SPLIT[p.id] for p in halves if k in p.kinds} == {"dev", "test"}]
    assert len(covered) >= 8
    assert all(set(p.kinds) <= set(bb.KINDS) for p in bb.PIECES)


def test_held_out_grooves_play_no_test_library_file_and_are_left_out_of_training():
    held_out = {p.path for p in bb.HOLDOUT}
    assert len(held_out) == len(bb.HOLDOUT) >= 40 and all(bb.SPLIT[p.id] == "holdout" for p in bb.HOLDOUT)
    assert not held_out & train_beat_tracker._library_files("test")
    assert train_beat_tracker._library_files("holdout") == held_out
    assert len(bb.HOLDOUT_SONGS) >= 20 and all(bb.SPLIT[p.id] == "holdout" for p in bb.HOLDOUT_SONGS)
    # Freedoom's songs the networks train on come from the other WAD file.
    assert all(bb.SPLIT[p.id] == "train" for p in bb.TRAIN_SONGS)
    assert not {p.path for p in bb.TRAIN_SONGS} & {p.path for p in bb.HOLDOUT_SONGS}
    assert len(bb.HOLDOUT_PROJECTS) >= 20 and all(bb.SPLIT[p.id] == "holdout" for p in bb.HOLDOUT_PROJECTS)


def test_training_skips_grooves_of_held_out_files_without_rendering_them(tmp_path, capsys):
    """A groove drawn from a held-out library file is left out before MMA is asked to play it (here there is no
    such file, so MMA would report a failure); the same groove not held out is tried."""
    lib = tmp_path / "pkgs" / "mma" / "usr/share/mma/lib/casio/held.mma"

    def songs(skip: set) -> list:
        return train_beat_tracker._groove_songs(tmp_path, tmp_path, [(lib, "Held")], np.random.default_rng(0), 1,
                                                (60.0, 190.0), "mma", skip)

    assert songs({lib}) == [] and "MMA failed" not in capsys.readouterr().out
    assert songs(set()) == [] and "mma-casio-Held: MMA failed" in capsys.readouterr().out


def test_tempo_kinds():
    assert bb.tempo_kinds(np.arange(0, 10, 60 / 160)) == {"fast"}
    assert bb.tempo_kinds(np.arange(0, 10, 60 / 80)) == {"slow"}
    assert bb.tempo_kinds(np.arange(0, 10, 0.5)) == set()
    # A chart at exactly 150 BPM, its beats summed in floating point: 149.99999999999787 before rounding.
    assert bb.tempo_kinds(np.cumsum(np.full(300, 0.4)) + 12.345) == {"fast"}


def test_mma_song_plays_the_groove_for_about_a_minute():
    piece = next(p for p in bb.PIECES if p.id == "triple-68ballad_56")
    lines = bb.mma_song(piece).splitlines()
    assert lines[:4] == ["RndSeed 1", "Tempo 168", "Use casio/68ballad", "Groove 68Ballad"]
    # 168 eighths a minute, six a bar: 28 bars a minute.
    assert len([line for line in lines[4:] if line]) == 28


def test_scores_leave_downbeats_empty_without_them():
    ref = np.arange(0.0, 20.0, 0.5)
    f, cmlt, amlt, down = bb.scores(ref, None, ref, ref[::4])
    assert (f, cmlt, amlt) == (1.0, 1.0, 1.0) and np.isnan(down)
    assert bb.scores(ref, ref[2::4], ref, ref[::4])[3] == 0.0
    assert bb._column_means([(1.0, np.nan), (0.5, np.nan)])[0] == 0.75
    assert np.isnan(bb._column_means([(1.0, np.nan)])[1])


def test_a_song_comes_out_of_its_wad_file_whole(tmp_path):
    """Freedoom's songs are MIDI lumps of a WAD file: a header, the lumps, then a directory of (offset, size, name)."""
    song, other = b"MThd" + bytes(range(40)), b"not a song"
    directory = struct.pack("<ii8s", 12, len(other), b"DEMO1") + struct.pack("<ii8s", 12 + len(other), len(song),
                                                                             b"D_RUNNIN")
    wad = tmp_path / "test.wad"
    wad.write_bytes(struct.pack("<4sii", b"IWAD", 2, 12 + len(other) + len(song)) + other + song + directory)
    assert bb.wad_lump(wad, "D_RUNNIN") == song
    piece = bb.Piece("p", ("rock-metal",), "freedoom", "test.wad", "BSD-3-Clause", "wad", "D_RUNNIN")
    (tmp_path / "pkgs" / "freedoom").mkdir(parents=True)
    wad.rename(tmp_path / "pkgs" / "freedoom" / "test.wad")
    assert bb.piece_midi(tmp_path, piece, tmp_path).read_bytes() == song


def test_an_lmms_project_keeps_its_tempo_and_bars_from_time_zero(tmp_path):
    """LMMS's ``.mmpz`` is its XML compressed the Qt way (a 4-byte big-endian length, then zlib); ``.mmp`` is plain."""
    xml = b'<lmms-project><head bpm="150" timesig_numerator="3" timesig_denominator="4"/><song/></lmms-project>'
    packed = tmp_path / "song.mmpz"
    packed.write_bytes(struct.pack(">I", len(xml)) + zlib.compress(xml))
    beats, downbeats = bb.lmms_grid(packed, 2.0)
    np.testing.assert_allclose(beats, np.arange(5) * 0.4)
    np.testing.assert_allclose(downbeats, [0.0, 1.2])
    plain = tmp_path / "eights.mmp"
    plain.write_bytes(xml.replace(b'timesig_denominator="4"', b'timesig_denominator="8"'))
    with pytest.raises(ValueError, match="x/4"):
        bb.lmms_grid(plain, 2.0)
