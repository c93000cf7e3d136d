"""Synthetic BODY_25 dances to a known beat grid, by forward kinematics of a 2D body seen from the front.

A dance is a sequence of moves from the style's vocabulary (:data:`MOVES`). A move is a few key poses, one per
segment of 1, 2 or 4 beats; each key pose is reached exactly on a music beat by a smooth (C2) trajectory that
speeds up and slows down within a fraction of a second (after a hold for hit-style moves), so the body stops
or turns sharply on those beats and glides through the others. Joint angles and root motion are then turned into
pixel positions with constant bone lengths; the root height keeps the lowest foot point on the floor (or above it
in a jump).

Angles are in radians in the image plane. Arm and leg angles are measured from straight down, positive away
from the body (an arm at pi/2 points sideways, at pi straight up); elbow angles add to the arm angle; knee
flexion bends the knees outwards (thigh at leg + knee/2, shin at leg - knee/2); ``lean``, ``head`` and
``pelvis`` tilt towards image right; ``shift`` (sideways root offset) and ``jump`` are in body heights.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dancesynth.core.skeleton import JOINT_INDEX, NUM_JOINTS, PoseSequence
from stage1_pose.data.layout import POSE_FPS
from stage1_pose.data.styles import Style

WIDTH, HEIGHT = 1280, 720
DOFS: tuple[str, ...] = ("lean", "head", "pelvis", "r_arm", "r_elbow", "l_arm", "l_elbow", "r_leg", "r_knee",
                         "l_leg", "l_knee", "r_foot", "l_foot", "shift", "jump")
_DOF = {name: i for i, name in enumerate(DOFS)}
# What mirroring a pose does: swap these pairs, negate the rest of the sideways quantities.
_MIRROR_SWAP = (("r_arm", "l_arm"), ("r_elbow", "l_elbow"), ("r_leg", "l_leg"), ("r_knee", "l_knee"),
                ("r_foot", "l_foot"))
_MIRROR_NEGATE = ("lean", "head", "pelvis", "shift")

# Standing poses each style returns to (DOFs not listed are 0).
BASE_POSES: dict[str, dict[str, float]] = {
    "ballet": {"r_arm": 0.25, "l_arm": 0.25, "r_elbow": -0.5, "l_elbow": -0.5, "r_leg": 0.08, "l_leg": 0.08},
    "hiphop": {"r_arm": 0.2, "l_arm": 0.2, "r_elbow": -0.6, "l_elbow": -0.6, "r_leg": 0.14, "l_leg": 0.14,
               "r_knee": 0.25, "l_knee": 0.25},
    "pop": {"r_arm": 0.15, "l_arm": 0.15, "r_elbow": -0.3, "l_elbow": -0.3, "r_leg": 0.1, "l_leg": 0.1,
            "r_knee": 0.1, "l_knee": 0.1},
}


def _both(**kw: float) -> dict[str, float]:
    """Give ``arm=..``, ``elbow=..`` etc. to both sides."""
    return {f"{side}_{k}": v for k, v in kw.items() for side in ("r", "l")}


_CLAP = _both(arm=0.3, elbow=-2.2)
# Each move is a tuple of key poses, one per segment; a key pose overrides some DOFs of the base pose
# (the rest return to it). Moves are written for the right side and mirrored at random.
MOVES: dict[str, tuple[dict[str, float], ...]] = {
    # ballet: slow, sustained arm arcs and leg extensions
    "port_de_bras": (_both(arm=1.2, elbow=-0.3), _both(arm=2.7, elbow=-0.5), _both(arm=1.5, elbow=0.1), {}),
    "plie": ({**_both(knee=0.8, leg=0.3, arm=1.4, elbow=-0.2)}, _both(arm=1.4, elbow=-0.2)),
    "arabesque_arms": ({"r_arm": 2.4, "r_elbow": -0.2, "l_arm": 1.4, "lean": -0.1, "head": -0.15},
                       {"r_arm": 2.4, "l_arm": 1.4, "lean": -0.15, "l_leg": 0.6, "l_foot": 0.8}, {}),
    "tendu": ({"r_leg": 0.45, "r_foot": 1.0, **_both(arm=1.5)}, _both(arm=1.5),
              {"l_leg": 0.45, "l_foot": 1.0, **_both(arm=1.5)}, {}),
    "cambre": ({"lean": 0.3, "head": 0.2, "l_arm": 2.8, "r_arm": 0.6},
               {"lean": -0.3, "head": -0.2, "r_arm": 2.8, "l_arm": 0.6}, {}),
    "arm_wave": ({**_both(arm=1.6), "r_elbow": 0.5, "l_elbow": -0.5},
                 {**_both(arm=1.6), "r_elbow": -0.5, "l_elbow": 0.5},
                 {**_both(arm=1.6), "r_elbow": 0.5, "l_elbow": -0.5}, {}),
    "bras_ouverts": (_both(arm=1.3, elbow=-0.1), {**_both(arm=2.0, foot=0.5), "head": 0.1}, {}),
    # hip-hop: knee bounces, arm hits, points and steps
    "bounce_hit": (_both(knee=0.6, arm=0.5, elbow=-1.2), {}, _both(knee=0.6, arm=0.5, elbow=-1.2), {}),
    "arm_cross": (_both(arm=0.6, elbow=-2.0), _both(arm=1.5, elbow=0.0), _both(arm=0.6, elbow=-2.0), {}),
    "point": ({"r_arm": 2.3, "r_elbow": 0.0, "l_arm": 0.3, "l_elbow": -1.4, "lean": 0.12, **_both(knee=0.4)},
              {"r_arm": 0.9, "r_elbow": -0.3, "lean": -0.05}, {"r_arm": 2.3, "r_elbow": 0.0, "lean": 0.12}, {}),
    "chest_pop": ({"lean": 0.15, "head": 0.2, **_both(arm=0.4, elbow=-1.5)},
                  {"lean": -0.15, "head": -0.2, **_both(arm=0.4, elbow=-1.5)},
                  {"lean": 0.15, "head": 0.2, **_both(arm=0.4, elbow=-1.5)}, {}),
    "side_step": ({"shift": 0.2, "r_leg": 0.35, "l_knee": 0.4, "r_arm": 0.8, "r_elbow": -1.0},
                  {"shift": 0.2, **_both(knee=0.4)}, {"shift": 0.0, "l_leg": 0.35, "r_knee": 0.4}, {}),
    "arm_wave_hit": ({"r_arm": 1.6, "r_elbow": 0.6, "l_arm": 0.3}, {**_both(arm=1.6), "r_elbow": -0.4, "l_elbow": 0.6},
                     {"l_arm": 1.6, "l_elbow": -0.4, "r_arm": 0.3}, {}),
    "squat_hold": (_both(knee=1.2, leg=0.4, arm=0.7, elbow=-1.6), _both(knee=1.2, leg=0.4, arm=0.7, elbow=-1.6), {}),
    # pop: claps, jumps, steps and arm pumps
    "clap": (_CLAP, _both(arm=1.0, elbow=0.2), _CLAP, {}),
    "jump": ({"jump": 0.12, **_both(knee=0.1, arm=2.6, foot=0.7)}, _both(knee=0.5)),
    "step_clap": ({"shift": 0.12, "r_leg": 0.3, **_CLAP}, {"shift": 0.12, **_both(arm=1.0)},
                  {"shift": 0.0, "l_leg": 0.3, **_CLAP}, {}),
    "arm_pump": ({"r_arm": 2.9, "r_elbow": 0.0}, {"r_arm": 1.2, "r_elbow": -1.2}, {"r_arm": 2.9, "r_elbow": 0.0}, {}),
    "disco_point": ({"r_arm": 2.5, "r_elbow": 0.0, "lean": 0.1}, {"r_arm": 0.4, "r_elbow": -1.0, "lean": -0.05},
                    {"r_arm": 2.5, "r_elbow": 0.0, "lean": 0.1}, {}),
    "jumping_jack": ({"jump": 0.05, **_both(leg=0.35, arm=2.7)}, {}),
    "hip_sway": ({"pelvis": 0.12, "lean": -0.08, "shift": 0.05, **_both(arm=0.6, elbow=-1.0)},
                 {"pelvis": -0.12, "lean": 0.08, "shift": -0.05, **_both(arm=0.6, elbow=-1.0)}),
}
# Chance that a move is followed by a held beat (the dancer stays still through it).
HOLD_PROBABILITY = 0.1


@dataclass(frozen=True)
class Body:
    """Body proportions in pixels: ``height`` (floor to top of head) and segment lengths.

    Attributes:
        height: standing height.
        torso: MidHip to Neck; shoulder, hip: half widths; upper_arm, forearm, thigh, shin: limb lengths;
        neck: Neck to Nose. Head and foot points sit at fixed fractions of ``height`` from the nose / ankle.
    """

    height: float
    torso: float
    shoulder: float
    hip: float
    upper_arm: float
    forearm: float
    thigh: float
    shin: float
    neck: float


# Segment lengths as fractions of height (anthropometric averages; joint centres, front view).
_PROPORTIONS = {"torso": 0.29, "shoulder": 0.12, "hip": 0.085, "upper_arm": 0.186, "forearm": 0.16,
                "thigh": 0.245, "shin": 0.246, "neck": 0.11}


def random_body(rng: np.random.Generator) -> Body:
    """A body 330-470 px tall with each segment length within +-8 % of the average proportion."""
    height = float(rng.uniform(330, 470))
    limb = float(rng.uniform(0.95, 1.05))  # long- or short-limbed
    limbs = ("upper_arm", "forearm", "thigh", "shin")
    sizes = {k: height * v * float(rng.uniform(0.92, 1.08)) * (limb if k in limbs else 1)
             for k, v in _PROPORTIONS.items()}
    return Body(height=height, **sizes)


def _pose_vector(base: dict[str, float], key: dict[str, float], amplitude: float, mirror: bool) -> np.ndarray:
    q = np.zeros(len(DOFS))
    for name, v in base.items():
        q[_DOF[name]] = v
    for name, v in key.items():
        q[_DOF[name]] += amplitude * (v - q[_DOF[name]])
    if mirror:
        for a, b in _MIRROR_SWAP:
            ia, ib = _DOF[a], _DOF[b]
            q[ia], q[ib] = q[ib], q[ia]
        for name in _MIRROR_NEGATE:
            q[_DOF[name]] = -q[_DOF[name]]
    return q


def choreograph(style: Style, beats: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Key poses of a random dance: ``times`` ``[K]`` seconds (0, then music beats) and ``poses`` ``[K, len(DOFS)]``.

    Moves are drawn from the style's vocabulary with random segment length, amplitude (0.7-1.2) and mirroring;
    every key pose falls on a beat.
    """
    base = BASE_POSES[style.name]
    rest = _pose_vector(base, {}, 1.0, False)
    times, poses = [0.0], [rest]
    i = 0
    while True:
        key_poses = MOVES[style.moves[rng.integers(len(style.moves))]]
        seg = int(rng.choice(style.segment_beats))
        amplitude, mirror = float(rng.uniform(0.7, 1.2)), bool(rng.random() < 0.5)
        if rng.random() < HOLD_PROBABILITY:
            key_poses = (*key_poses, key_poses[-1])
        for key in key_poses:
            i += seg
            if i >= len(beats):
                return np.array(times), np.array(poses)
            times.append(float(beats[i]))
            poses.append(_pose_vector(base, key, amplitude, mirror))


