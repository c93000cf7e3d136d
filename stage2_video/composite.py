"""Full-frame output: each generated crop put back into the target video's own scene, at its resolution.

The appearance model sees and renders only a crop of the target's canvas (:class:`stage2_video.framing.Framing`).
To show the dance in the target's scene, a background plate (the scene without the person) is estimated from
the target video once: per pixel, the median of that pixel over up to ``MAX_PLATE_FRAMES`` frames in which the
person does not cover it; pixels the person always covers are filled by inpainting. Where the person is: their
pose drawn with thick limbs, a head disc and a generous margin (:func:`stage2_video.masks.person_mask`), or,
tighter, their segmented pixels grown a little together with the pose drawn with a small margin, so a person who
stays on one spot leaves less to inpaint. Each generated frame then has its framing
inverted (padding dropped, resized back onto its crop box) and is blended over the plate through a soft mask
around the generated pose: the same drawing, feathered with a Gaussian and faded out towards the box's edges,
so neither the box nor the mask's outline shows.
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
from collections.abc import Iterable
from pathlib import Path

import cv2
import numpy as np

from dancesynth.core.checkpoint import load_meta
from dancesynth.core.draw import draw_pose
from dancesynth.core.errors import DancesynthError
from dancesynth.core.media import read_frames
from dancesynth.core.progress import track
from dancesynth.core.skeleton import PoseSequence, body_scale, true_runs
from stage2_video.extract import native_logs_hidden_unless_debug
from stage2_video.framing import MIN_CONFIDENCE, Framing
from stage2_video.masks import Segmenter, draw_person, frame_mask, person_mask, torso_length
from stage2_video.training_data import KIND, POSES_FILE, cache_file, poses_digest

PLATE_FILE = "background.png"
# Frames sampled for the plate's median: enough for a stable median, few enough to stay quick for long videos.
MAX_PLATE_FRAMES = 120
# A pixel free in fewer sampled frames than this is inpainted: one or two samples may be a badly posed frame.
MIN_FREE_SAMPLES = 3
# Neighbourhood (torso lengths) inpainting draws on; wider only blurs more, as the holes are person-sized.
INPAINT_RADIUS = 0.1
# Bytes of sampled pixels sorted at once (the plate is computed in row bands of about this size).
BAND_BYTES = 64 << 20
# Gap filling (stage2_video.extract) gives filled joints confidence 0.1: a frame without any joint above this
# is a guess of where the person was, useless for telling where they were not.
OBSERVED_CONFIDENCE = 0.2
# A joint filled over a longer gap than this (held at its last position, or interpolated across a jump) is a
# guess too: drawn, it would hide the same stretch of scene in every frame, so the plate leaves it out.
MAX_GUESS_SECONDS = 0.5

# Growth of the drawn person: generous for the plate (pose errors, motion blur, loose clothes), smaller for the
# composite, where the feather (Gaussian sigma) then fades the generated frame out beyond the person.
PLATE_MARGIN = 0.35
# With segmented masks: the pose's margin, and the growth of the segmented pixels (blur, hair), in torso lengths.
SEGMENTED_PLATE_MARGIN = 0.05
SEGMENTED_PLATE_GROWTH = 0.1
COMPOSITE_MARGIN = 0.2
FEATHER_SIGMA = 0.08
# Width of the fade to 0 at the crop box's edges inside the canvas, where a limb reaching out of the box is cut.
EDGE_FADE = 0.3
# The soft mask is drawn and blurred at a resolution where the feather is about this many pixels, then resized.
MASK_SIGMA_PIXELS = 3.0



def plate_frames(poses: PoseSequence, max_frames: int = MAX_PLATE_FRAMES) -> np.ndarray:
    """Indices (ascending) of up to ``max_frames`` frames, evenly spread, whose pose was observed rather than
    gap-filled (all frames when none was)."""
    observed = np.flatnonzero(poses.confidence.max(axis=1) >= OBSERVED_CONFIDENCE)
    if len(observed) == 0:
        observed = np.arange(len(poses))
    picks = np.round(np.linspace(0, len(observed) - 1, min(max_frames, len(observed)))).astype(int)
    return np.unique(observed[picks])


def trusted_joints(poses: PoseSequence) -> np.ndarray:
    """``[T, 25]`` bool: joints observed, or filled over a gap of at most ``MAX_GUESS_SECONDS``."""
    present = poses.confidence >= MIN_CONFIDENCE
    filled = present & (poses.confidence < OBSERVED_CONFIDENCE)
    longest = max(1, round(MAX_GUESS_SECONDS * poses.fps))
    trusted = present.copy()
    for j in range(filled.shape[1]):
        for start, stop in true_runs(filled[:, j]):
            if stop - start > longest:
                trusted[start:stop, j] = False
    return trusted


def _read_rows(path: Path, shape: tuple[int, ...], start: int, stop: int) -> np.ndarray:
    """Rows ``start:stop`` of every image in a raw uint8 file of ``shape`` ``[S, H, ...]``, copied out; the file
    is mapped only meanwhile (a lasting map would keep every page it touched resident)."""
    return np.array(np.memmap(path, np.uint8, "r", shape=shape)[:, start:stop])


def _band_median(pixels: np.ndarray, covered: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel median over the samples where the pixel is free.

    Args:
        pixels: ``[S, h, W, 3]`` uint8; ``covered``: ``[S, h, W]`` (non-zero = the person may be there).

    Returns:
        ``[h, W, 3]`` uint8 medians and ``[h, W]`` bool, True where fewer than ``MIN_FREE_SAMPLES`` were free.
    """
    covered = covered.astype(bool)
    values = pixels.astype(np.uint16)
    values[covered] = 256  # sorts after every real value
    values.sort(axis=0)
    free = (~covered).sum(axis=0)
    low = ((np.maximum(free, 1) - 1) // 2)[None, :, :, None].repeat(3, axis=3)
    high = (free // 2)[None, :, :, None].repeat(3, axis=3)
    median = (np.take_along_axis(values, low, 0)[0] + np.take_along_axis(values, high, 0)[0] + 1) // 2
    return np.minimum(median, 255).astype(np.uint8), free < MIN_FREE_SAMPLES


def plate_cover(frame: np.ndarray, keypoints: np.ndarray, reference: float,
                segmenter: Segmenter | None) -> np.ndarray:
    """``[H, W]`` bool: where the person of one ``[25, 3]`` pose may cover the ``[H, W, 3]`` frame, for the plate:
    the pose drawn with :data:`PLATE_MARGIN`, or with a ``segmenter`` their segmented pixels grown by
    :data:`SEGMENTED_PLATE_GROWTH` and the pose drawn with :data:`SEGMENTED_PLATE_MARGIN`."""
    height, width = frame.shape[:2]
    if segmenter is None:
        return person_mask(keypoints, width, height, reference, PLATE_MARGIN)
    grow = max(1, round(SEGMENTED_PLATE_GROWTH * reference))
    segmented = cv2.dilate(frame_mask(segmenter, frame, keypoints, reference).astype(np.uint8),
                           cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * grow + 1, 2 * grow + 1))) > 0
    return segmented | person_mask(keypoints, width, height, reference, SEGMENTED_PLATE_MARGIN)


