import json
import os
import pickle
import random

import numpy as np
import pytest
import torch
from safetensors.torch import save_file
from torch import nn

from dancesynth.core.checkpoint import (
    capture_rng_state,
    load_checkpoint,
    load_meta,
    load_training_state,
    restore_rng_state,
    save_checkpoint,
)
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
    training = load_training_state(tmp_path / "run", loaded)
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
    save_checkpoint(tmp_path / "weights_only", _model(), {"kind": "stage1"})
    with pytest.raises(DancesynthError, match="cannot be resumed"):
        load_training_state(tmp_path / "weights_only", load_meta(tmp_path / "weights_only", "stage1"))


def _checkpoint_folder(run):
    return run / json.loads((run / "latest.json").read_text())["checkpoint"]


def test_weights_from_another_save_are_detected(tmp_path):
    save_checkpoint(tmp_path / "a", _model(), {"kind": "stage1"})
    save_checkpoint(tmp_path / "b", _model(), {"kind": "stage1"})
    stray = _checkpoint_folder(tmp_path / "b") / "model.safetensors"
    stray.replace(_checkpoint_folder(tmp_path / "a") / "model.safetensors")
    with pytest.raises(DancesynthError, match="stopped while saving"):
        load_checkpoint(tmp_path / "a", "stage1")


def test_a_new_save_replaces_the_previous_checkpoint_folder(tmp_path):
    model = _model()
    save_checkpoint(tmp_path, model, {"kind": "stage1", "step": 1})
    first = _checkpoint_folder(tmp_path)
    with torch.no_grad():
        model[0].weight.add_(1.0)
    save_checkpoint(tmp_path, model, {"kind": "stage1", "step": 2})
    second = _checkpoint_folder(tmp_path)
    assert second.name.startswith("ckpt-00000002-") and not first.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["latest.json", second.name])
    assert torch.equal(load_checkpoint(tmp_path, "stage1")[0]["0.weight"], model[0].weight)


def test_the_best_weights_travel_with_their_checkpoint_and_the_next_save_drops_them(tmp_path):
    model = _model()
    best = {k: v.clone() for k, v in model.state_dict().items()}
    with torch.no_grad():
        model[0].weight.add_(1.0)
    save_checkpoint(tmp_path, model, {"kind": "stage1", "step": 5}, best=best)
    assert torch.equal(load_checkpoint(tmp_path, "stage1")[0]["0.weight"], model[0].weight)
    assert torch.equal(load_checkpoint(tmp_path, "stage1", best=True)[0]["0.weight"], best["0.weight"])
    save_checkpoint(tmp_path, model, {"kind": "stage1", "step": 6})  # the latest weights are the best again
    assert torch.equal(load_checkpoint(tmp_path, "stage1", best=True)[0]["0.weight"], model[0].weight)


def test_runs_saved_before_checkpoint_folders_still_load(tmp_path):
    """The earlier layout: latest.safetensors (+ latest.training.pt) beside latest.json, tied by save_id."""
    model = _model()
    save_file({k: v.contiguous() for k, v in model.state_dict().items()}, str(tmp_path / "latest.safetensors"),
              metadata={"save_id": "abc"})
    torch.save({"save_id": "abc", "state": {"position": 4}}, tmp_path / "latest.training.pt")
    (tmp_path / "latest.json").write_text(json.dumps({"kind": "stage1", "save_id": "abc"}))
    state, meta = load_checkpoint(tmp_path, "stage1")
    assert torch.equal(state["0.weight"], model[0].weight)
    assert load_training_state(tmp_path, meta) == {"position": 4}
    save_checkpoint(tmp_path, model, {"kind": "stage1"})  # moves the run to the folder layout
    assert not (tmp_path / "latest.safetensors").exists() and not (tmp_path / "latest.training.pt").exists()
    assert torch.equal(load_checkpoint(tmp_path, "stage1")[0]["0.weight"], model[0].weight)


class _RunsCode:
    """Pickles as a call of os.system: a malicious training state."""

    def __reduce__(self):
        return (os.system, ("echo pwned",))


@pytest.mark.parametrize("content", ["random bytes", "code", "a list", "no state"])
def test_a_training_state_that_is_not_ours_is_refused_in_one_sentence(tmp_path, content):
    save_checkpoint(tmp_path, _model(), {"kind": "stage1"}, {"position": 1})
    meta = load_meta(tmp_path, "stage1")
    path = tmp_path / meta["checkpoint"] / "training.pt"
    if content == "random bytes":
        path.write_bytes(np.random.default_rng(0).bytes(4096))
    elif content == "code":
        path.write_bytes(pickle.dumps(_RunsCode(), protocol=2))
    else:
        torch.save([1, 2] if content == "a list" else {"save_id": meta["save_id"]}, path)
    with pytest.raises(DancesynthError, match="is not a training state this program wrote"):
        load_training_state(tmp_path, meta)
