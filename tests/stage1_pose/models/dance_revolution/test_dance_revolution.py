import dataclasses

import pytest
import torch

from dancesynth.core.errors import DancesynthError
from stage1_pose.models.base import Batch
from stage1_pose.models.dance_revolution.model import (
    DanceRevolution,
    DanceRevolutionConfig,
    LSTMStepper,
    curriculum_p,
    predicted_inputs,
    sinusoidal_encoding,
)
from stage1_pose.models.kinematics import joint_speeds

# The machine is shared: one intra-op thread avoids OpenMP contention that makes tiny ops take milliseconds.
torch.set_num_threads(1)

TINY = DanceRevolutionConfig(feature_dim=12, d_model=16, heads=2, d_k=8, d_v=8, d_ff=32, layers=1, window=6,
                             dropout=0.0, lstm_hidden=32, lstm_layers=3, lam=0.5, q=3, lr=3e-3, window_frames=20)


def test_curriculum_schedules():
    assert [curriculum_p("linear", t, 0.01, 0, 900) for t in (0, 99, 100, 250)] == [0, 0, 1, 2]
    assert [curriculum_p("quadratic", t, 0.01, 0, 900) for t in (9, 10, 30)] == [0, 1, 9]
    assert [curriculum_p("exponential", t, 0.01, 0, 900) for t in (4, 5, 10, 10_000)] == [0, 1, 220, 900]
    assert curriculum_p("const", 123, 0.01, 7, 900) == 7
    assert curriculum_p("linear", 10**6, 0.01, 0, 90) == 90
    with pytest.raises(DancesynthError, match="curriculum"):
        DanceRevolutionConfig(curriculum="cosine")


def test_predicted_inputs_alternate_p_predicted_then_q_ground_truth():
    assert predicted_inputs(9, 2, 3) == [False, True, True, False, False, False, True, True, False]
    assert not any(predicted_inputs(9, 0, 3))


def test_positional_encoding_any_length():
    pe = sinusoidal_encoding(9001, 16)
    assert pe.shape == (9001, 16) and torch.isfinite(pe).all()
    torch.testing.assert_close(pe[:5], sinusoidal_encoding(5, 16))


def no_beats(batch: int, frames: int) -> torch.Tensor:
    return torch.zeros(batch, frames, dtype=torch.bool)


def test_chunked_encoding_equals_whole_sequence_encoding():
    encoder = DanceRevolution(dataclasses.replace(TINY, layers=2)).encoder.eval()
    features = torch.randn(1, 101, 12)
    with torch.no_grad():
        whole = encoder(features)
        for chunk in (10, 33, 101, 500):
            torch.testing.assert_close(encoder.encode_chunked(features, chunk), whole, rtol=1e-5, atol=1e-5)


def test_generate_shapes_seeds_and_length():
    model = DanceRevolution(TINY).eval()
    features, beats = torch.randn(2, 37, 12), no_beats(2, 37)
    a = model.generate(features, beats, torch.Generator().manual_seed(1))
    b = model.generate(features, beats, torch.Generator().manual_seed(1))
    c = model.generate(features, beats, torch.Generator().manual_seed(2))
    assert a.shape == (2, 37, 25, 2)
    assert torch.equal(a, b) and not torch.allclose(a, c)


def beat_features(beats: torch.Tensor) -> torch.Tensor:
    """``[1, T, 12]`` standardised features with a beat one-hot in column 0 (as the paper's features have) for
    ``[1, T]`` beat flags."""
    features = torch.full((*beats.shape, 12), -0.3)
    features[..., 0] = torch.where(beats, 2.5, -0.3)
    return features


@pytest.mark.parametrize("code_dim, beat_phase_input", [(0, False), (3, False), (3, True)])
def test_fused_lstm_runs_and_stepper_agree(code_dim, beat_phase_input):
    # Feeding the free-running outputs back as "ground truth" must reproduce them, whichever decoder inputs
    # the curriculum marks as predicted: nn.LSTM runs and per-frame fused steps are the same maths.
    model = DanceRevolution(dataclasses.replace(TINY, code_dim=code_dim, beat_phase_input=beat_phase_input)).eval()
    beats = no_beats(1, 25)
    beats[0, [0, 4, 11, 15, 22]] = True
    features = beat_features(beats)
    z = model.encoder(features.expand(2, -1, -1))
    state = model.decoder.initial_state(2, z.device, torch.Generator().manual_seed(0))
    extras = model.decoder_extras(beats.expand(2, -1), torch.randn(2, 25, code_dim))
    assert extras.shape == (2, 25, code_dim + 2 * beat_phase_input)
    free = model.decoder.generate(z, state, extras)
    for p in (0, 2, 30):
        with torch.no_grad():
            forced = model.decoder(z, state, free, predicted_inputs(25, p, 3), extras)
        torch.testing.assert_close(forced, free, rtol=1e-5, atol=1e-5)


def test_int8_decoding_stays_close_to_fp32():
    model = DanceRevolution(TINY).eval()
    features, beats = torch.randn(1, 30, 12), no_beats(1, 30)
    exact = model.generate(features, beats, torch.Generator().manual_seed(0))
    model.prepare_inference("int8")
    fast = model.generate(features, beats, torch.Generator().manual_seed(0))
    assert (fast - exact).abs().max() < 0.05 * exact.abs().max()
    with pytest.raises(DancesynthError, match="precision"):
        LSTMStepper(model.decoder.lstm, "int4")


