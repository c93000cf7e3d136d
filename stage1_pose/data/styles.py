"""The built-in dance styles: how their music sounds and which moves their dancers use.

A style is a dataclass of plain values read by :mod:`stage1_pose.data.synth_music` (tempo, timbres, drum
pattern) and :mod:`stage1_pose.data.synth_dance` (move vocabulary, beats per move segment, bounce and sway).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Style:
    """One dance style.

    Attributes:
        name: label stored in the dataset manifest.
        bpm_range: tempo range in beats per minute; each song draws its tempo uniformly from it.
        minor_probability: chance that a song is in a minor key.
        chord_beats: beats per chord of the progression.
        kick_gain: level of the kick drum on every beat (0 = none); the kick is what beat trackers follow.
        accent_kick: extra kick level on beats 1 and 3 of a bar.
        snare_gain: level of the snare / clap on beats 2 and 4 (0 = none).
        hihat_division: hi-hat hits per beat (0 = no hi-hat).
        bass: bass timbre: ``pluck`` (soft plucked string), ``808`` (long sine with saturation) or ``synth`` (saw).
        pad: chord timbre: ``strings`` (slow attack, detuned saws, vibrato), ``keys`` (decaying electric
            piano) or ``bright`` (plucky saw stabs on the off-beats).
        lead: melody timbre: ``flute`` (sine + soft harmonics, vibrato), ``bell`` or ``square``.
        melody_division: melody notes per beat (fractions give longer notes).
        moves: names of the moves in :data:`stage1_pose.data.synth_dance.MOVES` this style's dancers use.
        segment_beats: beats per move segment, from which each move instance draws (1, 2 or 4); keyframes
            sit at segment ends, so these are the beats the dance hits.
        hit_fraction: fraction of a segment spent holding before moving (0 = legato motion,
            larger = sharper hits that arrive on the beat).
        ramp: seconds a segment takes to speed up from rest and to slow down to rest; in between the joints move
            at constant speed. Short ramps make the sudden stops on beats that kinematic beat detectors find.
        bounce: knee bend on every beat in radians (0 = none).
        sway: amplitude of the side-to-side sway of the hips, as a fraction of body height.
    """

    name: str
    bpm_range: tuple[float, float]
    minor_probability: float
    chord_beats: int
    kick_gain: float
    accent_kick: float
    snare_gain: float
    hihat_division: int
    bass: str
    pad: str
    lead: str
    melody_division: float
    moves: tuple[str, ...]
    segment_beats: tuple[int, ...]
    hit_fraction: float
    ramp: float
    bounce: float
    sway: float


BALLET = Style(
    name="ballet", bpm_range=(60.0, 80.0), minor_probability=0.4, chord_beats=8,
    kick_gain=0.35, accent_kick=0.1, snare_gain=0.0, hihat_division=0,
    bass="pluck", pad="strings", lead="flute", melody_division=0.5,
    moves=("port_de_bras", "plie", "arabesque_arms", "tendu", "cambre", "arm_wave", "bras_ouverts"),
    segment_beats=(2, 4), hit_fraction=0.0, ramp=0.15, bounce=0.0, sway=0.015,
)
HIPHOP = Style(
    name="hiphop", bpm_range=(90.0, 105.0), minor_probability=0.8, chord_beats=4,
    kick_gain=0.7, accent_kick=0.3, snare_gain=0.5, hihat_division=2,
    bass="808", pad="keys", lead="bell", melody_division=1.0,
    moves=("bounce_hit", "arm_cross", "point", "chest_pop", "side_step", "arm_wave_hit", "squat_hold"),
    segment_beats=(1, 2), hit_fraction=0.1, ramp=0.08, bounce=0.1, sway=0.01,
)
POP = Style(
    name="pop", bpm_range=(115.0, 135.0), minor_probability=0.2, chord_beats=4,
    kick_gain=0.6, accent_kick=0.0, snare_gain=0.4, hihat_division=2,
    bass="synth", pad="bright", lead="square", melody_division=2.0,
    moves=("clap", "jump", "step_clap", "arm_pump", "disco_point", "jumping_jack", "hip_sway"),
    segment_beats=(1, 2), hit_fraction=0.2, ramp=0.1, bounce=0.1, sway=0.02,
)

STYLES: dict[str, Style] = {s.name: s for s in (BALLET, HIPHOP, POP)}
