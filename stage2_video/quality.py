"""Quality of generated frames: image similarity to held-out real frames and pose consistency.

* SSIM and PSNR (dB) between a generated and the real frame (``skimage.metrics``, data range 255, RGB), over the
  whole frame or inside the person's box (:func:`scoring_box`, :func:`box_scores`: what the real-footage benchmark
  reports and, on the prior-size crop before compositing, what the trainer selects checkpoints by).
* PCK@alpha: share of the commanded pose's visible joints that the pose re-extracted from the generated frame
  puts within ``alpha`` x torso size (Neck-MidHip distance of the commanded pose, per frame); joints the
  extractor misses count as wrong.
"""

from __future__ import annotations

import numpy as np
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

from dancesynth.core.skeleton import NECK, ROOT, PoseSequence

MIN_CONFIDENCE = 0.05
# The person's box: the pose's joints' box grown by this share of its longer side.
BOX_MARGIN = 0.15
# skimage's SSIM window (pixels): a smaller image has no SSIM.
SSIM_WINDOW = 7


def ssim(generated: np.ndarray, real: np.ndarray) -> float:
    """SSIM of two ``[H, W, 3]`` uint8 images (1 = identical)."""
    return float(structural_similarity(generated, real, channel_axis=2, data_range=255))


def psnr(generated: np.ndarray, real: np.ndarray) -> float:
    """PSNR in dB of two ``[H, W, 3]`` uint8 images (capped at 100 for identical images)."""
    if np.array_equal(generated, real):
        return 100.0
    return float(peak_signal_noise_ratio(real, generated, data_range=255))


def scoring_box(keypoints: np.ndarray, width: int, height: int) -> tuple[int, int, int, int]:
    """``(x0, y0, x1, y1)`` pixels: the box of one ``[25, 3]`` pose's joints (pixels of a ``width x height`` frame)
    grown by :data:`BOX_MARGIN` of its longer side, clipped to the frame; the whole frame without a joint or where
    the box inside the frame is narrower than SSIM's 7-pixel window."""
    seen = keypoints[:, 2] >= MIN_CONFIDENCE
    if not seen.any():
        return 0, 0, width, height
    lo, hi = keypoints[seen, :2].min(0), keypoints[seen, :2].max(0)
    grow = BOX_MARGIN * float((hi - lo).max())
    x0, y0 = (int(min(max(0, v - grow), limit)) for v, limit in zip(lo, (width, height)))
    x1, y1 = int(min(width, max(0, hi[0] + grow + 1))), int(min(height, max(0, hi[1] + grow + 1)))
    if x1 - x0 < SSIM_WINDOW or y1 - y0 < SSIM_WINDOW:
        return 0, 0, width, height
    return x0, y0, x1, y1


def box_scores(generated: np.ndarray, real: np.ndarray, keypoints: np.ndarray) -> tuple[float, float]:
    """(SSIM, PSNR dB) of two ``[H, W, 3]`` uint8 frames inside the :func:`scoring_box` of ``keypoints`` (the real
    frame's ``[25, 3]`` pose in its pixels)."""
    x0, y0, x1, y1 = scoring_box(keypoints, real.shape[1], real.shape[0])
    a, b = generated[y0:y1, x0:x1], real[y0:y1, x0:x1]
    return ssim(a, b), psnr(a, b)


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
