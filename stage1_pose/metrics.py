"""Stage-1 metrics of the three seed papers, as pure functions on arrays.

Feature-space metrics (FID, diversity, multimodality, cross-modal distance) take embeddings from the project's
style classifier (:mod:`stage1_pose.style_classifier`, a 200-d LSTM feature as in Dance Revolution). Beat
metrics take beat positions: music beats in seconds, kinematic beats as pose-frame indices (from
:mod:`dancesynth.core.motion`), so every metric here is independent of how beats were found.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg

from dancesynth.core.motion import DEFAULT_TOLERANCE_FRAMES, beats_aligned

# Bailando's Beat Align Score uses sigma = 3 frames at 60 fps, i.e. 50 ms.
DEFAULT_BAS_SIGMA_SECONDS = 0.05


def gaussian_fit(features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean ``[D]`` and covariance ``[D, D]`` (unbiased, N-1) of ``[N, D]`` features (N >= 2)."""
    f = np.asarray(features, dtype=np.float64)
    if f.ndim != 2 or f.shape[0] < 2:
        raise ValueError(f"need [N, D] features with N >= 2, got shape {f.shape}")
    return f.mean(axis=0), np.atleast_2d(np.cov(f, rowvar=False))


def _trace_sqrt_product(cov_a: np.ndarray, cov_b: np.ndarray) -> float:
    """``tr(sqrt(A B))`` for covariance matrices A, B.

    scipy's ``sqrtm`` first; when it returns non-finite values or a clearly complex result (A B nearly
    singular, common with fewer samples than dimensions) the symmetric form ``tr(sqrt(A^1/2 B A^1/2))``,
    which has the same trace and only needs eigen-decompositions of symmetric PSD matrices, is used instead.
    """
    with warnings.catch_warnings():
        # A singular product is expected here and handled by the fallback below.
        warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
        root = scipy.linalg.sqrtm(cov_a @ cov_b)
    if np.all(np.isfinite(root)) and np.abs(np.imag(root)).max(initial=0.0) <= 1e-3 * max(1.0, np.abs(root).max()):
        return float(np.real(np.trace(root)))
    w, v = np.linalg.eigh((cov_a + cov_a.T) / 2)
    half_a = (v * np.sqrt(np.clip(w, 0.0, None))) @ v.T
    inner = half_a @ cov_b @ half_a
    return float(np.sqrt(np.clip(np.linalg.eigvalsh((inner + inner.T) / 2), 0.0, None)).sum())


def frechet_distance(features_a: np.ndarray, features_b: np.ndarray) -> float:
    """FID: Fréchet distance between Gaussian fits of two feature sets ``[N, D]`` and ``[M, D]``.

    ``FID = ||mu_a - mu_b||^2 + tr(S_a + S_b - 2 (S_a S_b)^(1/2))``, in squared feature units; 0 for
    identical distributions. Small sets give a biased (too high) estimate, so compare rows computed with
    the same set sizes.
    """
    mu_a, cov_a = gaussian_fit(features_a)
    mu_b, cov_b = gaussian_fit(features_b)
    value = float(((mu_a - mu_b) ** 2).sum() + np.trace(cov_a) + np.trace(cov_b)
                  - 2.0 * _trace_sqrt_product(cov_a, cov_b))
    return max(value, 0.0)


def style_accuracy(predicted: np.ndarray, target: np.ndarray) -> float:
    """ACC: fraction of dances whose predicted style index equals the song's style, ``mean(pred == target)``."""
    predicted, target = np.asarray(predicted), np.asarray(target)
    if predicted.shape != target.shape or predicted.size == 0:
        raise ValueError(f"need two equal, non-empty label arrays, got {predicted.shape} and {target.shape}")
    return float((predicted == target).mean())


def beat_coverage(kinematic_frames: np.ndarray, music_frames: np.ndarray) -> float:
    """Beat coverage ``B_k / B_m`` (Lee et al. 2019): kinematic beats per music beat.

    ``B_k`` = number of kinematic beats, ``B_m`` = number of music beats (same stretch of time). 0 for a
    frozen dance; can exceed 1 for a dance that accents more often than the music. NaN without music beats.
    """
    n_music = np.asarray(music_frames).size
    return float(np.asarray(kinematic_frames).size / n_music) if n_music else float("nan")


def beat_hit_rate(kinematic_frames: np.ndarray, music_frames: np.ndarray,
                  tolerance_frames: float = DEFAULT_TOLERANCE_FRAMES) -> float:
    """Beat hit rate ``B_a / B_k`` (Lee et al. 2019): share of kinematic beats aligned with a music beat.

    A kinematic beat (frame index) is aligned when a music beat (frame index, may be fractional: seconds x fps)
    lies within ``tolerance_frames`` of it. NaN when there is no kinematic beat.
    """
    aligned = beats_aligned(kinematic_frames, music_frames, tolerance_frames)
    return float(aligned.mean()) if aligned.size else float("nan")


