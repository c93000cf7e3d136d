"""pix2pixHD's VGG19 perceptual loss, with ImageNet weights from a file the user supplies.

Nothing is downloaded: without a weights file the loss is switched off and a notice says so (once per process).
"""

from __future__ import annotations

import logging
from pathlib import Path

import torch
import torch.nn.functional as F
from torch import nn

from dancesynth.core.errors import DancesynthError

logger = logging.getLogger(__name__)

# torchvision vgg19.features indices ending at relu1_1, relu2_1, relu3_1, relu4_1, relu5_1, and pix2pixHD's weights.
SLICE_ENDS = (2, 7, 12, 21, 30)
LAYER_WEIGHTS = (1.0 / 32, 1.0 / 16, 1.0 / 8, 1.0 / 4, 1.0)
IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)

NOTICE = ("VGG perceptual loss is OFF (no --vgg-weights file given). pix2pixHD uses it with weight 10; "
          "to turn it on pass a local torchvision vgg19 ImageNet state dict (.pth or .safetensors).")
_notice_shown = False


def _load_state_dict(path: Path) -> dict[str, torch.Tensor]:
    if not path.is_file():
        raise DancesynthError(f"VGG weights file {path} does not exist; check --vgg-weights.")
    try:
        if path.suffix == ".safetensors":
            from safetensors.torch import load_file
            return load_file(str(path))
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # noqa: BLE001 - any unreadable file is the same user error
        raise DancesynthError(f"Could not read VGG weights from {path} ({e}); pass a vgg19 state dict "
                              "saved with torch.save or safetensors.") from e
    if not isinstance(state, dict):
        raise DancesynthError(f"{path} does not hold a state dict; pass torchvision vgg19 weights.")
    return state


class VGGLoss(nn.Module):
    """Weighted L1 distance between VGG19 activations of two ``[B, 3, H, W]`` images in [-1, 1]. Frozen."""

    def __init__(self, state_dict: dict[str, torch.Tensor]) -> None:
        super().__init__()
        # Imported here: torchvision takes a second and a half to import, and the loss is off unless weights are given.
        from torchvision.models.vgg import cfgs, make_layers

        # vgg19's `features` (config "E") without building its 120M-parameter classifier.
        features = make_layers(cfgs["E"])
        # Accept a full vgg19 state dict or just its `features` part.
        sub = {k.removeprefix("features."): v for k, v in state_dict.items() if not k.startswith("classifier.")}
        try:
            features.load_state_dict({k: v for k, v in sub.items() if int(k.split(".")[0]) < SLICE_ENDS[-1]},
                                     strict=False)
            missing = [k for k in features.state_dict() if int(k.split(".")[0]) < SLICE_ENDS[-1] and k not in sub]
        except (RuntimeError, ValueError) as e:
            raise DancesynthError(f"The VGG weights do not match torchvision's vgg19 ({e}); pass vgg19 weights.") from e
        if missing:
            raise DancesynthError(f"The VGG weights lack {missing[0]}; pass a complete torchvision vgg19 state dict.")
        starts = (0,) + SLICE_ENDS[:-1]
        self.slices = nn.ModuleList(features[a:b] for a, b in zip(starts, SLICE_ENDS))
        self.register_buffer("mean", torch.tensor(IMAGENET_MEAN).view(1, 3, 1, 1))
        self.register_buffer("std", torch.tensor(IMAGENET_STD).view(1, 3, 1, 1))
        self.requires_grad_(False)
        self.eval()

    def forward(self, fake: torch.Tensor, real: torch.Tensor) -> torch.Tensor:
        x = ((torch.cat([fake, real]) + 1) / 2 - self.mean) / self.std
        loss = fake.new_zeros(())
        for weight, block in zip(LAYER_WEIGHTS, self.slices):
            x = block(x)
            f, r = x.chunk(2)
            loss = loss + weight * F.l1_loss(f, r.detach())
        return loss


def build_vgg_loss(weights_path: str | Path | None) -> VGGLoss | None:
    """The VGG loss from a local weights file, or None (after logging :data:`NOTICE` once) when no file is given."""
    global _notice_shown
    if weights_path is None:
        if not _notice_shown:
            logger.warning(NOTICE)
            _notice_shown = True
        return None
    return VGGLoss(_load_state_dict(Path(weights_path)))
