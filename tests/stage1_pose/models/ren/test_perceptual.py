import pytest
import torch

from dancesynth.core.errors import DancesynthError
from stage1_pose.models.ren.perceptual import PosePerceptualLoss, load_stgcn
from stage1_pose.models.ren.stgcn import STGCN, STGCNConfig

WEIGHTS = (20.0, 5.0, 1.0, 1.0)


def small_net() -> STGCN:
    torch.manual_seed(0)
    net = STGCN(STGCNConfig.preset("small"))
    net.train()
    # A few forward passes give the batch norms non-trivial statistics, as training would.
    for _ in range(3):
        net(torch.randn(4, 12, 25, 2))
    return net


def test_perceptual_loss_zero_for_identical_positive_otherwise():
    loss = PosePerceptualLoss(small_net(), WEIGHTS)
    real = torch.randn(2, 12, 25, 2)
    assert loss(real, real.clone()).item() == 0.0
    assert loss(real, real + 0.1 * torch.randn_like(real)).item() > 0.0


def test_perceptual_loss_trains_the_generator_not_the_network():
    net = small_net()
    loss = PosePerceptualLoss(net, WEIGHTS)
    assert not net.training and not any(p.requires_grad for p in net.parameters())
    fake = torch.randn(1, 12, 25, 2, requires_grad=True)
    loss(torch.randn(1, 12, 25, 2), fake).backward()
    assert fake.grad is not None and fake.grad.abs().sum() > 0
    assert all(p.grad is None for p in net.parameters())


def test_layer_weights_must_cover_every_block():
    with pytest.raises(DancesynthError, match="one weight per block"):
        PosePerceptualLoss(small_net(), (20.0, 5.0))


def test_missing_stgcn_run_says_what_to_do():
    with pytest.raises(DancesynthError, match="train-stgcn"):
        load_stgcn("")


def _tiny_dataset(root, seconds: float = 6.0, fps: int = 15, sr: int = 8000):
    """3 styles whose dances differ in tempo and which joints move; 3 train songs and 1 val song each."""
    import numpy as np
    import soundfile as sf

    from dancesynth.core.skeleton import NECK, ROOT, PoseSequence
    from stage1_pose.data.dataset import Clip, clip_paths, create_layout, write_beats, write_manifest

    create_layout(root)
    rng = np.random.default_rng(0)
    base = np.stack([640 + rng.uniform(-60, 60, 25), 360 + rng.uniform(-150, 150, 25)], axis=1)
    base[NECK], base[ROOT] = (640, 300), (640, 420)
    styles = ("slow", "fast", "legs")
    t = np.arange(int(seconds * fps)) / fps
    clips = []
    for s, style in enumerate(styles):
        moving = np.arange(25) % 3 == s
        for n, split in enumerate(("train", "train", "train", "val")):
            cid = f"{style}{n}"
            phase = rng.uniform(0, 6.28)
            xy = np.repeat(base[None], len(t), axis=0)
            xy[:, moving, 1] += 40 * np.sin(2 * np.pi * (0.5 + s) * t + phase)[:, None]
            kp = np.concatenate([xy, np.ones((len(t), 25, 1))], axis=-1)
            paths = clip_paths(cid)
            PoseSequence(kp, fps, 1280, 720).save(root / paths["poses"])
            sf.write(root / paths["audio"], 0.1 * rng.standard_normal(int(seconds * sr)).astype("float32"), sr)
            write_beats(root / paths["beats"], np.arange(0, seconds, 0.5), np.arange(0, seconds, 2.0), 120.0, "exact")
            clips.append(Clip(id=cid, song=cid, style=style, split=split, **paths))
    write_manifest(root, fps, sr, styles, clips)
    return root


def test_train_stgcn_command_saves_a_loadable_frozen_classifier(tmp_path):
    from dataclasses import replace

    from apps.cli import main
    from dancesynth.core.checkpoint import load_meta
    from stage1_pose.models.ren.model import RenConfig, RenMethod

    data = _tiny_dataset(tmp_path / "data")
    run = tmp_path / "stgcn"
    assert main(["train-stgcn", "--data", str(data), "--out", str(run), "--epochs", "40", "--quiet"]) == 0
    meta = load_meta(run, "stgcn")
    assert meta["styles"] == ["slow", "fast", "legs"] and meta["config"]["num_classes"] == 3
    assert meta["train_accuracy"] > 0.6  # chance is 1/3: the network learned the styles
    net = load_stgcn(run)
    assert not net.training and not any(p.requires_grad for p in net.parameters())
    cfg = replace(RenConfig.preset("small"), stgcn_run=str(run))
    method = RenMethod(cfg)
    method.configure_optimizers()
    assert method.perceptual is not None and "perceptual" not in " ".join(method.state_dict())


def test_train_stgcn_rejects_unknown_preset(tmp_path):
    from stage1_pose.models.ren.perceptual import train_stgcn

    with pytest.raises(DancesynthError, match="Unknown ST-GCN preset"):
        train_stgcn(tmp_path, tmp_path / "run", preset="giant")


class Crash(BaseException):
    """Stands for the process dying mid-training: nothing on the way handles it."""


def test_interrupted_stgcn_training_resumes_bit_exactly(tmp_path, monkeypatch):
    from apps.cli import main
    from dancesynth.core.checkpoint import load_checkpoint, load_meta
    from stage1_pose.models.ren import perceptual

    data = _tiny_dataset(tmp_path / "data")
    straight, killed = tmp_path / "straight", tmp_path / "killed"
    expected = perceptual.train_stgcn(data, straight, epochs=3, device="cpu", progress=False)
    real_augment, calls = perceptual._augment, []

    def augment_then_die(*args):
        calls.append(1)
        if len(calls) == 4:  # second batch of the second epoch: the first epoch's checkpoint is on disk
            raise Crash
        return real_augment(*args)

    monkeypatch.setattr(perceptual, "_augment", augment_then_die)
    with pytest.raises(Crash):
        perceptual.train_stgcn(data, killed, epochs=3, device="cpu", progress=False)
    monkeypatch.undo()
    assert load_meta(killed, "stgcn")["epoch"] == 1
    assert main(["train-stgcn", "--data", str(data), "--out", str(killed), "--device", "cpu"]) == 1  # needs --resume
    assert main(["train-stgcn", "--data", str(data), "--out", str(killed), "--device", "cpu", "--resume"]) == 0
    (a, meta_a), (b, meta_b) = load_checkpoint(straight, "stgcn"), load_checkpoint(killed, "stgcn")
    for k in a:
        assert torch.equal(a[k], b[k]), k
    assert meta_b["epoch"] == 3 and meta_b["train_accuracy"] == meta_a["train_accuracy"] == expected["train_accuracy"]
    assert (killed / "metrics.csv").read_text() == (straight / "metrics.csv").read_text()
