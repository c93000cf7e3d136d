import dataclasses
import json

import pytest

from dancesynth.core.config import (
    apply_overrides,
    config_from_dict,
    config_to_dict,
    format_config,
    load_config_file,
    update_config,
)
from dancesynth.core.errors import DancesynthError
from stage1_pose.models.ren.stgcn import STGCN_PRESETS
from stage1_pose.registry import load_method, method_names
from stage1_pose.style_classifier import PRESETS as STYLE_PRESETS
from stage1_pose.train import TrainerConfig
from stage2_video.models.pix2pixhd import PRESETS as PIX2PIXHD_PRESETS
from stage2_video.train import TrainOptions


def every_config():
    """Every config of the project: all presets of every stage-1 method, pix2pixHD, the style classifier and
    the ST-GCN, and the two trainers' options (defaults and with optional fields set)."""
    configs = [cfg for name in method_names() for cfg in load_method(name)[1].values()]
    configs += [*PIX2PIXHD_PRESETS.values(), *STYLE_PRESETS.values(), *STGCN_PRESETS.values()]
    return configs + [TrainerConfig(), TrainerConfig(epochs=3, minutes=1.5), TrainOptions(), TrainOptions(epochs=2)]


@dataclasses.dataclass(frozen=True)
class Inner:
    sizes: tuple[int, ...] = (1, 2)
    rate: float = 0.5


@dataclasses.dataclass(frozen=True)
class Outer:
    name: str = "a"
    inner: Inner = Inner()
    steps: int | None = None


@pytest.mark.parametrize("cfg", every_config(), ids=lambda c: type(c).__name__)
def test_every_config_survives_json_and_toml(cfg, tmp_path):
    assert config_from_dict(type(cfg), json.loads(json.dumps(config_to_dict(cfg)))) == cfg
    for fmt in ("toml", "json"):
        path = tmp_path / f"config.{fmt}"
        path.write_text(format_config(cfg, fmt))
        assert update_config(cfg, load_config_file(path)) == cfg


def test_tuples_come_back_as_tuples():
    ren = load_method("ren")[1]["paper"]
    back = config_from_dict(type(ren), json.loads(json.dumps(config_to_dict(ren))))
    assert isinstance(back.audio_channels, tuple) and isinstance(back.perceptual_layer_weights, tuple)
    assert back.perceptual_layer_weights == ren.perceptual_layer_weights


def test_nested_config_round_trips_and_overrides_change_one_field(tmp_path):
    cfg = Outer(inner=Inner(sizes=(3, 4, 5)), steps=7)
    assert config_from_dict(Outer, json.loads(json.dumps(config_to_dict(cfg)))) == cfg
    path = tmp_path / "c.toml"
    path.write_text(format_config(cfg))
    assert config_from_dict(Outer, load_config_file(path)) == cfg
    assert apply_overrides(cfg, ["inner.rate=2"]) == Outer(inner=Inner(sizes=(3, 4, 5), rate=2.0), steps=7)


def test_strings_are_parsed_to_the_field_types():
    cfg = apply_overrides(Outer(steps=3), ["name=b", "steps=none", "inner.sizes=8, 16", "inner.rate=1e-3"])
    assert cfg == Outer(name="b", inner=Inner(sizes=(8, 16), rate=1e-3), steps=None)
    lstm = load_method("lstm")[1]["small"]
    dr_type = type(load_method("dance_revolution")[1]["small"])
    assert apply_overrides(lstm, ["hidden=64", "dropout=0"]).hidden == 64
    assert config_from_dict(dr_type, {"code_on_beats": "true", "beat_phase_input": "0"}).code_on_beats is True


def test_unknown_key_is_named_with_the_known_ones():
    with pytest.raises(DancesynthError, match="no setting hiden; known settings: .*hidden"):
        apply_overrides(load_method("lstm")[1]["small"], ["hiden=3"])
    with pytest.raises(DancesynthError, match="no setting colour"):
        config_from_dict(type(PIX2PIXHD_PRESETS["small"]), {"colour": 1})


@pytest.mark.parametrize("item", ["steps=many", "steps=2.5", "inner.sizes=a,b", "inner.rate=fast"])
def test_a_value_that_does_not_fit_is_an_error(item):
    with pytest.raises(DancesynthError, match="Invalid (Outer|Inner) setting"):
        apply_overrides(Outer(), [item])


def test_a_malformed_override_says_how_to_write_it():
    with pytest.raises(DancesynthError, match="FIELD=VALUE"):
        apply_overrides(Outer(), ["steps"])


def test_config_file_errors_are_clear(tmp_path):
    with pytest.raises(DancesynthError, match="does not exist"):
        load_config_file(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("hidden = = 3\n")
    with pytest.raises(DancesynthError, match="cannot be read"):
        load_config_file(bad)
    good = tmp_path / "good.toml"
    good.write_text("hidden = 64\n# a comment\nlayers = 2\n")
    assert load_config_file(good) == {"hidden": 64, "layers": 2}
