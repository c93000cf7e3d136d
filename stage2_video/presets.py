"""The appearance model's presets by name: what every command and the web page offer, and ``auto`` resolved.

The configs are :data:`stage2_video.models.pix2pixhd.PRESETS`; this module names them without importing torch, so
argument parsers list them at once (``tests/stage2_video/test_presets.py`` checks that the two agree). ``auto`` is
resolved here and nowhere else (:func:`resolve_preset`).
"""

from __future__ import annotations

from dancesynth.core.errors import DancesynthError

AUTO = "auto"
# Each preset of pix2pixhd.PRESETS, in a few words for help texts and the web page's menu.
PRESETS: dict[str, str] = {
    "small": "128 px, CPU",
    "medium": "256 px, GPUs and AMX CPUs",
    "paper": "1024x512, local enhancer, GPU",
}
AUTO_MEANS = "medium on GPUs and AMX CPUs, small elsewhere"


def preset_names(auto: bool = False) -> tuple[str, ...]:
    """The presets' names, led by ``auto`` for a caller that resolves it with :func:`resolve_preset`."""
    return (AUTO, *PRESETS) if auto else tuple(PRESETS)


def describe_presets(auto: bool = False) -> str:
    """One line naming each preset and what it is, for a ``--preset`` help text."""
    listed = "; ".join(f"{name}: {what}" for name, what in PRESETS.items())
    return f"{listed}; {AUTO}: {AUTO_MEANS}" if auto else listed


def resolve_preset(name: str | None, device: str = "auto", precision: str = "auto") -> str:
    """Preset ``name``, checked; for ``auto`` (or None) the largest preset that trains well in minutes on ``device``
    computing in ``precision`` (:func:`stage2_video.models.pix2pixhd.affordable_preset`)."""
    if name is None or name == AUTO:
        from dancesynth.core.device import resolve_device, resolve_precision
        from stage2_video.models.pix2pixhd import affordable_preset

        dev = resolve_device(device)
        return affordable_preset(dev, resolve_precision(precision, dev))
    if name not in PRESETS:
        raise DancesynthError(f"Unknown preset {name!r}; choose one of {', '.join(preset_names(auto=True))}.")
    return name