def _segment_profile(u: np.ndarray, seconds: np.ndarray, ramp: float) -> np.ndarray:
    """Progress ``[0, 1]`` along a segment at fractions ``u`` of its duration ``seconds``: rest, a smoothstep
    speed-up of ``ramp`` seconds, constant speed, a smoothstep slow-down of ``ramp`` seconds, rest.
    Velocity is continuous and zero at both ends (the integral of a smoothstep-edged plateau)."""
    r = np.clip(ramp / np.maximum(seconds, 1e-9), 1e-6, 0.5)

    def ramp_integral(x: np.ndarray) -> np.ndarray:  # integral of smoothstep(x / r) from 0 to x, for 0 <= x <= r
        z = np.clip(x / r, 0.0, 1.0)
        return r * (z**3 - z**4 / 2)

    # speed(u) = smoothstep(u / r) * smoothstep((1 - u) / r): each ramp covers r / 2, the plateau 1 - 2 r
    u = np.clip(u, 0.0, 1.0)
    distance = np.select([u <= r, u <= 1 - r],
                         [ramp_integral(u), r / 2 + (u - r)],
                         1 - r - ramp_integral(np.clip(1 - u, 0.0, r)))
    return distance / (1 - r)


def angle_trajectories(style: Style, times: np.ndarray, poses: np.ndarray, beats: np.ndarray,
                       num_frames: int, fps: float = POSE_FPS) -> np.ndarray:
    """DOF values at each pose frame, ``[num_frames, len(DOFS)]``.

    Between key poses: a hold for ``style.hit_fraction`` of the segment, then :func:`_segment_profile` with
    ``style.ramp`` second speed ramps. On top: the style's knee bounce peaking on every beat and a hip sway
    whose direction changes on every beat. Frame ``i`` is at ``i / fps`` seconds.
    """
    t = np.arange(num_frames) / fps
    seg = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 1)
    nxt = np.minimum(seg + 1, len(times) - 1)
    span = np.maximum(times[nxt] - times[seg], 1e-9)
    u = np.clip((t - times[seg]) / span, 0.0, 1.0)
    h = style.hit_fraction
    s = _segment_profile(np.clip((u - h) / (1 - h), 0.0, 1.0), span * (1 - h), style.ramp)
    s = np.where(nxt == seg, 0.0, s)
    q = poses[seg] + (poses[nxt] - poses[seg]) * s[:, None]
    if len(beats) > 1:
        period = float(np.median(np.diff(beats)))
        near = np.abs(t[:, None] - beats[None, :]).min(axis=1)
        bounce = style.bounce * np.exp(-0.5 * (near / (0.2 * period)) ** 2)
        q[:, _DOF["r_knee"]] += bounce
        q[:, _DOF["l_knee"]] += bounce
        q[:, _DOF["shift"]] -= style.sway * np.cos(np.pi * (t - beats[0]) / period)
    return q