def background_plate(frames: Iterable[np.ndarray], poses: PoseSequence, max_frames: int = MAX_PLATE_FRAMES,
                     work_dir: str | os.PathLike | None = None, segment: bool = False) -> np.ndarray:
    """The target's scene without the person: ``[height, width, 3]`` uint8 RGB at the poses' canvas size.

    Args:
        frames: the video's frames in order (``[height, width, 3]`` uint8 RGB, e.g. :func:`read_frames`); only
            the sampled ones are kept, and reading stops after the last of them.
        poses: the person's poses in those frames (canvas pixels).
        max_frames: how many frames the median is taken over (see :func:`plate_frames`).
        work_dir: folder for the temporary copy of the sampled frames (default the system's temporary folder);
            it takes ``max_frames x height x width x 4`` bytes of disk, while memory stays within a few times
            ``BAND_BYTES`` whatever the video's length and size.
        segment: tell where the person is by segmenting their pixels (:func:`plate_cover`), not by the pose alone.
    """
    picks = plate_frames(poses, max_frames)
    if len(picks) == 0:
        raise DancesynthError("The pose sequence has no frames; pass the poses extracted from the target video.")
    width, height = poses.width, poses.height
    reference = body_scale(poses)
    keypoints = poses.keypoints.copy()
    keypoints[~trusted_joints(poses), 2] = 0.0
    plate = np.empty((height, width, 3), np.uint8)
    holes = np.empty((height, width), bool)
    pixels_shape, covered_shape = (len(picks), height, width, 3), (len(picks), height, width)
    with tempfile.TemporaryDirectory(dir=work_dir, prefix=".plate-") as tmp:
        pixels_path, covered_path = Path(tmp) / "pixels", Path(tmp) / "covered"
        slot, count = 0, 0
        with contextlib.ExitStack() as stack:
            pixels, covered = (stack.enter_context(open(p, "wb")) for p in (pixels_path, covered_path))
            segmenter = None
            if segment:
                stack.enter_context(native_logs_hidden_unless_debug())
                segmenter = Segmenter()
                stack.callback(segmenter.close)
            for t, frame in enumerate(frames):
                count = t + 1
                if t == picks[slot]:
                    if frame.shape != (height, width, 3):
                        raise DancesynthError(f"The video's frames are {frame.shape[1]}x{frame.shape[0]} but the "
                                              f"poses are for {width}x{height}; pass the poses extracted from it.")
                    pixels.write(np.ascontiguousarray(frame, np.uint8).tobytes())
                    covered.write(plate_cover(frame, keypoints[t], reference, segmenter).tobytes())
                    slot += 1
                    if slot == len(picks):
                        break
        if slot < len(picks):
            raise DancesynthError(f"The video has {count} frames but the poses have {len(poses)}; "
                                  "pass the poses extracted from this video.")
        rows = max(1, BAND_BYTES // (2 * len(picks) * width * 3))  # sorting works on uint16 copies
        for y in range(0, height, rows):
            plate[y:y + rows], holes[y:y + rows] = _band_median(_read_rows(pixels_path, pixels_shape, y, y + rows),
                                                                _read_rows(covered_path, covered_shape, y, y + rows))
    if holes.any():
        radius = max(3, round(INPAINT_RADIUS * reference))
        plate = cv2.inpaint(plate, holes.astype(np.uint8), radius, cv2.INPAINT_TELEA)
    return plate


def read_plate(path: Path) -> np.ndarray:
    """A plate written by :func:`cache_plate` -> ``[H, W, 3]`` uint8 RGB."""
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise DancesynthError(f"{path} is not a readable image; delete it so the background is estimated again.")
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


def cache_plate(video: Path, poses: PoseSequence, run_dir: Path, segment: bool = False) -> np.ndarray:
    """The plate of ``video`` (:func:`background_plate`, ``segment`` as there), cached as
    ``RUN_DIR/background.png`` with a key file naming the video's content, the poses and how the person was found;
    a plate made otherwise is rebuilt."""
    path = Path(run_dir) / PLATE_FILE

    def write(tmp: Path) -> None:
        frames = track(read_frames(video), total=len(poses), desc="background", unit="frame")
        plate = background_plate(frames, poses, work_dir=run_dir, segment=segment)
        _, png = cv2.imencode(".png", cv2.cvtColor(plate, cv2.COLOR_RGB2BGR))
        tmp.write_bytes(png.tobytes())

    # Plates found from the poses alone keep the key they always had.
    cache_file(path, Path(video), write, poses=poses_digest(poses), **({"segmented": True} if segment else {}))
    return read_plate(path)


def load_plate(run_dir: str | os.PathLike) -> np.ndarray:
    """The background plate of an appearance model's run: its ``background.png``, or for a run trained before
    plates were cached, estimated now from its ``poses.npz`` and target video (when that file still exists)."""
    run_dir = Path(run_dir)
    if (run_dir / PLATE_FILE).is_file():
        return read_plate(run_dir / PLATE_FILE)
    meta = load_meta(run_dir, KIND)
    video = meta.get("video")
    if not (video and Path(video).is_file() and (run_dir / POSES_FILE).is_file()):
        raise DancesynthError(f"{run_dir} has no background of the target's scene and its target video {video} "
                              "cannot be found to make one; pass --crop to write the model's crop instead.")
    segment = bool(meta.get("config", {}).get("prior", False))  # as training made it (stage2_video.train)
    return cache_plate(Path(video), PoseSequence.load(run_dir / POSES_FILE), run_dir, segment)


class Compositor:
    """Generated model-resolution frames -> full frames of the target's scene at ``size``.

    Each frame comes with the :class:`Framing` its model image was cut by (one per frame: the box may follow
    the person).

    Args:
        plate: ``[H, W, 3]`` uint8 background plate at the canvas size.
        size: ``(width, height)`` of the output in pixels (the canvas, or scaled with its aspect kept).
        torso: the target's torso length in canvas pixels (:func:`body_scale` of its poses); sizes the mask.
    """

    def __init__(self, plate: np.ndarray, size: tuple[int, int], torso: float) -> None:
        self.canvas = (plate.shape[1], plate.shape[0])
        self.size = (int(size[0]), int(size[1]))
        self.sx, self.sy = self.size[0] / self.canvas[0], self.size[1] / self.canvas[1]
        shrink = self.sx < 1 or self.sy < 1
        self.plate = cv2.resize(plate, self.size, interpolation=cv2.INTER_AREA if shrink else cv2.INTER_CUBIC)
        self.torso = float(torso) * self.sy

    def box(self, framing: Framing) -> tuple[float, float, float, float]:
        """The crop box of ``framing`` in output pixels (x0, y0, x1, y1)."""
        f = framing
        return f.x0 * self.sx, f.y0 * self.sy, (f.x0 + f.crop_width) * self.sx, (f.y0 + f.crop_height) * self.sy

    def region(self, framing: Framing) -> tuple[int, int, int, int]:
        """The box's part inside the output, in whole pixels: the only region a generated frame touches."""
        box = self.box(framing)
        return (max(0, math.floor(box[0])), max(0, math.floor(box[1])),
                min(self.size[0], math.ceil(box[2])), min(self.size[1], math.ceil(box[3])))

    def to_output(self, xy: np.ndarray) -> np.ndarray:
        """``[..., 2]`` canvas pixels -> output pixels (pixel-centre convention of ``cv2.resize``)."""
        out = np.asarray(xy, np.float32).copy()
        out[..., 0] = (out[..., 0] + 0.5) * self.sx - 0.5
        out[..., 1] = (out[..., 1] + 0.5) * self.sy - 0.5
        return out

    def _uncrop(self, generated: np.ndarray, f: Framing) -> np.ndarray:
        """The generated image (or a single-channel map) without padding, resampled onto the region:
        ``[rh, rw, 3]`` (``[rh, rw]``), same dtype."""
        inner = generated[f.pad_y:f.pad_y + f.inner_height, f.pad_x:f.pad_x + f.inner_width]
        ax, ay = f.crop_width / f.inner_width * self.sx, f.crop_height / f.inner_height * self.sy
        x0, y0, x1, y1 = self.region(f)
        # inner pixel i (centre) -> canvas (i + 0.5) * crop / inner - 0.5 + x0 -> output, minus the region origin
        m = np.array([[ax, 0, 0.5 * ax + f.x0 * self.sx - 0.5 - x0],
                      [0, ay, 0.5 * ay + f.y0 * self.sy - 0.5 - y0]], np.float64)
        return cv2.warpAffine(inner, m, (x1 - x0, y1 - y0), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)

    def alpha(self, keypoints: np.ndarray, framing: Framing) -> np.ndarray:
        """``[rh, rw]`` float32 in [0, 1]: the generated frame's weight over the region of ``framing`` for one
        ``[25, 3]`` pose in canvas pixels (1 on the person, a Gaussian fall-off around, 0 at the box's inner
        edges)."""
        x0, y0, x1, y1 = self.region(framing)
        torso = torso_length(np.c_[self.to_output(keypoints[:, :2]), keypoints[:, 2]], self.torso)
        sigma = FEATHER_SIGMA * torso
        scale = min(1.0, MASK_SIGMA_PIXELS / max(sigma, 1e-6))
        small = np.zeros((max(1, math.ceil((y1 - y0) * scale)), max(1, math.ceil((x1 - x0) * scale))), np.uint8)
        xy = (self.to_output(keypoints[:, :2]) - (x0, y0) + 0.5) * scale - 0.5
        draw_person(small, xy, keypoints[:, 2] >= MIN_CONFIDENCE, torso * scale, COMPOSITE_MARGIN * torso * scale)
        soft = cv2.GaussianBlur(small.astype(np.float32) / 255.0, (0, 0), sigma * scale)
        soft = cv2.resize(soft, (x1 - x0, y1 - y0), interpolation=cv2.INTER_LINEAR)
        return soft * self._edge_fade(EDGE_FADE * torso, framing)

    def _edge_fade(self, width: float, framing: Framing) -> np.ndarray:
        """``[rh, rw]`` ramp from 0 at each box edge that lies inside the canvas to 1 at ``width`` pixels in."""
        x0, y0, x1, y1 = self.region(framing)
        box = self.box(framing)
        ramps = []
        for lo, hi, start, stop, size in ((box[0], box[2], x0, x1, self.size[0]),
                                          (box[1], box[3], y0, y1, self.size[1])):
            centres = np.arange(start, stop, dtype=np.float32) + 0.5
            ramp = np.ones_like(centres)
            if lo > 0:
                ramp = np.minimum(ramp, np.clip((centres - lo) / width, 0, 1))
            if hi < size:
                ramp = np.minimum(ramp, np.clip((hi - centres) / width, 0, 1))
            ramps.append(ramp)
        return ramps[1][:, None] * ramps[0][None, :]

    def frame(self, generated: np.ndarray, keypoints: np.ndarray, framing: Framing,
              coverage: np.ndarray | None = None) -> np.ndarray:
        """One generated ``[model height, model width, 3]`` uint8 frame, the ``[25, 3]`` pose (canvas pixels)
        it was rendered from and the framing its label map was drawn in -> ``[height, width, 3]`` uint8 frame of
        the scene at the output size. ``coverage`` (``[model height, model width]`` float32 in [0, 1], e.g. a
        warped prior's alpha) widens the blend mask to where the person's own pixels reach."""
        out = self.plate.copy()
        x0, y0, x1, y1 = self.region(framing)
        if x1 <= x0 or y1 <= y0:
            return out
        a = self.alpha(np.asarray(keypoints, np.float32), framing)
        if coverage is not None:
            reach = np.clip(self._uncrop(np.asarray(coverage, np.float32), framing), 0.0, 1.0)
            a = np.maximum(a, reach * self._edge_fade(EDGE_FADE * self.torso, framing))
        out[y0:y1, x0:x1] = cv2.blendLinear(self._uncrop(generated, framing), out[y0:y1, x0:x1], a, 1.0 - a)
        return out

    def skeleton(self, keypoints: np.ndarray) -> np.ndarray:
        """The ``[25, 3]`` pose (canvas pixels) drawn over black at the output size, where :meth:`frame` puts
        the person (black, not the plate: the preview stays legible on busy scenes and looks like the label maps
        the model was conditioned on)."""
        kp = np.asarray(keypoints, np.float32).copy()
        kp[:, :2] = self.to_output(kp[:, :2])
        return draw_pose(np.zeros((self.size[1], self.size[0], 3), np.uint8), kp)


def output_size(canvas: tuple[int, int], height: int | None) -> tuple[int, int]:
    """``(width, height)`` in pixels of the scene output: the ``canvas`` (pixels), or ``height`` pixels high with
    the aspect kept; both even, as H.264's 4:2:0 sampling needs."""
    width, canvas_height = canvas
    if height is None:
        height = canvas_height
    width = round(width * height / canvas_height)
    return width + width % 2, height + height % 2


def scene_compositor(run_dir: str | os.PathLike, size: tuple[int, int]) -> Compositor:
    """The :class:`Compositor` of an appearance model's run (its plate and torso length) for output ``size``."""
    plate = load_plate(run_dir)
    poses = Path(run_dir) / POSES_FILE
    if not poses.is_file():
        raise DancesynthError(f"{run_dir} has no {POSES_FILE} to size the person's mask by; "
                              "pass --crop to write the model's crop instead.")
    return Compositor(plate, size, body_scale(PoseSequence.load(poses)))
