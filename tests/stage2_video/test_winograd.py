import pytest
import torch
from torch import nn

from stage2_video.models.pix2pixhd import Pix2PixHD, ResnetBlock, generator_channels, preset
from stage2_video.render import OpenVINOGenerator
from stage2_video.winograd import WinogradConv3x3, WinogradResnetStack, winograd_generator


def _randomise(module: nn.Module) -> nn.Module:
    torch.manual_seed(0)
    for p in module.parameters():
        nn.init.normal_(p, std=0.2)
    return module.eval()


def test_winograd_convolution_equals_padded_direct_convolution():
    conv = _randomise(nn.Conv2d(5, 7, 3))
    x = torch.randn(1, 5, 12, 8)
    with torch.no_grad():
        ref = conv(nn.functional.pad(x, (1, 1, 1, 1), mode="reflect"))
        out = WinogradConv3x3(conv, 12, 8)(x.reshape(5, 96).t())
    assert torch.allclose(out.t().reshape(1, 7, 12, 8), ref, atol=1e-4 * ref.abs().max())


def test_winograd_stack_computes_the_same_residual_blocks():
    blocks = [_randomise(ResnetBlock(16)) for _ in range(3)]
    x = torch.randn(1, 16, 8, 20)
    with torch.no_grad():
        ref = nn.Sequential(*blocks)(x)
        out = WinogradResnetStack(blocks, 8, 20)(x)
    assert torch.allclose(out, ref, atol=1e-4 * ref.abs().max())


@pytest.mark.parametrize("size, rewritten", [(64, True), (40, False)])
def test_generator_rewrite_keeps_the_output(size, rewritten):
    config = preset("small", width=size, height=size, ngf=4, n_downsample=2, n_blocks=2)
    generator = _randomise(Pix2PixHD(config).generator)
    fast = winograd_generator(generator, generator_channels(config), size, size, min_channels=1)
    # 64 px -> 16 px blocks (tiles of 4 fit); 40 px -> 10 px blocks stay direct.
    assert any(isinstance(m, WinogradResnetStack) for m in fast.modules()) == rewritten
    assert any(isinstance(m, ResnetBlock) for m in fast.modules()) != rewritten
    x = torch.rand(1, generator_channels(config), size, size) * 2 - 1
    with torch.no_grad():
        assert torch.allclose(fast(x), generator(x), atol=1e-4)


def test_narrow_blocks_stay_direct_by_default():
    config = preset("small", width=32, height=32, ngf=4, n_downsample=1, n_blocks=1)
    fast = winograd_generator(Pix2PixHD(config).generator, generator_channels(config), 32, 32)
    assert not any(isinstance(m, WinogradResnetStack) for m in fast.modules())


@pytest.mark.parametrize("blend", [False, True])
def test_openvino_renderer_with_winograd_blocks_matches_plain_forward(blend):
    config = preset("small", width=32, height=32, ngf=16, n_downsample=3, n_blocks=2, background=blend, blend=blend,
                    prior=False)
    generator = _randomise(Pix2PixHD(config).generator)
    channels = generator_channels(config)
    assert any(isinstance(m, WinogradResnetStack) for m in winograd_generator(generator, channels, 32, 32).modules())
    x = torch.rand(1, channels, 32, 32) * 2 - 1
    with torch.no_grad():
        assert torch.allclose(OpenVINOGenerator(generator, channels, 32, 32)(x), generator(x), atol=1e-4)


def test_blocks_over_the_weight_budget_stay_direct():
    config = preset("small", width=32, height=32, ngf=4, n_downsample=1, n_blocks=1)
    generator = Pix2PixHD(config).generator.eval()
    fast = winograd_generator(generator, generator_channels(config), 32, 32, max_weight_bytes=0, min_channels=1)
    assert not any(isinstance(m, WinogradResnetStack) for m in fast.modules())


def test_local_enhancer_blocks_are_rewritten_too():
    config = preset("paper", width=64, height=32, ngf=4, n_downsample=1, n_blocks=2, n_blocks_local=1)
    generator = _randomise(Pix2PixHD(config).generator)
    fast = winograd_generator(generator, 6, 64, 32, min_channels=1)
    assert sum(isinstance(m, WinogradResnetStack) for m in fast.modules()) == 2
    x = torch.rand(1, 6, 32, 64) * 2 - 1
    with torch.no_grad():
        assert torch.allclose(fast(x), generator(x), atol=1e-4)
