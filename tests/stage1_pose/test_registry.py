import subprocess
import sys
from pathlib import Path

import pytest

import stage1_pose.models
from dancesynth.core.errors import DancesynthError
from stage1_pose.models.base import Stage1Method
from stage1_pose.registry import build_method, config_type, load_method, make_config, method_names


def test_methods_are_the_packages_under_models():
    packages = sorted(p.parent.name for p in Path(stage1_pose.models.__path__[0]).glob("*/__init__.py"))
    assert method_names() == packages == ["dance_revolution", "dancing2music", "lstm", "ren"]


def test_listing_methods_imports_none_of_them():
    code = ("import sys; from stage1_pose.registry import method_names; method_names(); "
            "print(sorted(m for m in sys.modules if m.startswith('stage1_pose.models.') or m == 'torch'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=Path(__file__).parents[2]).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize("name", method_names())
def test_every_method_exports_its_class_config_and_presets(name):
    method, presets = load_method(name)
    assert issubclass(method, Stage1Method) and {"small", "paper"} <= set(presets)
    assert all(type(cfg) is config_type(name) for cfg in presets.values())


def test_make_config_applies_string_overrides_and_builds():
    config = make_config("lstm", "small", {"hidden": "8", "layers": "1"})
    assert (config.hidden, config.layers) == (8, 1)
    assert isinstance(build_method("lstm", config), Stage1Method)


def test_unknown_method_or_preset_lists_the_choices():
    with pytest.raises(DancesynthError, match="choose one of dance_revolution, dancing2music, lstm, ren"):
        load_method("nope")
    with pytest.raises(DancesynthError, match="choose one of"):
        make_config("lstm", "huge")