def test_tiny_model_overfits_one_clip_with_curriculum():
    torch.manual_seed(0)
    model = DanceRevolution(TINY)
    model._optimizers = model.configure_optimizers()
    t = torch.linspace(0, 6.28, 20)
    poses = torch.stack([torch.sin(t + j) for j in range(50)], dim=-1).reshape(1, 20, 25, 2) * 0.5
    batch = Batch(torch.randn(1, 20, 12), no_beats(1, 20), poses, torch.zeros(1, dtype=torch.long))
    losses = [model.training_step(batch, epoch=e // 30)["l1"] for e in range(120)]
    assert model.p == 1 and model.curriculum_state()["p"] == 1
    assert losses[-1] < losses[0] / 5


def two_way_dances(move: torch.Tensor, code_dim: int, speed_weight: float = 0.0) -> list[torch.Tensor]:
    """Train free-running on one song danced two ways (``move`` and its mirror image); dances of 8 seeds."""
    torch.manual_seed(0)
    model = DanceRevolution(dataclasses.replace(TINY, code_dim=code_dim, code_frames=20, kl_weight=0.001,
                                                speed_weight=speed_weight))
    model._optimizers = model.configure_optimizers()
    features, beats = torch.randn(1, 20, 12).expand(2, -1, -1), no_beats(2, 20)
    batch = Batch(features, beats, torch.stack([move, -move]), torch.zeros(2, dtype=torch.long))
    for _ in range(300):
        model.training_step(batch, epoch=100)  # p = 50: every input is the decoder's own output
    model.eval()
    return [model.generate(features[:1], beats[:1], torch.Generator().manual_seed(s))[0] for s in range(8)]


def test_choreography_code_makes_the_seed_choose_the_dance(mirrored_move, dances_one_way_or_the_other):
    # The paper's decoder: whatever its initial state, the L1 loss makes it dance the mean of the two ways.
    assert max(d.abs().mean() for d in two_way_dances(mirrored_move, 0)) < 0.25 * mirrored_move.abs().mean()
    # With a code: most seeds dance one of the two ways, and both ways occur.
    assert dances_one_way_or_the_other(mirrored_move, two_way_dances(mirrored_move, 2), 0.4)


def test_speed_loss_keeps_the_dance_moving_when_its_direction_is_uncertain(mirrored_move):
    # The pose loss alone makes the decoder dance the mean of the two ways, close to standing still; the speed
    # loss asks for the real dances' speed whichever way the move goes.
    def speed(dance: torch.Tensor) -> float:
        return joint_speeds(dance[None]).mean().item()

    real = speed(mirrored_move)
    assert max(speed(d) for d in two_way_dances(mirrored_move, 0)) < 0.5 * real  # measured: 0.39-0.41
    assert min(speed(d) for d in two_way_dances(mirrored_move, 0, speed_weight=5.0)) > 0.9 * real  # 0.99


def test_code_settings_are_checked():
    for field, value in (("code_dim", -1), ("code_frames", 0), ("kl_weight", -0.1), ("free_bits", -0.1)):
        with pytest.raises(DancesynthError, match="code_dim must be"):
            dataclasses.replace(TINY, **{field: value})
    with pytest.raises(DancesynthError, match="speed_weight must be"):
        dataclasses.replace(TINY, speed_weight=-1.0)


def test_speed_loss_and_free_bits_train_with_the_decoder():
    torch.manual_seed(0)
    model = DanceRevolution(dataclasses.replace(TINY, code_dim=3, code_frames=5, free_bits=0.5, speed_weight=3.0))
    model._optimizers = model.configure_optimizers()
    poses = torch.randn(2, 20, 25, 2)
    batch = Batch(torch.randn(2, 20, 12), no_beats(2, 20), poses, torch.zeros(2, dtype=torch.long))
    scalars = model.training_step(batch, epoch=0)
    assert {"l1", "kl", "speed"} <= scalars.keys() and scalars["kl"] > 0 and scalars["speed"] > 0


def test_code_segments_follow_the_beats():
    model = DanceRevolution(dataclasses.replace(TINY, code_dim=2, code_on_beats=True))
    beats = no_beats(1, 12)
    beats[0, [4, 9]] = True
    assert model.segments(beats).tolist() == [[0] * 4 + [1] * 5 + [2] * 3]
    assert model.generate(torch.randn(1, 12, 12), beats, torch.Generator().manual_seed(0)).shape == (1, 12, 25, 2)
    with pytest.raises(DancesynthError, match="z_smoothing"):
        dataclasses.replace(TINY, z_smoothing=-1.0)


def test_beat_phase_input_times_the_moves_by_a_new_songs_beats(beat_following_error):
    # The paper's decoder hears the music only through the output layer and its own fed-back poses: it learns
    # the training song's rhythm, not to follow the beats. With the beat phase it follows another song's beats.
    def error(beat_phase_input: bool) -> float:
        config = dataclasses.replace(TINY, window_frames=48, beat_phase_input=beat_phase_input)
        return beat_following_error(lambda: DanceRevolution(config), beat_features, epoch=100)
    assert error(True) < 0.25
    assert error(False) > 0.4
