"""The appearance model's preset names and ``auto``'s resolution (:mod:`stage2_video.presets`)."""

import pytest

from dancesynth.core.errors import DancesynthError
from stage2_video import presets
from stage2_video.models import pix2pixhd


def test_the_names_are_the_configs_presets_in_their_order():
    assert presets.preset_names() == tuple(pix2pixhd.PRESETS)
    assert presets.preset_names(auto=True) == ("auto", *pix2pixhd.PRESETS)


def test_a_named_preset_is_itself_and_an_unknown_one_a_sentence_listing_the_choices():
    for name in pix2pixhd.PRESETS:
        assert presets.resolve_preset(name, "cpu") == name
    with pytest.raises(DancesynthError, match=r"Unknown preset 'huge'; choose one of auto, small, medium, paper\."):
        presets.resolve_preset("huge", "cpu")


@pytest.mark.parametrize("amx", [True, False])
def test_auto_is_what_the_hardware_affords(monkeypatch, amx):
    """``auto`` and no preset both go to :func:`pix2pixhd.affordable_preset` with the precision asked for."""
    monkeypatch.setattr(pix2pixhd, "cpu_has_amx", lambda: amx)
    monkeypatch.setattr("dancesynth.core.device.cpu_has_bf16", lambda: True)
    expected = "medium" if amx else "small"
    assert presets.resolve_preset("auto", "cpu", "bf16") == presets.resolve_preset(None, "cpu", "bf16") == expected
    assert presets.resolve_preset("auto", "cpu", "fp32") == "small"
