import dataclasses

import numpy as np
import pytest
import torch

from dancesynth.core.errors import DancesynthError
from dancesynth.core.runs import RunFolder
from dancesynth.core.skeleton import PoseSequence
from stage1_pose.style_classifier import (
    KIND,
    PRESETS,
    classifier_accuracy,
    load_style_classifier,
    train_style_classifier,
)

CPU = torch.device("cpu")


@pytest.fixture(autouse=True, scope="module")
def one_torch_thread():
    # Tiny LSTMs: thread synchronisation costs more than it saves (60x slower with 2 threads on a loaded 2-core box).
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)

STANDING = np.array([[640, 200], [640, 250], [600, 250], [580, 320], [570, 380], [680, 250], [700, 320],
                     [710, 380], [640, 400], [615, 400], [610, 500], [605, 600], [665, 400], [670, 500],
                     [675, 600], [630, 190], [650, 190], [620, 195], [660, 195], [690, 610], [700, 610],
                     [670, 605], [590, 610], [580, 610], [610, 605]], np.float32)


def toy_dance(style: int, seed: int, frames: int = 90) -> PoseSequence:
    """Style 0 waves the arms slowly, 1 bounces the whole body fast, 2 sways sideways."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / 15.0
    phase = rng.uniform(0, 2 * np.pi)
    amp = rng.uniform(0.8, 1.2)
    xy = np.repeat(STANDING[None], frames, axis=0).copy()
    if style == 0:
        xy[:, [3, 4, 6, 7], 1] -= 60 * amp * np.sin(2 * np.pi * 0.5 * t + phase)[:, None]
    elif style == 1:
        xy[:, :, 1] += 25 * amp * np.sin(2 * np.pi * 2.5 * t + phase)[:, None]
    else:
        xy[:, :, 0] += 50 * amp * np.sin(2 * np.pi * 1.0 * t + phase)[:, None]
    xy += rng.normal(scale=1.0, size=xy.shape)
    kp = np.concatenate([xy, np.ones((frames, 25, 1), np.float32)], axis=-1)
    return PoseSequence(kp, 15.0, 1280, 720)


def test_classifier_learns_separable_toy_styles_and_round_trips(tmp_path):
    styles = ["wave", "bounce", "sway"]
    train = [(toy_dance(s, seed), s) for seed in range(8) for s in range(3)]
    test = [(toy_dance(s, 100 + seed), s) for seed in range(4) for s in range(3)]
    clf = train_style_classifier([d for d, _ in train], [y for _, y in train], styles, PRESETS["small"], CPU,
                                 RunFolder(tmp_path / "clf", KIND, CPU))
    acc = classifier_accuracy(clf, [d for d, _ in test], [y for _, y in test])
    assert acc >= 0.9

    pred, feature, windows = clf.embed(test[0][0])
    assert feature.shape == (PRESETS["small"].hidden,)
    assert windows.shape == (90 // PRESETS["small"].window_frames, PRESETS["small"].hidden)

    again = load_style_classifier(tmp_path / "clf", CPU)
    assert again.styles == styles
    np.testing.assert_allclose(again.embed(test[0][0])[1], feature, rtol=1e-5, atol=1e-6)


def test_too_short_dance_is_a_user_error(tmp_path):
    config = dataclasses.replace(PRESETS["small"], steps=1)
    clf = train_style_classifier([toy_dance(0, 0)], [0], ["a"], config, CPU, RunFolder(tmp_path, KIND, CPU))
    with pytest.raises(DancesynthError, match="shorter than the style classifier's window"):
        clf.embed(toy_dance(0, 1, frames=10))


def test_loading_a_wrong_folder_is_a_user_error(tmp_path):
    with pytest.raises(DancesynthError):
        load_style_classifier(tmp_path / "missing", torch.device("cpu"))


class Crash(BaseException):
    """Stands for the process dying mid-training: nothing on the way handles it."""


def test_interrupted_training_resumes_bit_exactly(tmp_path, monkeypatch):
    from dancesynth.core.checkpoint import load_checkpoint, load_meta
    from stage1_pose.style_classifier import StyleClassifier

    dances = [toy_dance(s, seed) for seed in range(2) for s in range(3)]
    labels = [s for _ in range(2) for s in range(3)]
    config = dataclasses.replace(PRESETS["small"], steps=7)

    def train(out, resume=False):
        return train_style_classifier(dances, labels, ["a", "b", "c"], config, CPU,
                                      RunFolder(out, KIND, CPU, resume=resume), checkpoint_every=3)

    train(tmp_path / "straight")
    real_forward, calls = StyleClassifier.forward, []

    def forward_then_die(self, x):
        calls.append(1)
        if len(calls) == 5:  # step 5: the checkpoint of step 3 is on disk
            raise Crash
        return real_forward(self, x)

    monkeypatch.setattr(StyleClassifier, "forward", forward_then_die)
    with pytest.raises(Crash):
        train(tmp_path / "killed")
    monkeypatch.undo()
    assert load_meta(tmp_path / "killed", KIND)["step"] == 3
    with pytest.raises(DancesynthError, match="--resume"):
        train(tmp_path / "killed")
    clf = train(tmp_path / "killed", resume=True)
    a, b = load_checkpoint(tmp_path / "straight", KIND)[0], load_checkpoint(tmp_path / "killed", KIND)[0]
    for k in a:
        assert torch.equal(a[k], b[k]), k
        assert torch.equal(clf.model.state_dict()[k], a[k]), k
    csv = (tmp_path / "killed" / "metrics.csv").read_text()
    assert csv == (tmp_path / "straight" / "metrics.csv").read_text()
    assert [line.split(",")[0] for line in csv.splitlines()] == ["step", "3", "6", "7"]


def test_train_style_classifier_command_resumes_to_more_steps(tiny_stage1_dataset, tmp_path):
    from apps.cli import main
    from dancesynth.core.checkpoint import load_meta

    args = ["train-style-classifier", "--data", str(tiny_stage1_dataset), "--out", str(tmp_path / "clf"),
            "--preset", "small", "--device", "cpu"]
    assert main([*args, "--steps", "2"]) == 0
    assert main([*args, "--steps", "4"]) == 1  # the folder holds a model: continuing it needs --resume
    assert main([*args, "--steps", "4", "--resume"]) == 0
    meta = load_meta(tmp_path / "clf", "style_classifier")
    assert meta["step"] == 4 and meta["config"]["steps"] == 4 and "test_accuracy" in meta
    assert load_style_classifier(tmp_path / "clf", torch.device("cpu")).styles == ["hiphop"]
