"""A procedurally drawn target person, so stage 2 can be trained and scored against exact ground-truth frames.

:func:`render_person` turns each BODY_25 pose into a picture of a stylised person in a room: a wall and
floor background, a soft floor shadow, legs and arms as shaded capsules (lit from the upper left), a clothed
torso, a neck, and a head with hair and eyes. The picture depends only on the pose, the appearance and the
sequence's body scale, so the same pose always gives the same frame.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import asdict, dataclass, fields

import cv2
import numpy as np

from dancesynth.core.draw import fit_to_canvas
from dancesynth.core.errors import DancesynthError
from dancesynth.core.media import VideoWriter
from dancesynth.core.skeleton import JOINT_INDEX, PoseSequence, body_scale

RGB = tuple[int, int, int]
MIN_CONFIDENCE = 0.05
_LIGHT = np.array([-0.6, -0.8])  # direction towards the light in image coordinates (up and to the left)
_SHIFT = 4  # sub-pixel bits for OpenCV polygon filling


@dataclass(frozen=True)
class PersonAppearance:
    """How the synthetic person and the room look. Widths are full widths as fractions of the body scale
    (the Neck-MidHip distance in pixels); colours are RGB 0-255."""

    skin: RGB = (224, 172, 138)
    hair: RGB = (62, 40, 28)
    shirt: RGB = (200, 40, 48)
    trousers: RGB = (40, 56, 110)
    shoes: RGB = (30, 30, 34)
    long_sleeves: bool = False
    shorts: bool = False
    upper_arm_width: float = 0.22
    forearm_width: float = 0.17
    thigh_width: float = 0.32
    shin_width: float = 0.24
    neck_width: float = 0.2
    torso_margin: float = 0.1
    head_height: float = 0.62
    foot_width: float = 0.13
    wall_top: RGB = (198, 206, 214)
    wall_bottom: RGB = (150, 160, 172)
    floor_far: RGB = (150, 118, 88)
    floor_near: RGB = (104, 76, 54)
    horizon: float = 0.62  # where the floor meets the wall, as a fraction of the image height from the top

    def to_dict(self) -> dict:
        """JSON-ready dictionary (colours as lists)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "PersonAppearance":
        """Inverse of :meth:`to_dict`; unknown keys are an error."""
        known = {f.name for f in fields(cls)}
        unknown = set(data) - known
        if unknown:
            raise DancesynthError(f"Unknown appearance settings {sorted(unknown)}; known ones are {sorted(known)}.")
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in data.items()})


PRESETS: dict[str, PersonAppearance] = {
    "red_tee": PersonAppearance(),
    "green_hoodie": PersonAppearance(
        skin=(150, 100, 70), hair=(20, 16, 14), shirt=(46, 140, 76), trousers=(50, 50, 54), shoes=(230, 230, 226),
        long_sleeves=True, upper_arm_width=0.26, forearm_width=0.21, torso_margin=0.14,
        wall_top=(226, 218, 196), wall_bottom=(190, 178, 150), floor_far=(120, 120, 124), floor_near=(80, 80, 86)),
    "yellow_shorts": PersonAppearance(
        skin=(238, 196, 164), hair=(170, 110, 50), shirt=(250, 250, 245), trousers=(236, 186, 40),
        shoes=(200, 40, 40), shorts=True, thigh_width=0.3, shin_width=0.2,
        wall_top=(120, 150, 190), wall_bottom=(80, 104, 140), floor_far=(196, 190, 176), floor_near=(160, 152, 136)),
}


def appearance_preset(name: str) -> PersonAppearance:
    """One of :data:`PRESETS` by name."""
    if name not in PRESETS:
        raise DancesynthError(f"Unknown appearance preset {name!r}; choose one of {', '.join(PRESETS)}.")
    return PRESETS[name]


def render_background(width: int, height: int, appearance: PersonAppearance) -> np.ndarray:
    """The empty room, float32 ``[height, width, 3]`` in 0-255: a vertical wall gradient above the horizon,
    a floor below it with a near-to-far gradient and perspective plank lines."""
    horizon = int(round(appearance.horizon * height))
    rows = np.zeros((height, 3), np.float32)
    t_wall = np.linspace(0.0, 1.0, max(horizon, 1))[:, None]
    rows[:horizon] = (1 - t_wall) * appearance.wall_top + t_wall * appearance.wall_bottom
    t_floor = np.linspace(0.0, 1.0, max(height - horizon, 1))[:, None]
    rows[horizon:] = (1 - t_floor) * appearance.floor_far + t_floor * appearance.floor_near
    # Plank joints get further apart towards the viewer, which reads as a floor receding in depth.
    for k in range(1, 9):
        y = horizon + int((height - horizon) * (k / 9) ** 1.6)
        if y < height:
            rows[y] *= 0.82
    if 0 < horizon < height:
        rows[horizon] *= 0.7  # skirting line
    return np.repeat(rows[:, None, :], width, axis=1)


