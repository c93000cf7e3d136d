"""Ren et al.'s waveform input: consecutive pieces of the song brought to one level, one per pose frame."""

import numpy as np

from stage1_pose.models.ren.music_input import WAVEFORM_SR
from stage1_pose.music_features import cache_name, extract_features, level_normalised


def test_waveform_rows_are_consecutive_level_normalised_audio():
    y = np.sin(np.arange(WAVEFORM_SR * 2) * 0.05).astype(np.float32) * np.linspace(0.05, 0.5, WAVEFORM_SR * 2)
    rows = extract_features(y, WAVEFORM_SR, "waveform")
    np.testing.assert_allclose(rows.reshape(-1), level_normalised(y, WAVEFORM_SR), rtol=1e-6)


def test_a_quiet_intro_and_a_loud_rest_come_out_at_one_level():
    rng = np.random.default_rng(0)
    noise = rng.standard_normal(WAVEFORM_SR * 20).astype(np.float32)
    song = noise * np.where(np.arange(len(noise)) < WAVEFORM_SR * 10, 0.01, 0.3).astype(np.float32)  # -30 dB intro
    rows = extract_features(song, WAVEFORM_SR, "waveform")
    rms = np.sqrt((rows ** 2).mean(axis=1))
    intro, rest = rms[:8 * 15].mean(), rms[12 * 15:].mean()
    assert abs(20 * np.log10(intro / rest)) < 1.0
    assert 0.08 < rest < 0.12


def test_silence_stays_quiet():
    y = np.zeros(WAVEFORM_SR * 4, np.float32)
    y[WAVEFORM_SR:WAVEFORM_SR * 2] = 1e-4
    assert np.abs(level_normalised(y, WAVEFORM_SR)).max() <= 1e-2


def test_the_cache_folder_names_the_recipe_version():
    assert cache_name("waveform") == "waveform-v2"
    assert cache_name("dance_revolution") == "dance_revolution"
