"""Quality of generated frames: image similarity to held-out real frames and pose consistency.

* SSIM and PSNR (dB) between a generated and the real frame (``skimage.metrics``, data range 255, RGB).
* PCK@alpha: share of the commanded pose's visible joints that the pose re-extracted from the generated frame
  puts within ``alpha`` x torso size (Neck-MidHip distance of the commanded pose, per frame); joints the
  extractor misses count as wrong.
"""

from __future__ import annotations

import numpy as np
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

from dancesynth.core.skeleton import NECK, ROOT, PoseSequence

MIN_CONFIDENCE = 0.05


def ssim(generated: np.ndarray, real: np.ndarray) -> float:
    """SSIM of two ``[H, W, 3]`` uint8 images (1 = identical)."""
    return float(structural_similarity(generated, real, channel_axis=2, data_range=255))


def psnr(generated: np.ndarray, real: np.ndarray) -> float:
    """PSNR in dB of two ``[H, W, 3]`` uint8 images (capped at 100 for identical images)."""
    if np.array_equal(generated, real):
        return 100.0
    return float(peak_signal_noise_ratio(real, generated, data_range=255))


def pck(predicted: PoseSequence, commanded: PoseSequence, alpha: float = 0.1) -> float:
    """PCK@alpha of ``predicted`` against ``commanded`` (same canvas and frame count); NaN if nothing to score."""
    if len(predicted) != len(commanded):
        raise ValueError(f"frame counts differ: {len(predicted)} vs {len(commanded)}")
    ref = commanded.keypoints
    torso = np.linalg.norm(ref[:, NECK, :2] - ref[:, ROOT, :2], axis=-1)
    scored = (ref[..., 2] >= MIN_CONFIDENCE) & (torso[:, None] > 0)
    dist = np.linalg.norm(predicted.xy - commanded.xy, axis=-1)
    hit = (dist <= alpha * torso[:, None]) & (predicted.confidence >= MIN_CONFIDENCE)
    return float(hit[scored].mean()) if scored.any() else float("nan")