class _Painter:
    """Blends shaded shapes into one float32 frame, each shape touching only its bounding box."""

    def __init__(self, image: np.ndarray) -> None:
        self.image = image
        self.height, self.width = image.shape[:2]

    def _box(self, lo: np.ndarray, hi: np.ndarray) -> tuple[int, int, int, int] | None:
        x0, y0 = max(int(np.floor(lo[0])), 0), max(int(np.floor(lo[1])), 0)
        x1, y1 = min(int(np.ceil(hi[0])) + 1, self.width), min(int(np.ceil(hi[1])) + 1, self.height)
        return (x0, y0, x1, y1) if x0 < x1 and y0 < y1 else None

    def _blend(self, box: tuple[int, int, int, int], alpha: np.ndarray, colour: np.ndarray) -> None:
        x0, y0, x1, y1 = box
        region = self.image[y0:y1, x0:x1]
        region += alpha[..., None] * (colour - region)

    def capsule(self, a: np.ndarray, b: np.ndarray, width: float, colour: RGB) -> None:
        """A rounded segment from ``a`` to ``b`` (pixels), shaded like a cylinder lit from the upper left."""
        r = max(width / 2.0, 0.75)
        box = self._box(np.minimum(a, b) - r - 1, np.maximum(a, b) + r + 1)
        if box is None:
            return
        x0, y0, x1, y1 = box
        ys, xs = np.mgrid[y0:y1, x0:x1].astype(np.float32)
        ab = b - a
        length2 = float(ab @ ab) or 1e-6
        t = np.clip(((xs - a[0]) * ab[0] + (ys - a[1]) * ab[1]) / length2, 0.0, 1.0)
        dx, dy = xs - (a[0] + t * ab[0]), ys - (a[1] + t * ab[1])
        alpha = np.clip(r - np.sqrt(dx * dx + dy * dy) + 0.5, 0.0, 1.0)
        normal = np.array([-ab[1], ab[0]]) / np.sqrt(length2) if length2 > 1e-6 else _LIGHT
        if normal @ _LIGHT < 0:
            normal = -normal
        u = np.clip((dx * normal[0] + dy * normal[1]) / r, -1.0, 1.0)  # +1 on the lit edge, -1 on the dark one
        brightness = 0.78 + 0.2 * u + 0.12 * np.sqrt(1.0 - u * u) - 0.12
        self._blend(box, alpha, brightness[..., None] * np.asarray(colour, np.float32))

    def polygon(self, points: np.ndarray, colour: RGB, axis: np.ndarray, centre: np.ndarray, half_width: float) -> None:
        """A filled, anti-aliased polygon, darker towards its sides across ``axis`` (a unit vector) from
        ``centre``, as a rounded torso would be."""
        box = self._box(points.min(axis=0) - 1, points.max(axis=0) + 1)
        if box is None:
            return
        x0, y0, x1, y1 = box
        mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
        local = np.round((points - (x0, y0)) * (1 << _SHIFT)).astype(np.int32)
        cv2.fillPoly(mask, [local], 255, lineType=cv2.LINE_AA, shift=_SHIFT)
        ys, xs = np.mgrid[y0:y1, x0:x1].astype(np.float32)
        u = np.clip(((xs - centre[0]) * axis[0] + (ys - centre[1]) * axis[1]) / max(half_width, 1.0), -1.0, 1.0)
        brightness = 0.95 - 0.3 * u * u + 0.08 * (u * np.sign(axis @ _LIGHT))
        self._blend(box, mask.astype(np.float32) / 255.0, brightness[..., None] * np.asarray(colour, np.float32))

    def ellipse(self, centre: np.ndarray, radii: tuple[float, float], angle: float, colour: RGB,
                opacity: float = 1.0, soft: bool = False) -> None:
        """A filled ellipse rotated by ``angle`` radians; ``soft`` fades it out from the centre (shadows)."""
        reach = max(radii) + 1
        box = self._box(centre - reach, centre + reach)
        if box is None:
            return
        x0, y0, x1, y1 = box
        ys, xs = np.mgrid[y0:y1, x0:x1].astype(np.float32)
        c, s = np.cos(angle), np.sin(angle)
        px, py = xs - centre[0], ys - centre[1]
        along, across = (px * c + py * s) / max(radii[0], 0.5), (-px * s + py * c) / max(radii[1], 0.5)
        rho = np.sqrt(along * along + across * across)
        if soft:
            alpha = np.clip(1.0 - rho * rho, 0.0, 1.0)
        else:
            alpha = np.clip((1.0 - rho) * min(radii) + 0.5, 0.0, 1.0)
        self._blend(box, opacity * alpha, np.asarray(colour, np.float32))