def _rot(x: np.ndarray, y: np.ndarray, angle: np.ndarray, side: float) -> np.ndarray:
    """A vector given as (outward, down) components, turned outwards by ``angle``, in image (x, y) for ``side``
    (-1 = the dancer's right, which is image left when facing the camera)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([side * (x * c + y * s), -x * s + y * c], axis=-1)


def forward_kinematics(q: np.ndarray, body: Body, floor_y: float, center_x: float) -> np.ndarray:
    """``[T, len(DOFS)]`` DOF values -> ``[T, 25, 2]`` BODY_25 pixel positions (constant bone lengths).

    The root's height is chosen so that the lowest foot point is on ``floor_y`` (or ``jump`` body heights above
    it); ``center_x`` is the root's x at zero shift.
    """
    T = len(q)
    d = {name: q[:, i] for i, name in enumerate(DOFS)}
    down = (np.zeros(T), np.ones(T))
    P = np.zeros((T, NUM_JOINTS, 2))
    J = JOINT_INDEX
    lean = d["lean"]
    up = np.stack([np.sin(lean), -np.cos(lean)], -1)
    across = np.stack([np.cos(lean), np.sin(lean)], -1)
    pelvis_across = np.stack([np.cos(d["pelvis"]), np.sin(d["pelvis"])], -1)
    P[:, J["Neck"]] = body.torso * up
    for side, name in ((-1.0, "R"), (1.0, "L")):
        pre = "r" if side < 0 else "l"
        shoulder = P[:, J["Neck"]] + side * body.shoulder * across
        # arm angles are relative to the torso: turn the (outward, down) direction by the lean as well
        arm_dir = _rot(*down, d[f"{pre}_arm"], side)
        fore_dir = _rot(*down, d[f"{pre}_arm"] + d[f"{pre}_elbow"], side)
        elbow = shoulder + body.upper_arm * _turn(arm_dir, lean)
        P[:, J[f"{name}Shoulder"]] = shoulder
        P[:, J[f"{name}Elbow"]] = elbow
        P[:, J[f"{name}Wrist"]] = elbow + body.forearm * _turn(fore_dir, lean)
        hip = side * body.hip * pelvis_across
        thigh = d[f"{pre}_leg"] + d[f"{pre}_knee"] / 2
        shin = d[f"{pre}_leg"] - d[f"{pre}_knee"] / 2
        knee = hip + body.thigh * _rot(*down, thigh, side)
        ankle = knee + body.shin * _rot(*down, shin, side)
        foot_turn = shin + 0.4 * d[f"{pre}_foot"]
        P[:, J[f"{name}Hip"]] = hip
        P[:, J[f"{name}Knee"]] = knee
        P[:, J[f"{name}Ankle"]] = ankle
        for joint, (x, y) in (("BigToe", (0.012, 0.05)), ("SmallToe", (0.04, 0.045)), ("Heel", (-0.004, 0.035))):
            P[:, J[f"{name}{joint}"]] = ankle + body.height * _rot(np.full(T, x), np.full(T, y), foot_turn, side)
    head = lean + d["head"]
    nose = P[:, J["Neck"]] + body.neck * np.stack([np.sin(head), -np.cos(head)], -1)
    P[:, J["Nose"]] = nose
    for side, name in ((-1.0, "R"), (1.0, "L")):
        for joint, (x, y) in (("Eye", (0.025, -0.025)), ("Ear", (0.06, -0.005))):
            local = np.stack([side * x * body.height * np.ones(T), y * body.height * np.ones(T)], -1)
            P[:, J[f"{name}{joint}"]] = nose + _turn(local, head)
    feet = [J[f"{s}{j}"] for s in "RL" for j in ("Ankle", "BigToe", "SmallToe", "Heel")]
    lowest = P[:, feet, 1].max(axis=1)
    root_y = floor_y - lowest - d["jump"] * body.height
    root_x = center_x + d["shift"] * body.height
    P[..., 0] += root_x[:, None]
    P[..., 1] += root_y[:, None]
    return P


def _turn(v: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotate ``[T, 2]`` image vectors by ``angle`` (positive turns up into right)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1]], -1)


def synthesize_dance(style: Style, beats: np.ndarray, num_frames: int, rng: np.random.Generator,
                     fps: float = POSE_FPS) -> PoseSequence:
    """A random ``num_frames``-frame dance in ``style`` to beats at ``beats`` seconds, on a 1280x720 canvas at
    ``fps`` with a random body, position and floor height; every joint has confidence 1."""
    body = random_body(rng)
    floor_y = HEIGHT - float(rng.uniform(30, 80))
    center_x = WIDTH / 2 + float(rng.uniform(-150, 150))
    times, poses = choreograph(style, beats, rng)
    q = angle_trajectories(style, times, poses, beats, num_frames, fps)
    xy = forward_kinematics(q, body, floor_y, center_x)
    kp = np.concatenate([xy, np.ones((num_frames, NUM_JOINTS, 1))], axis=-1)
    return PoseSequence(kp, fps, WIDTH, HEIGHT)
