from dataclasses import replace

import numpy as np
import torch

# The machine is shared: one intra-op thread avoids OpenMP contention that makes tiny ops take milliseconds.
torch.set_num_threads(1)

from dancesynth.core.skeleton import NECK, ROOT, normalize  # noqa: E402
from stage1_pose.data.styles import STYLES  # noqa: E402
from stage1_pose.data.synth_dance import synthesize_dance  # noqa: E402
from stage1_pose.models.base import Batch  # noqa: E402
from stage1_pose.models.dance_revolution.music_input import FEATURE_DIM, TEMPOGRAM_WINDOW  # noqa: E402
from stage1_pose.models.lstm.model import LSTMBaseline, LSTMConfig  # noqa: E402

TINY = LSTMConfig(feature_dim=6, hidden=24, layers=2, dropout=0.0, lr=1e-2, window_frames=16)


def test_shapes_and_determinism():
    model = LSTMBaseline(TINY).eval()
    features, beats = torch.randn(3, 41, 6), torch.zeros(3, 41, dtype=torch.bool)
    a = model.generate(features, beats, torch.Generator().manual_seed(0))
    assert a.shape == (3, 41, 25, 2)
    assert torch.equal(a, model.generate(features, beats, torch.Generator().manual_seed(1)))


def test_overfits_one_clip():
    torch.manual_seed(0)
    model = LSTMBaseline(TINY)
    model._optimizers = model.configure_optimizers()
    t = torch.linspace(0, 6.28, 16)
    poses = torch.stack([torch.sin(t * 2 + j) for j in range(50)], dim=-1).reshape(1, 16, 25, 2)
    batch = Batch(torch.randn(1, 16, 6), torch.zeros(1, 16, dtype=torch.bool), poses, torch.zeros(1, dtype=torch.long))
    losses = [model.training_step(batch, 0)["l1"] for _ in range(150)]
    assert losses[-1] < losses[0] / 5


def test_a_long_song_is_danced_from_windows_of_the_training_length():
    model = LSTMBaseline(replace(TINY, windowed_generation=True)).eval()
    features, beats = torch.randn(1, 100, 6), torch.zeros(1, 100, dtype=torch.bool)
    dance = model.generate(features, beats)
    assert dance.shape == (1, 100, 25, 2)
    # Windows of 16 frames start every 14: frames 44-53 come from the window starting at 42 alone, run from a
    # fresh state, not from a state carried over the song.
    assert torch.allclose(dance[:, 44:54], model(features[:, 42:58])[:, 2:12], atol=1e-5)
    assert not torch.allclose(dance[:, 44:54], model(features)[:, 44:54], atol=1e-3)


def test_root_smoothing_steadies_the_root_and_leaves_the_other_joints():
    torch.manual_seed(0)
    free = LSTMBaseline(TINY).eval()
    smooth = LSTMBaseline(replace(TINY, root_smoothing=2.0)).eval()
    smooth.load_state_dict(free.state_dict())
    features, beats = torch.randn(1, 60, 6), torch.zeros(1, 60, dtype=torch.bool)
    a, b = free.generate(features, beats), smooth.generate(features, beats)
    def jitter(x):
        return x[:, :, ROOT].diff(n=2, dim=1).norm(dim=-1).mean()
    assert jitter(b) < 0.3 * jitter(a)
    others = [j for j in range(25) if j != ROOT]
    assert torch.equal(a[:, :, others], b[:, :, others])


def test_feature_dropout_acts_in_training_only():
    model = LSTMBaseline(replace(TINY, feature_dropout=0.5))
    features, beats = torch.randn(2, 30, 6), torch.zeros(2, 30, dtype=torch.bool)
    assert not torch.equal(model(features), model(features))
    model.eval()
    assert torch.equal(model.generate(features, beats), model.generate(features, beats))


def test_without_the_tempogram_a_tempo_it_never_heard_changes_nothing():
    # Real recordings faster than any built-in song have a tempogram the LSTM never saw; small reads without it.
    config = replace(TINY, feature_dim=FEATURE_DIM, tempogram=False)
    model = LSTMBaseline(config).eval()
    features, beats = torch.randn(1, 40, FEATURE_DIM), torch.zeros(1, 40, dtype=torch.bool)
    other_tempo = features.clone()
    other_tempo[..., FEATURE_DIM - TEMPOGRAM_WINDOW:] = torch.randn(1, 40, TEMPOGRAM_WINDOW) * 5
    assert torch.equal(model.generate(other_tempo, beats), model.generate(features, beats))
    with_it = LSTMBaseline(replace(config, tempogram=True)).eval()
    assert not torch.allclose(with_it.generate(other_tempo, beats), with_it.generate(features, beats), atol=1e-3)
    assert not LSTMConfig.preset("small").tempogram


def test_centred_features_ignore_an_offset_within_each_window():
    # A song's timbre or level offsets every frame's features alike; centred, each window sees only its changes.
    model = LSTMBaseline(replace(TINY, centre_features=True, windowed_generation=True)).eval()
    features, beats = torch.randn(1, 60, 6), torch.zeros(1, 60, dtype=torch.bool)
    offset = torch.randn(1, 1, 6) * 3
    assert torch.allclose(model.generate(features + offset, beats), model.generate(features, beats), atol=1e-5)
    plain = LSTMBaseline(TINY).eval()
    assert not torch.allclose(plain(features + offset), plain(features), atol=1e-3)


def upright_dances(clips: int, frames: int) -> torch.Tensor:
    """``[clips, frames, 25, 2]`` built-in ballet dances in model coordinates."""
    rng = np.random.default_rng(0)
    beats = np.arange(0, frames / 15, 0.5)
    return torch.from_numpy(np.stack([normalize(synthesize_dance(STYLES["ballet"], beats, frames, rng))[0]
                                      for _ in range(clips)]))


def test_mean_pose_start_begins_every_initialisation_upright():
    # A kinematic output normalises each bone's direction; a torso that starts pointing down can stay there.
    poses = upright_dances(4, 16)
    batch = Batch(torch.randn(4, 16, 6), torch.zeros(4, 16, dtype=torch.bool), poses, torch.zeros(4, dtype=torch.long))
    for seed in range(8):
        torch.manual_seed(seed)
        model = LSTMBaseline(replace(TINY, kinematic_output=True, mean_pose_start=True, lr=1e-4))
        model._optimizers = model.configure_optimizers()
        model.training_step(batch, 0)
        dance = model.eval().generate(torch.randn(1, 30, 6), torch.zeros(1, 30, dtype=torch.bool))
        assert (dance[0, :, NECK, 1] < 0).all()  # the neck above the hip (y grows downwards)
        torso = dance[0, :, NECK].mean(0)
        assert torch.cosine_similarity(torso, poses[:, :, NECK].mean((0, 1)), dim=0) > 0.95


def beat_one_hot(beats: torch.Tensor) -> torch.Tensor:
    """``[1, T, 6]`` features for ``[1, T]`` beat flags: the beat one-hot in every column."""
    return beats[..., None].float().expand(-1, -1, 6)


def test_beat_phase_input_times_the_moves_by_a_new_songs_beats(beat_following_error):
    # The features' beat one-hot says when a beat is, not when the next one comes; the beat phase does.
    def error(beat_phase_input: bool) -> float:
        config = replace(TINY, window_frames=48, beat_phase_input=beat_phase_input)
        return beat_following_error(lambda: LSTMBaseline(config), beat_one_hot)
    assert error(True) < 0.1  # measured 0.04
    assert error(False) > 0.25  # measured 0.34: the LSTM can count frames since the last beat, but not ahead