def _joint(kp: np.ndarray, name: str) -> np.ndarray | None:
    j = JOINT_INDEX[name]
    return kp[j, :2] if kp[j, 2] >= MIN_CONFIDENCE else None


def _segment(painter: _Painter, kp: np.ndarray, a: str, b: str, width: float, colour: RGB) -> None:
    pa, pb = _joint(kp, a), _joint(kp, b)
    if pa is not None and pb is not None:
        painter.capsule(pa, pb, width, colour)


def _draw_arm(painter: _Painter, kp: np.ndarray, side: str, scale: float, look: PersonAppearance) -> None:
    upper = look.shirt
    lower = look.shirt if look.long_sleeves else look.skin
    _segment(painter, kp, f"{side}Shoulder", f"{side}Elbow", look.upper_arm_width * scale, upper)
    _segment(painter, kp, f"{side}Elbow", f"{side}Wrist", look.forearm_width * scale, lower)
    wrist = _joint(kp, f"{side}Wrist")
    if wrist is not None:
        painter.ellipse(wrist, (0.12 * scale, 0.12 * scale), 0.0, look.skin)  # the hand


def _draw_leg(painter: _Painter, kp: np.ndarray, side: str, scale: float, look: PersonAppearance) -> None:
    _segment(painter, kp, f"{side}Hip", f"{side}Knee", look.thigh_width * scale, look.trousers)
    _segment(painter, kp, f"{side}Knee", f"{side}Ankle", look.shin_width * scale,
             look.skin if look.shorts else look.trousers)
    foot = look.foot_width * scale
    _segment(painter, kp, f"{side}Heel", f"{side}BigToe", foot, look.shoes)
    _segment(painter, kp, f"{side}Ankle", f"{side}BigToe", foot, look.shoes)
    _segment(painter, kp, f"{side}Ankle", f"{side}Heel", foot, look.shoes)


def _draw_torso(painter: _Painter, kp: np.ndarray, scale: float, look: PersonAppearance) -> None:
    neck, hip = _joint(kp, "Neck"), _joint(kp, "MidHip")
    if neck is None or hip is None:
        return
    down = hip - neck
    down = down / (np.linalg.norm(down) or 1.0)
    across = np.array([-down[1], down[0]])
    # Missing shoulders/hips are guessed at typical offsets from Neck/MidHip so the torso is still drawn.
    r_sh = _joint(kp, "RShoulder")
    l_sh = _joint(kp, "LShoulder")
    r_hip, l_hip = _joint(kp, "RHip"), _joint(kp, "LHip")
    r_sh = neck - 0.35 * scale * across if r_sh is None else r_sh
    l_sh = neck + 0.35 * scale * across if l_sh is None else l_sh
    r_hip = hip - 0.2 * scale * across if r_hip is None else r_hip
    l_hip = hip + 0.2 * scale * across if l_hip is None else l_hip
    margin = look.torso_margin * scale
    centre = (neck + hip) / 2
    points = [r_sh, l_sh, l_hip, r_hip]
    grown = np.array([p + margin * (p - centre) / (np.linalg.norm(p - centre) or 1.0) for p in points])
    half = max(np.linalg.norm(l_sh - r_sh), np.linalg.norm(l_hip - r_hip)) / 2 + margin
    hips = np.array([r_hip, l_hip])
    pelvis = np.array([hips[0] - margin * across, hips[1] + margin * across,
                       hips[1] + 0.25 * scale * down, hips[0] + 0.25 * scale * down])
    painter.polygon(pelvis, look.trousers, across, hip, half)
    painter.polygon(grown, look.shirt, across, centre, half)


