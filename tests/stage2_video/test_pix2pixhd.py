import pytest
import torch

from dancesynth.core.errors import DancesynthError
from stage2_video.models.pix2pixhd import (
    LocalEnhancer,
    Pix2PixHD,
    Pix2PixHDConfig,
    carry_correction,
    condition_channels,
    feature_matching_loss,
    foreground_target,
    lsgan_loss,
    preset,
)
from stage2_video.vgg import NOTICE, VGGLoss, build_vgg_loss


def _tiny(**kw):
    """pix2pixHD from label maps alone unless told otherwise (the seed's network, as the paper preset has it)."""
    return Pix2PixHDConfig(width=32, height=32, ngf=4, n_downsample=2, n_blocks=1, ndf=4, **kw)


@pytest.mark.parametrize("local", [False, True])
@pytest.mark.parametrize("background", [False, True])
def test_generator_and_discriminator_shapes(local, background):
    cfg = _tiny(local_enhancer=local, background=background)
    model = Pix2PixHD(cfg)
    assert isinstance(model.generator, LocalEnhancer) == local
    # The condition: a label map, + the background's crop.
    label = torch.rand(2, condition_channels(cfg), 32, 32) * 2 - 1
    assert label.shape[1] == (6 if background else 3)
    frame = model.generate(label)
    assert frame.shape == (2, 3, 32, 32) and frame.abs().max() <= 1
    assert model.generate(label, frame).shape == frame.shape
    spatial = model.discriminator(torch.cat([label, frame], 1))
    assert len(spatial) == cfg.num_d and len(spatial[0]) == cfg.n_layers_d + 2
    assert spatial[0][-1].shape[1] == 1
    temporal = model.temporal_discriminator(torch.cat([label, label, frame, frame], 1))
    assert len(temporal) == cfg.num_d


@pytest.mark.parametrize("local", [False, True])
def test_blend_paints_over_the_background_crop(local):
    cfg = _tiny(local_enhancer=local, background=True, blend=True)
    model = Pix2PixHD(cfg)
    label = torch.rand(2, condition_channels(cfg), 32, 32) * 2 - 1
    plate = label[:, 3:6]
    # Untrained, the frame is mostly the plate: training starts from the scene, not from noise.
    assert (model.generate(label) - plate).abs().mean() < 0.3 * plate.abs().mean()
    with torch.no_grad():
        model.generator.inner.output_conv.bias[3] = -30.0  # mask shut: the plate exactly, whatever the skeleton
    assert torch.allclose(model.generate(label), plate, atol=1e-5)


def test_blend_needs_the_background():
    with pytest.raises(DancesynthError, match="background"):
        _tiny(blend=True)
    with pytest.raises(DancesynthError, match="blend"):
        _tiny(background=True, prior=True)


def test_the_prior_model_paints_over_the_warped_person_not_the_plate():
    cfg = _tiny(background=True, blend=True, prior=True)
    assert preset("small").prior and preset("medium").prior and not preset("paper").prior
    model = Pix2PixHD(cfg)
    # label map, plate crop, warped person over the plate, its alpha
    label = torch.rand(2, condition_channels(cfg), 32, 32) * 2 - 1
    assert label.shape[1] == 10
    with torch.no_grad():
        model.generator.inner.output_conv.bias[3] = -30.0  # mask shut: what it paints over, exactly
    assert torch.allclose(model.generate(label), label[:, 6:9], atol=1e-5)
    real = label[:, 6:9].clone()
    real[:, :, :4] = -real[:, :, :4]  # the warp is wrong in the top rows only
    label[:, :3] = 1.0  # the skeleton is drawn everywhere
    wrong = foreground_target(label, real, prior=True)[:, 0]
    assert wrong[:, :4].mean() > 0.5 and wrong[:, 4:].sum() == 0


def test_a_residual_model_starts_at_the_prior_and_learns_a_correction():
    cfg = _tiny(background=True, blend=True, prior=True, residual=True, lambda_mask=0.0)
    assert cfg.repairs and preset("small").repairs and preset("medium").repairs
    model = Pix2PixHD(cfg)
    label = torch.rand(2, condition_channels(cfg), 32, 32) * 2 - 1
    prior = label[:, 6:9]
    assert torch.equal(model.generate(label), prior)  # untrained: the warp itself, not a blend with noise
    real = prior.clone()
    real[:, :, :8] = -1.0  # the warp is wrong in the top rows: they should be black
    optimizer = torch.optim.Adam(model.generator.parameters(), lr=1e-2)
    errors = []
    for _ in range(30):
        loss = (model.generate(label) - real).abs().mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        errors.append(loss.item())
    assert errors[-1] < 0.8 * errors[0]
    with pytest.raises(DancesynthError, match="lambda_mask"):
        _tiny(background=True, blend=True, prior=True, residual=True)