def beat_align_score(music_seconds: np.ndarray, kinematic_seconds: np.ndarray,
                     sigma_seconds: float = DEFAULT_BAS_SIGMA_SECONDS) -> float:
    """Beat Align Score (Bailando, Li et al. 2022), in [0, 1].

    ``BAS = 1/|B_m| * sum_{t in B_m} exp(-min_{t' in B_k} (t - t')^2 / (2 sigma^2))``: for every music beat
    ``t`` (seconds), how close the nearest kinematic beat ``t'`` (seconds) is. 1 when every music beat has a
    kinematic beat exactly on it; 0 without kinematic beats; NaN without music beats.
    """
    m = np.asarray(music_seconds, dtype=np.float64).ravel()
    k = np.asarray(kinematic_seconds, dtype=np.float64).ravel()
    if m.size == 0:
        return float("nan")
    if k.size == 0:
        return 0.0
    nearest = np.abs(m[:, None] - k[None, :]).min(axis=1)
    return float(np.exp(-nearest ** 2 / (2.0 * sigma_seconds ** 2)).mean())


def diversity(features: np.ndarray, pairs: int = 500, rng: np.random.Generator | None = None) -> float:
    """Diversity (Lee et al. 2019 / Dance Revolution): mean Euclidean feature distance over random pairs.

    ``features`` ``[N, D]``: one embedding per dance, each generated for a different song. ``pairs`` random
    pairs ``(i, j), i != j`` are drawn (all pairs when there are fewer): ``mean ||f_i - f_j||``.
    """
    f = np.asarray(features, dtype=np.float64)
    n = f.shape[0]
    if n < 2:
        raise ValueError("diversity needs at least two dances")
    i, j = np.triu_indices(n, k=1)
    if i.size > pairs:
        pick = (rng or np.random.default_rng(0)).choice(i.size, size=pairs, replace=False)
        i, j = i[pick], j[pick]
    return float(np.linalg.norm(f[i] - f[j], axis=1).mean())


def multimodality(features: np.ndarray) -> float:
    """Multimodality (Lee et al. 2019): mean feature distance between dances generated for the same song.

    ``features`` ``[S, K, D]``: S songs, K >= 2 dances each (different seeds). For each song the mean of
    ``||f_a - f_b||`` over all ``K(K-1)/2`` pairs, then the mean over songs. 0 for a deterministic model.
    """
    f = np.asarray(features, dtype=np.float64)
    if f.ndim != 3 or f.shape[1] < 2:
        raise ValueError(f"multimodality needs [songs, K >= 2, D] features, got shape {f.shape}")
    a, b = np.triu_indices(f.shape[1], k=1)
    return float(np.linalg.norm(f[:, a] - f[:, b], axis=-1).mean())


def fid_over_time(window_features: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Long-term FID curve (Dance Revolution Fig. 4): FID of each time window against a reference set.

    ``window_features`` ``[N, W, D]``: N dances cut into W consecutive windows (e.g. 4 s each), one
    embedding per window. Returns ``[W]``: ``FID(window_features[:, w], reference)`` (NaN when N < 2: one
    dance has no covariance). A dance that freezes drifts away from real motion, so its curve rises with w.
    """
    f = np.asarray(window_features, dtype=np.float64)
    if f.shape[0] < 2:
        return np.full(f.shape[1], np.nan)
    return np.array([frechet_distance(f[:, w], reference) for w in range(f.shape[1])])


def cross_modal_distance(generated: np.ndarray, music: np.ndarray, train_music: np.ndarray,
                         train_dance: np.ndarray) -> float:
    """Ren et al. (2020)'s cross-modal evaluation, with our embeddings.

    For each generated dance ``g_i`` (``generated`` ``[N, D]``) of song ``i`` (``music`` ``[N, E]``), find the
    training song nearest to it in music-embedding space (``train_music`` ``[M, E]``, Euclidean), take that
    song's real dance (``train_dance`` ``[M, D]``) and measure ``||g_i - train_dance[nn(i)]||``; return the
    mean over i. Ren et al. learn both embeddings with metric learning; here the dance space is the style
    classifier's feature space and the music space is standardised summary audio statistics, so values are
    comparable between rows of one report, not with the paper.
    """
    nn_idx = np.linalg.norm(np.asarray(music)[:, None] - np.asarray(train_music)[None], axis=-1).argmin(axis=1)
    return float(np.linalg.norm(np.asarray(generated) - np.asarray(train_dance)[nn_idx], axis=1).mean())
