"""The trainer protocol (:meth:`dancesynth.core.runs.RunFolder.training`), held by all four trainers: Ctrl-C or
SIGTERM during step N saves a checkpoint of step N and raises KeyboardInterrupt; ``--minutes`` counts the run's
time in all, so a resumed run whose budget is spent takes no step; ``--resume`` ends with the weights of an
uninterrupted run.

The signal is simulated: the handler the protocol installed is called as the signal's arrival would call it, at the
end of step N. A real signal sent to the test process could land in native libraries other tests loaded there;
tests/core/test_interrupts.py sends real ones, in a fresh process.
"""

import csv
import signal
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest
import torch

from dancesynth.core.checkpoint import load_checkpoint, load_meta
from dancesynth.core.runs import RunFolder, TrainingSession
from stage1_pose.models.ren.perceptual import train_stgcn
from stage1_pose.style_classifier import train_on_dataset
from stage1_pose.train import TrainerConfig
from stage1_pose.train import train as train_pose
from stage2_video.train import TrainOptions, train_video

STOP_AT = 3  # inside the first or second epoch of every trainer below
# The stage-1 methods' loop, tried with the LSTM baseline's small preset at a tiny size.
TINY_LSTM = dict(hidden=16, layers=2, window_frames=30, batch_size=4, epoch_windows=0)


@dataclass(frozen=True)
class Inputs:
    data: Path  # a stage-1 dataset of two styles
    video: Path
    poses: Path
    appearance: dict  # config overrides of a tiny appearance model


@dataclass(frozen=True)
class Trainer:
    kind: str
    table: str  # its metrics table, one row per step, epoch or checkpoint interval
    # (inputs, run folder, resume, minutes) -> trains to the end, or raises KeyboardInterrupt
    train: Callable[[Inputs, Path, bool, float | None], object]


TRAINERS = {
    "train-pose": Trainer("stage1", "metrics", lambda i, out, resume, minutes: train_pose(
        "lstm", i.data, out, overrides=TINY_LSTM, epochs=2, resume=resume, device="cpu", minutes=minutes,
        options=TrainerConfig(preview_every=0))),
    "train-stgcn": Trainer("stgcn", "metrics", lambda i, out, resume, minutes: train_stgcn(
        i.data, out, "small", epochs=2, device="cpu", progress=False, resume=resume, minutes=minutes)),
    "train-style-classifier": Trainer("style_classifier", "metrics", lambda i, out, resume, minutes: train_on_dataset(
        i.data, out, "small", steps=6, minutes=minutes, device="cpu", resume=resume)),
    "train-video": Trainer("stage2", "losses", lambda i, out, resume, minutes: train_video(
        i.video, out, "small", TrainOptions(minutes=minutes, epochs=2, val_frames=2, sample_every=1000,
                                            checkpoint_every=1000),
        resume=resume, poses=i.poses, device="cpu", overrides=i.appearance)),
}


@pytest.fixture(scope="module")
def inputs(tiny_target, tiny_config, stage1_dataset_writer, tmp_path_factory) -> Inputs:
    # Six training clips: the ST-GCN's small preset gets two batches an epoch, so a stop can fall inside one.
    data = stage1_dataset_writer(tmp_path_factory.mktemp("protocol") / "data", ("train",) * 6 + ("val", "test"),
                                 styles=("hiphop", "salsa"), more_features=("waveform",))
    # pix2pixHD alone: the warped prior's person masks and plate would take most of the test's time.
    return Inputs(data, *tiny_target, {**tiny_config, "prior": False, "background": False, "blend": False})


def _signal_during_step(monkeypatch: pytest.MonkeyPatch, step: int, signum: int) -> None:
    real = TrainingSession.step_done

    def step_done(self: TrainingSession, done: int, **shown: object) -> bool:
        if done == step:
            signal.getsignal(signum)(signum, None)
        return real(self, done, **shown)

    monkeypatch.setattr(TrainingSession, "step_done", step_done)


def _steps(table: Path) -> list[str]:
    with open(table, newline="") as f:
        return [row["step"] for row in csv.DictReader(f)]


@pytest.mark.parametrize(("name", "signum"), [
    pytest.param("train-pose", signal.SIGINT, id="train-pose-SIGINT"),
    pytest.param("train-stgcn", signal.SIGTERM, id="train-stgcn-SIGTERM"),
    pytest.param("train-style-classifier", signal.SIGINT, id="train-style-classifier-SIGINT"),
    pytest.param("train-video", signal.SIGTERM, id="train-video-SIGTERM")])
def test_a_signal_saves_the_step_and_resume_ends_as_an_uninterrupted_run(inputs, tmp_path, monkeypatch, name,
                                                                        signum):
    trainer = TRAINERS[name]
    monkeypatch.setattr(RunFolder, "plot", lambda self, name: None)  # a second each, and no part of the protocol
    straight, stopped = tmp_path / "straight", tmp_path / "stopped"
    trainer.train(inputs, straight, False, None)

    handler = signal.getsignal(signum)
    with monkeypatch.context() as patched:
        _signal_during_step(patched, STOP_AT, signum)
        with pytest.raises(KeyboardInterrupt):
            trainer.train(inputs, stopped, False, None)
    assert signal.getsignal(signum) is handler, "the trainer gave the signal its handler back"
    saved = load_meta(stopped, trainer.kind)
    assert saved["step"] == STOP_AT and saved["trained_seconds"] >= 0

    # The budget is the run's time in all: spent already, so the resumed call takes no step.
    trainer.train(inputs, stopped, True, saved["trained_seconds"] / 60)
    assert load_meta(stopped, trainer.kind)["step"] == STOP_AT

    trainer.train(inputs, stopped, True, None)
    (a, meta_a), (b, meta_b) = load_checkpoint(straight, trainer.kind), load_checkpoint(stopped, trainer.kind)
    assert meta_b["step"] == meta_a["step"] > STOP_AT
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    assert _steps(stopped / f"{trainer.table}.csv") == _steps(straight / f"{trainer.table}.csv")
