import random

import numpy as np
import pytest
import torch
from torch import nn

from dancesynth.core.checkpoint import (
    capture_rng_state, load_checkpoint, load_training_state, restore_rng_state, save_checkpoint)
from dancesynth.core.errors import DancesynthError


def _model() -> nn.Module:
    torch.manual_seed(0)
    return nn.Sequential(nn.Linear(4, 3), nn.BatchNorm1d(3))


def test_round_trip_weights_meta_and_training_state(tmp_path):
    model = _model()
    opt = torch.optim.Adam(model.parameters(), lr=1e-3)
    model(torch.randn(5, 4)).sum().backward()
    opt.step()
    meta = {"kind": "stage1", "method": "lstm", "epoch": 3, "curriculum": {"p": 2}}
    save_checkpoint(tmp_path / "run", model, meta, {"optimizers": {"main": opt.state_dict()}, "position": 7})
    state, loaded = load_checkpoint(tmp_path / "run", "stage1")
    assert loaded["epoch"] == 3 and loaded["curriculum"] == {"p": 2}
    for k, v in model.state_dict().items():
        assert torch.equal(state[k], v)
    training = load_training_state(tmp_path / "run")
    assert training["position"] == 7
    opt2 = torch.optim.Adam(model.parameters(), lr=1e-3)
    opt2.load_state_dict(training["optimizers"]["main"])
    assert torch.equal(opt2.state_dict()["state"][0]["exp_avg"], opt.state_dict()["state"][0]["exp_avg"])


def test_tied_weights_are_saved(tmp_path):
    model = nn.Sequential(nn.Linear(3, 3, bias=False), nn.Linear(3, 3, bias=False))
    model[1].weight = model[0].weight
    save_checkpoint(tmp_path, model, {"kind": "stage1"})
    state, _ = load_checkpoint(tmp_path, "stage1")
    assert torch.equal(state["0.weight"], state["1.weight"])


def test_rng_state_round_trip_is_exact():
    random.gauss(0, 1)  # leaves a cached gaussian in python's state
    np.random.standard_normal()
    state = capture_rng_state()
    expected = (random.random(), random.gauss(0, 1), np.random.standard_normal(3), torch.rand(3))
    restore_rng_state(state)
    got = (random.random(), random.gauss(0, 1), np.random.standard_normal(3), torch.rand(3))
    assert expected[:2] == got[:2]
    np.testing.assert_array_equal(expected[2], got[2])
    assert torch.equal(expected[3], got[3])


def test_wrong_kind_says_what_to_pass(tmp_path):
    save_checkpoint(tmp_path, _model(), {"kind": "stage2"})
    with pytest.raises(DancesynthError, match="appearance model.*pose model.*instead"):
        load_checkpoint(tmp_path, "stage1")


def test_missing_and_foreign_folders(tmp_path):
    with pytest.raises(DancesynthError, match="does not exist"):
        load_checkpoint(tmp_path / "nope", "stage1")
    with pytest.raises(DancesynthError, match="not a finished dancesynth run"):
        load_checkpoint(tmp_path, "stage1")
    (tmp_path / "latest.json").write_text("[1, 2]")
    with pytest.raises(DancesynthError, match="not dancesynth checkpoint metadata"):
        load_checkpoint(tmp_path, "stage1")
    with pytest.raises(DancesynthError, match="cannot be resumed"):
        load_training_state(tmp_path)


def test_weights_from_another_save_are_detected(tmp_path):
    save_checkpoint(tmp_path / "a", _model(), {"kind": "stage1"})
    save_checkpoint(tmp_path / "b", _model(), {"kind": "stage1"})
    (tmp_path / "b" / "latest.safetensors").replace(tmp_path / "a" / "latest.safetensors")
    with pytest.raises(DancesynthError, match="stopped while saving"):
        load_checkpoint(tmp_path / "a", "stage1")
