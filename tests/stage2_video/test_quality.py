import numpy as np

from stage2_video.quality import BOX_MARGIN, box_scores, scoring_box


def _pose(points: list[tuple[float, float]]) -> np.ndarray:
    keypoints = np.zeros((25, 3), np.float32)
    keypoints[:len(points), :2] = points
    keypoints[:len(points), 2] = 1.0
    return keypoints


def test_the_scoring_box_is_the_joints_box_grown_and_clipped():
    pose = _pose([(40, 20), (60, 120)])  # 20 x 100 px
    grow = BOX_MARGIN * 100
    assert scoring_box(pose, 200, 200) == (int(40 - grow), int(20 - grow), int(60 + grow + 1), int(120 + grow + 1))
    assert scoring_box(pose, 50, 100) == (int(40 - grow), int(20 - grow), 50, 100)
    assert scoring_box(np.zeros((25, 3), np.float32), 50, 100) == (0, 0, 50, 100)
    off_frame = _pose([(300, 20), (320, 120)])  # a pose beside the frame: no box of its own
    assert scoring_box(off_frame, 200, 200) == (0, 0, 200, 200)


def test_box_scores_see_only_the_person():
    rng = np.random.default_rng(0)
    real = rng.integers(0, 256, (200, 200, 3), dtype=np.uint8)
    pose = _pose([(80, 60), (120, 140)])
    elsewhere = real.copy()
    elsewhere[180:, :] = 0  # the scene changes below the box
    assert box_scores(elsewhere, real, pose) == (1.0, 100.0)
    inside = real.copy()
    inside[90:110, 90:110] = 0  # the person changes
    ssim_inside, psnr_inside = box_scores(inside, real, pose)
    assert ssim_inside < 0.99 and psnr_inside < 30