def test_a_correction_is_carried_onto_the_prior_at_the_output_size():
    base_high = torch.rand(1, 3, 64, 64) * 2 - 1
    base = torch.nn.functional.interpolate(base_high, size=(32, 32), mode="area")
    assert torch.equal(carry_correction(base, base, base_high), base_high)  # no correction: the prior's detail
    frame = base.clone()
    frame[:, 0] += 0.5  # redder everywhere at the model's size
    high = carry_correction(frame, base, base_high)
    assert torch.allclose(high[:, 0], base_high[:, 0] + 0.5, atol=1e-6)
    assert torch.allclose(high[:, 1:], base_high[:, 1:], atol=1e-6)

def test_size_must_divide_by_downsampling():
    with pytest.raises(DancesynthError, match="divisible by 8"):
        preset("small", width=100, height=128)
    with pytest.raises(DancesynthError, match="Unknown preset"):
        preset("huge")
    with pytest.raises(DancesynthError, match="odd count"):
        preset("small", prior_candidates=2)


def test_paper_preset_is_published_pix2pixhd():
    cfg = preset("paper")
    assert cfg.local_enhancer and cfg.n_downsample == 4 and cfg.n_blocks == 9 and cfg.ngf * 2 == 64
    assert (cfg.ndf, cfg.n_layers_d, cfg.num_d, cfg.lambda_feat, cfg.lambda_vgg) == (64, 3, 2, 10.0, 10.0)


def test_lsgan_and_feature_matching_losses():
    real = [[torch.ones(1, 2, 4, 4), torch.ones(1, 1, 3, 3)] for _ in range(2)]
    fake = [[torch.zeros(1, 2, 4, 4), torch.zeros(1, 1, 3, 3)] for _ in range(2)]
    assert lsgan_loss(real, True).item() == 0.0
    assert lsgan_loss(fake, True).item() == pytest.approx(1.0)
    assert lsgan_loss(fake, False).item() == 0.0
    # one intermediate layer per scale, |diff| = 1: 2 scales * (4 / (3 + 1)) * (1 / 2) * 1 * lambda 10 = 10
    assert feature_matching_loss(fake, real, n_layers=3, weight=10.0).item() == pytest.approx(10.0)
    assert feature_matching_loss(real, real, n_layers=3, weight=10.0).item() == 0.0


def test_vgg_off_with_visible_notice(caplog, monkeypatch):
    import stage2_video.vgg as vgg
    monkeypatch.setattr(vgg, "_notice_shown", False)
    assert build_vgg_loss(None) is None
    assert build_vgg_loss(None) is None
    assert [r.getMessage() for r in caplog.records if r.levelname == "WARNING"].count(NOTICE) == 1


def test_vgg_loads_local_weights(tmp_path):
    from torchvision.models.vgg import cfgs, make_layers
    path = tmp_path / "vgg19.pth"
    torch.save({f"features.{k}": v for k, v in make_layers(cfgs["E"]).state_dict().items()}, path)
    loss = build_vgg_loss(path)
    assert isinstance(loss, VGGLoss)
    x = torch.rand(1, 3, 32, 32) * 2 - 1
    assert loss(x, x).item() == 0.0
    assert loss(x, -x).item() > 0
    with pytest.raises(DancesynthError, match="does not exist"):
        build_vgg_loss(tmp_path / "missing.pth")


def test_256_px_where_the_hardware_affords_it(monkeypatch):
    from stage2_video.models import pix2pixhd

    cpu, gpu = torch.device("cpu"), torch.device("cuda")
    for amx, precision, expected in ((True, torch.bfloat16, "medium"), (True, torch.float32, "small"),
                                     (False, torch.bfloat16, "small"), (False, torch.float32, "small")):
        monkeypatch.setattr(pix2pixhd, "cpu_has_amx", lambda amx=amx: amx)
        assert pix2pixhd.affordable_preset(cpu, precision) == expected, (amx, precision)
    assert pix2pixhd.affordable_preset(gpu, torch.float16) == "medium"


def test_the_foreground_is_where_the_frame_leaves_the_plate_near_the_skeleton():
    plate = torch.full((1, 3, 64, 64), -0.5)
    label = torch.full((1, 3, 64, 64), -1.0)
    label[0, :, 20:40, 30] = 1.0  # a drawn limb
    real = plate.clone()
    real[0, :, 18:42, 27:34] = 0.4  # the person around it
    real[0, :, 2:6, 2:6] = 0.4  # the scene changes far from the skeleton (a leaf)
    real[0, :, 50:60, 28:32] -= 0.1  # a change below the threshold (noise, the plate's error)
    target = foreground_target(torch.cat([label, plate], 1), real)
    assert target.shape == (1, 1, 64, 64)
    assert target[0, 0, 18:42, 27:34].all()
    assert target.sum() == 24 * 7
