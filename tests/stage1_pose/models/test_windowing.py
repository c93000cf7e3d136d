"""Generation in windows of the training length; smoothing along time."""

import torch

from stage1_pose.models.windowing import smooth_in_time, windowed


def test_a_long_song_is_encoded_from_windows_of_the_training_length():
    # An encoder whose state grows with every frame it reads, as a drifting recurrent state does.
    def elapsed(x):
        return torch.arange(1.0, x.shape[1] + 1).view(1, -1, 1).expand(x.shape[0], -1, 1)

    codes = windowed(elapsed, (torch.zeros(2, 200, 3),), 40)
    assert codes.shape == (2, 200, 1) and float(codes.max()) <= 40
    # A per-frame encoder gives the same codes windowed or not: the cross-fade weights sum to one everywhere.
    x = torch.randn(1, 200, 3)
    torch.testing.assert_close(windowed(lambda a: 2 * a, (x,), 40), 2 * x)
    assert torch.equal(windowed(elapsed, (x[:, :30],), 40), elapsed(x[:, :30]))
    assert torch.equal(windowed(elapsed, (x,), 0), elapsed(x))  # window 0: the whole input at once


def test_windows_cross_fade_over_an_eighth_of_a_window_also_at_the_songs_end():
    window = 40
    for frames in (41, 75, 76, 200):
        # Each window's code is its index: a frame is blended exactly where it holds a fraction.
        calls = []

        def index(x, calls=calls):
            calls.append(None)
            return torch.full((1, x.shape[1], 1), float(len(calls) - 1))

        codes = windowed(index, (torch.zeros(1, frames, 1),), window)[0, :, 0]
        junctions = int(codes.max())
        assert junctions >= 1 and int((codes != codes.round()).sum()) == junctions * (window // 8), frames
        assert torch.all(codes.diff() >= 0)


def test_smoothing_in_time_keeps_the_mean_and_damps_frame_to_frame_changes():
    x = torch.randn(2, 50, 3)
    assert smooth_in_time(x, 0.0) is x
    smooth = smooth_in_time(x, 2.0)
    assert smooth.shape == x.shape
    torch.testing.assert_close(smooth_in_time(torch.full((1, 9, 2), 3.0), 2.0), torch.full((1, 9, 2), 3.0))
    assert smooth.diff(dim=1).abs().mean() < 0.3 * x.diff(dim=1).abs().mean()
    assert (smooth.mean(dim=1) - x.mean(dim=1)).abs().max() < 0.1