def _draw_head(painter: _Painter, kp: np.ndarray, scale: float, look: PersonAppearance) -> None:
    neck, nose = _joint(kp, "Neck"), _joint(kp, "Nose")
    if neck is None:
        return
    ears = [p for p in (_joint(kp, "REar"), _joint(kp, "LEar")) if p is not None]
    up = (nose - neck) if nose is not None else np.array([0.0, -1.0])
    up = up / (np.linalg.norm(up) or 1.0)
    r = look.head_height * scale / 2
    if ears:
        centre = np.mean(ears, axis=0)
    elif nose is not None:
        centre = nose - 0.15 * r * up
    else:
        centre = neck + 1.1 * r * up
    painter.capsule(neck, centre, look.neck_width * scale, look.skin)
    angle = float(np.arctan2(up[1], up[0]))
    painter.ellipse(centre + 0.12 * r * up, (1.08 * r, 0.86 * r), angle, look.hair)
    painter.ellipse(centre - 0.1 * r * up, (0.9 * r, 0.72 * r), angle, look.skin)
    for eye in ("REye", "LEye"):
        p = _joint(kp, eye)
        if p is not None:
            painter.ellipse(p, (0.07 * r, 0.07 * r), 0.0, (40, 30, 30))


def _near_side(kp: np.ndarray) -> str:
    """The side nearer the camera ("R" or "L"), judged by which ear the pose estimator saw more surely."""
    return "R" if kp[JOINT_INDEX["REar"], 2] >= kp[JOINT_INDEX["LEar"], 2] else "L"


def render_pose(background: np.ndarray, kp: np.ndarray, scale: float, look: PersonAppearance) -> np.ndarray:
    """Draw the person for one ``[25, 3]`` pose (pixels of the background) over a float32 background copy;
    returns RGB uint8. ``scale`` is the body scale in pixels."""
    painter = _Painter(background.copy())
    feet = [p for p in (_joint(kp, n) for n in ("RAnkle", "LAnkle", "RHeel", "LHeel")) if p is not None]
    if feet:
        feet_arr = np.array(feet)
        painter.ellipse(np.array([feet_arr[:, 0].mean(), feet_arr[:, 1].max() + 0.05 * scale]),
                        (0.6 * scale, 0.12 * scale), 0.0, (0, 0, 0), opacity=0.35, soft=True)
    near = _near_side(kp)
    far = "L" if near == "R" else "R"
    shoulders = _joint(kp, "RShoulder"), _joint(kp, "LShoulder")
    # Facing the camera, both arms usually move in front of the body; in profile the far arm is hidden behind it.
    profile = all(p is not None for p in shoulders) and np.linalg.norm(shoulders[0] - shoulders[1]) < 0.35 * scale
    if profile:
        _draw_arm(painter, kp, far, scale, look)
    _draw_leg(painter, kp, far, scale, look)
    _draw_leg(painter, kp, near, scale, look)
    _draw_torso(painter, kp, scale, look)
    _draw_head(painter, kp, scale, look)
    if not profile:
        _draw_arm(painter, kp, far, scale, look)
    _draw_arm(painter, kp, near, scale, look)
    return np.clip(painter.image + 0.5, 0, 255).astype(np.uint8)


def render_person(seq: PoseSequence, appearance: PersonAppearance, size: tuple[int, int] | None = None,
                  scale: float | None = None) -> Iterator[np.ndarray]:
    """One RGB uint8 frame per pose of ``seq``, streamed.

    Args:
        size: ``(width, height)`` of the frames in pixels; default the pose canvas. Another size scales the
            canvas into it keeping the aspect ratio (the room fills the whole frame).
        scale: body scale in canvas pixels (limb widths are relative to it); default
            :func:`dancesynth.core.skeleton.body_scale` of the sequence.
    """
    width, height = size if size is not None else (seq.width, seq.height)
    s, dx, dy = fit_to_canvas(seq.width, seq.height, width, height)
    body = (body_scale(seq) if scale is None else float(scale)) * s
    background = render_background(width, height, appearance)
    for kp in seq.keypoints:
        placed = kp.astype(np.float64)
        placed[:, :2] = kp[:, :2] * s + (dx, dy)
        yield render_pose(background, placed, body, appearance)


def write_person_video(seq: PoseSequence, path: str | os.PathLike, appearance: PersonAppearance,
                       audio: np.ndarray | None = None, audio_sr: int | None = None,
                       size: tuple[int, int] | None = None) -> None:
    """Write :func:`render_person`'s frames as an mp4 at the sequence's fps, optionally with the song
    (mono ``[N]`` samples at ``audio_sr`` Hz, cut or padded to the video's duration)."""
    width, height = size if size is not None else (seq.width, seq.height)
    with VideoWriter(path, seq.fps, width, height, audio=audio, audio_sr=audio_sr) as writer:
        for frame in render_person(seq, appearance, (width, height)):
            writer.write(frame)
