"""A catalogue of bad input, run through the CLI: each case ends with exit status 1, one error line on stderr,
no traceback, and no file written or left anywhere (outputs, inputs, datasets, run folders)."""

import contextlib
import errno
import io
import json
import os
import pickle
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import soundfile
import torch

from apps.cli import main
from dancesynth.core.draw import draw_pose
from dancesynth.core.media import write_video
from dancesynth.core.skeleton import PoseSequence

SR = 22050
OUT_OF_RANGE = [
    # (command line, what the message says); {in} holds the inputs, {out} is an empty output folder
    *[(["train-pose", "--method", "lstm", "--data", "{data}", "--out", "{out}/run", flag, value], says)
      for flag, value, says in [
          ("--batch-size", "0", "--batch-size: must be positive"), ("--epochs", "-1", "--epochs: must be positive"),
          ("--window", "0", "--window: must be positive"), ("--checkpoint-every", "0", "must be positive"),
          ("--minutes", "nan", "must be a finite number"), ("--minutes", "-5", "must be positive"),
          ("--seed", "-1", "--seed: must be 0 or more"), ("--workers", "-2", "must be 0 or more"),
          ("--epochs", "2.5", "must be a whole number"), ("--epochs", "99999999999", "must be at most"),
          ("--preview-every", "-1", "must be 0 or more"), ("--preview-gap", "inf", "must be a finite number")]],
    *[(["train-video", "{in}/video.mp4", "--out", "{out}/run", flag, value], says) for flag, value, says in [
        ("--batch-size", "0", "must be positive"), ("--epochs", "0", "must be positive"),
        ("--threads", "0", "must be positive"), ("--checkpoint-every", "0", "must be positive"),
        ("--sample-every", "-5", "must be positive"), ("--minutes", "-1", "must be positive"),
        ("--minutes", "inf", "must be a finite number"), ("--seed", "x", "must be a whole number")]],
    *[(["dance", "{in}/song.wav", "--pose-model", "{stage1}", "--video-model", "{stage2}", "--out", "{out}/d.mp4",
        flag, value], says) for flag, value, says in [
        ("--duration", "-1", "must be positive"), ("--duration", "0", "must be positive"),
        ("--start", "-0.5", "must be 0 or more"), ("--seed", "abc", "must be a whole number")]],
    *[(["make-dataset", "--out", "{out}/ds", flag, value], says) for flag, value, says in [
        ("--clips", "0", "must be positive"), ("--seconds", "-1", "must be positive"),
        ("--workers", "0", "must be positive"), ("--seconds", "nan", "must be a finite number")]],
    *[(["evaluate", "--data", "{data}", "--out", "{out}/report", flag, value], says) for flag, value, says in [
        ("--trials", "0", "must be positive"), ("--seconds", "0", "must be positive"),
        ("--tolerance", "-1", "must be 0 or more"), ("--video-seconds", "nan", "must be a finite number")]],
    *[(["extract-poses", "{in}/video.mp4", "--out", "{out}/p.npz", flag, value], says) for flag, value, says in [
        ("--window", "0", "must be positive"), ("--min-visibility", "1.5", "must be between 0 and 1"),
        ("--max-missing", "-0.1", "must be between 0 and 1"), ("--beta", "-1", "must be 0 or more")]],
    *[(["import-dance", "--out", "{out}/ds", "--aistpp", "{in}/gPO_x.npy", "--audio", "{in}/song.wav", flag, value],
       says) for flag, value, says in [
        ("--fps", "0", "must be positive"), ("--width", "0", "must be positive"),
        ("--view", "-1", "must be 0 or more")]],
    (["render", "{in}/poses.npz", "--model", "{stage2}", "--out", "{out}/r.mp4", "--threads", "0"], "must be positive"),
    (["prepare", "{in}/videos", "--out", "{out}/ds", "--clip-seconds", "-1"], "must be positive"),
    (["train-stgcn", "--data", "{data}", "--out", "{out}/st", "--epochs", "0"], "must be positive"),
    (["train-style-classifier", "--data", "{data}", "--out", "{out}/c", "--steps", "0"], "must be positive"),
    (["generate", "{in}/song.wav", "--model", "{stage1}", "--out", "{out}/p.npz", "--seed", "-3"], "must be 0 or more"),
    (["demo", "--out", "{out}/demo", "--minutes", "0"], "must be positive"),
    (["check", "{stage1}", "--clips", "0"], "must be positive"),
    (["check", "{stage1}", "--seeds", "0", "-1"], "must be 0 or more"),
]
RENDER = ["--model", "{stage2}", "--out", "{out}/r.mp4"]
TRAIN_VIDEO = ["--out", "{out}/run", "--epochs", "1"]
FOLDER_FOR_FILE = [
    (["render", "{in}/folder", *RENDER], "{in}/folder is a folder, not a file"),
    (["generate", "{in}/folder", "--model", "{stage1}", "--out", "{out}/p.npz"], "is a folder, not a file"),
    (["dance", "{in}/folder", "--pose-model", "{stage1}", "--video-model", "{stage2}", "--out", "{out}/d.mp4"],
     "is a folder, not a file"),
    (["train-video", "{in}/folder", *TRAIN_VIDEO], "is a folder, not a file"),
    (["render", "{in}/poses.npz", *RENDER, "--audio", "{in}/folder"], "is a folder, not a file"),
    (["train-video", "{in}/video.mp4", *TRAIN_VIDEO, "--poses", "{in}/folder"], "is a folder, not a file"),
    (["train-video", "{in}/video.mp4", *TRAIN_VIDEO, "--vgg-weights", "{in}/folder"], "is a folder, not a file"),
    (["import-dance", "--out", "{out}/ds", "--aistpp", "{in}/folder", "--audio", "{in}/song.wav"],
     "is a folder, not a file"),
    (["extract-poses", "{in}/folder", "--out", "{out}/p.npz"], "is a folder, not a file"),
    (["render", "{in}/poses.npz", "--model", "{stage2}", "--out", "{out}"], "is a folder; give the path of the file"),
    (["generate", "{in}/song.wav", "--model", "{stage1}", "--out", "{out}"], "is a folder; give the path"),
    (["generate", "{in}/song.wav", "--model", "{stage1}", "--out", "{out}/p.npz", "--preview", "{out}"],
     "is a folder; give the path"),
    (["dance", "{in}/song.wav", "--pose-model", "{stage1}", "--video-model", "{stage2}", "--out", "{out}"],
     "is a folder; give the path"),
    (["dance", "{in}/song.wav", "--pose-model", "{stage1}", "--video-model", "{stage2}", "--out", "{out}/d.mp4",
      "--side-by-side", "{out}"], "is a folder; give the path"),
    (["extract-poses", "{in}/video.mp4", "--out", "{out}"], "is a folder; give the path"),
    (["check", "{stage1}", "--json", "{out}"], "is a folder; give the path"),
]
FILE_FOR_FOLDER = [
    (["train-pose", "--method", "lstm", "--data", "{data}", "--out", "{in}/a_file.txt"], "is a file, not a folder"),
    (["train-pose", "--method", "lstm", "--data", "{data}", "--out", "{in}/a_file.txt/run"], "is a file, not a folder"),
    (["make-dataset", "--out", "{in}/a_file.txt"], "is a file, not a folder"),
    (["evaluate", "--data", "{data}", "--out", "{in}/a_file.txt"], "is a file, not a folder"),
    (["train-video", "{in}/video.mp4", "--out", "{in}/a_file.txt", "--epochs", "1"], "is a file, not a folder"),
    (["prepare", "{in}/videos", "--out", "{in}/a_file.txt"], "is a file, not a folder"),
    (["train-style-classifier", "--data", "{data}", "--out", "{in}/a_file.txt"], "is a file, not a folder"),
    (["train-pose", "--method", "lstm", "--data", "{in}/a_file.txt", "--out", "{out}/run", "--epochs", "1"],
     "is a file, not a dataset folder"),
]
MISSING_OR_UNREADABLE = [
    (["render", "{in}/missing.npz", *RENDER], "missing.npz does not exist"),
    (["render", "{in}/poses.npz", "--model", "{stage2}", "--out", "{out}/no/such/r.mp4"], "does not exist"),
    (["generate", "{in}/song.wav", "--model", "{stage1}", "--out", "{out}/no/p.npz"], "does not exist"),
    (["train-video", "{in}/missing.mp4", *TRAIN_VIDEO], "does not exist"),
    (["render", "{in}/empty.npz", *RENDER], "is empty (0 bytes)"),
    (["train-video", "{in}/video.mp4", *TRAIN_VIDEO, "--poses", "{in}/empty.npz"], "is empty (0 bytes)"),
    (["generate", "{in}/empty.wav", "--model", "{stage1}", "--out", "{out}/p.npz"], "is empty (0 bytes)"),
    (["render", "{in}/garbage.npz", *RENDER], "not a dancesynth pose file"),
    (["render", "{in}/song.wav", *RENDER], "not a dancesynth pose file"),
    (["render", "{in}/truncated.npz", *RENDER], "not a dancesynth pose file"),
    (["train-pose", "--method", "lstm", "--data", "{in}/ds_empty_poses", "--out", "{out}/run", "--epochs", "1"],
     "not a dancesynth pose file"),
    (["import-dance", "--out", "{out}/ds", "--aistpp", "{in}/gPO_x.npy", "--audio", "{in}/nan.wav"], "not finite"),
    (["import-dance", "--out", "{out}/ds", "--aistpp", "{in}/gPO_x.npy", "--audio", "{in}/huge.wav"], "not finite"),
    (["import-dance", "--out", "{out}/ds", "--aistpp", "{in}/gPO_x.npy", "--audio", "{in}/garbage.npz"],
     "not a readable audio"),
]
BAD_DATASETS = [
    *[(["train-pose", "--method", "lstm", "--data", "{in}/" + name, "--out", "{out}/run", "--epochs", "1"], says)
      for name, says in [("ds_up", "Clip 'clip0' in"), ("ds_absolute", "its poses at"),
                         ("ds_link", "outside the dataset folder"), ("ds_id", "'../../../X' in"),
                         ("ds_features", "features links outside the dataset")]],
    (["evaluate", "--data", "{in}/ds_up", "--out", "{out}/report"], "outside the dataset folder"),
    (["train-style-classifier", "--data", "{in}/ds_id", "--out", "{out}/c"], "is not a plain name"),
]
WRONG_RUNS = [
    (["render", "{in}/poses.npz", "--model", "{stage1}", "--out", "{out}/r.mp4"], "is a pose model"),
    (["generate", "{in}/song.wav", "--model", "{stage2}", "--out", "{out}/p.npz"], "is an appearance model"),
    (["evaluate", "--data", "{data}", "--models", "{stage2}", "--out", "{out}/report"], "is an appearance model"),
    (["render", "{in}/poses.npz", "--model", "{in}/folder", "--out", "{out}/r.mp4"],
     "is not a finished dancesynth run"),
    (["generate", "{in}/song.wav", "--model", "{in}/missing", "--out", "{out}/p.npz"], "does not exist"),
    (["train-pose", "--method", "lstm", "--data", "{data}", "--out", "{stage2}", "--resume"],
     "is an appearance model"),
]
OUT_OF_RANGE += [
    (["train-pose", "--method", "lstm", "--data", "{data}", "--out", "{out}/run", "--checkpoint-every", "-1"],
     "must be positive"),
    (["train-pose", "--method", "lstm", "--data", "{data}", "--out", "{out}/run", "--batch-size", "2147483648"],
     "must be at most"),
    (["train-video", "{in}/video.mp4", "--out", "{out}/run", "--threads", "-1"], "must be positive"),
    (["train-video", "{in}/video.mp4", "--out", "{out}/run", "--epochs", "1", "--device", "cpu", "--precision",
      "fp16"], "--precision fp16 needs a CUDA GPU"),
    (["render", "{in}/poses.npz", "--model", "{stage2}", "--out", "{out}/r.mp4", "--device", "cpu", "--precision",
      "fp16"], "--precision fp16 needs a CUDA GPU"),
    (["render", "{in}/poses.npz", "--model", "{stage2}", "--out", "{out}/r.mp4", "--precision", "fp64"],
     "invalid choice"),
    (["dance", "{in}/song.wav", "--pose-model", "{stage1}", "--video-model", "{stage2}", "--out", "{out}/d.mp4",
      "--start", "nan"], "must be a finite number"),
    (["dance", "{in}/song.wav", "--pose-model", "{stage1}", "--video-model", "{stage2}", "--out", "{out}/d.mp4",
      "--duration", "inf"], "must be a finite number"),
    (["make-dataset", "--out", "{out}/ds", "--clips", "1e3"], "must be a whole number"),
    (["import-dance", "--out", "{out}/ds", "--aistpp", "{in}/gPO_x.npy", "--audio", "{in}/song.wav", "--fps", "nan"],
     "must be a finite number"),
    (["evaluate", "--data", "{data}", "--out", "{out}/report", "--tolerance", "inf"], "must be a finite number"),
]
GENERATE = ["--model", "{lstm}", "--out", "{out}/p.npz", "--device", "cpu"]
DANCE = ["--pose-model", "{lstm}", "--video-model", "{p2p}", "--out", "{out}/d.mp4", "--device", "cpu"]
BAD_AUDIO = [
    *[(["generate", "{in}/" + name, *GENERATE], says) for name, says in [
        ("nan.wav", "not finite"), ("inf.wav", "not finite"), ("huge.wav", "far beyond full scale"),
        ("loud.wav", "far beyond full scale"), ("silent.wav", "is silent"), ("short.wav", "is only 0.50 s long"),
        ("no_samples.wav", "no audio samples"), ("garbage.npz", "not a readable audio"),
        ("video_only.mp4", "has no audio stream")]],
    *[(["dance", "{in}/" + name, *DANCE], says) for name, says in [
        ("nan.wav", "not finite"), ("silent.wav", "is silent"), ("short.wav", "is only 0.50 s long")]],
    (["import-dance", "--out", "{out}/ds", "--aistpp", "{in}/gPO_x.npy", "--audio", "{in}/inf.wav"], "not finite"),
    (["import-dance", "--out", "{out}/ds", "--aistpp", "{in}/gPO_x.npy", "--audio", "{in}/silent.wav"], "is silent"),
]
SONG_SEGMENT = [  # a 10-s song
    (["dance", "{in}/song10.wav", *DANCE, "--start", "9.5"], "--start 9.5 s is too close to the end of the song, "
                                                             "which lasts 10.0 s"),
    (["dance", "{in}/song10.wav", *DANCE, "--start", "9.2", "--duration", "5"], "too close to the end"),
    (["dance", "{in}/song10.wav", *DANCE, "--start", "10"], "is outside the song, which lasts 10.0 s"),
    (["dance", "{in}/song10.wav", *DANCE, "--start", "12.5"], "is outside the song"),
    (["dance", "{in}/song10.wav", *DANCE, "--duration", "0.5"], "--duration 0.5 s is too short"),
]
RENDER_REAL = ["--model", "{p2p}", "--out", "{out}/r.mp4", "--device", "cpu", "--no-optimize"]
BAD_POSE_FILES = [
    *[(["render", "{in}/" + name, *RENDER_REAL], says) for name, says in [
        ("garbage.npz", "not a dancesynth pose file"), ("truncated.npz", "not a dancesynth pose file"),
        ("poses_coco18.npz", "not a dancesynth pose file"), ("poses_no_frames.npz", "holds no frames"),
        ("poses_nan.npz", "not finite"), ("poses_bad_fps.npz", "not a dancesynth pose file"),
        ("poses_bad_canvas.npz", "not a dancesynth pose file"), ("gPO_x.npy", "not a dancesynth pose file")]],
    (["train-video", "{in}/video.mp4", *TRAIN_VIDEO, "--poses", "{in}/garbage.npz"], "not a dancesynth pose file"),
    (["train-video", "{in}/video.mp4", *TRAIN_VIDEO, "--poses", "{in}/truncated.npz"], "not a dancesynth pose file"),
]
RESUME_LSTM = ["--method", "lstm", "--data", "{data}", "--resume", "--epochs", "2", "--preview-every", "0",
               "--device", "cpu"]
NOT_A_TRAINING_STATE = "training.pt is not a training state this program wrote"
DAMAGED_TRAINING_STATE = "training.pt does not fit the model it belongs to"
TRAINING_STATE_EDITS = {  # run name -> what `train-pose --resume` says
    "random_bytes": NOT_A_TRAINING_STATE, "malicious_pickle": NOT_A_TRAINING_STATE,
    "a_list": NOT_A_TRAINING_STATE, "no_state": NOT_A_TRAINING_STATE, "empty_file": NOT_A_TRAINING_STATE,
    "truncated": NOT_A_TRAINING_STATE, "state_is_a_list": NOT_A_TRAINING_STATE,
    "empty_state": "was saved by an older dancesynth", "no_optimizers": DAMAGED_TRAINING_STATE,
    "no_rng": DAMAGED_TRAINING_STATE, "no_rows": DAMAGED_TRAINING_STATE, "bad_rng": DAMAGED_TRAINING_STATE,
    "other_optimizer": DAMAGED_TRAINING_STATE, "rows_a_list": DAMAGED_TRAINING_STATE,
    "extra_a_list": DAMAGED_TRAINING_STATE, "two_processes": "was trained with 2 processes",
    "other_save": "does not belong to", "training_missing": "has no training state",
    "weights_random": "is not a readable safetensors file", "weights_missing": "model.safetensors is missing",
}
TRAINING_STATE = [(["train-pose", "--out", "{runs}/" + name, *RESUME_LSTM], says)
                  for name, says in TRAINING_STATE_EDITS.items()]
EDITED = "latest.json does not fit the model it belongs to"
META_EDITS = {  # run name -> (entry path, new value, what `generate` says, what `train-pose --resume` says)
    "hidden_16": (("config", "hidden"), 16, EDITED, EDITED),
    "layers_3": (("config", "layers"), 3, EDITED, EDITED),
    "feature_dim_10": (("config", "feature_dim"), 10, "leaves no music features", "leaves no music features"),
    "hidden_text": (("config", "hidden"), "eight", "is not a whole number", "is not a whole number"),
    "config_a_list": (("config",), [1], EDITED, EDITED),
    "config_missing": (("config",), None, EDITED, EDITED),
    "unknown_setting": (("config", "colour"), "red", "has no setting colour", "has no setting colour"),
    "fps_text": (("fps",), "fast", EDITED, None),
    "fps_negative": (("fps",), -15, EDITED, None),
    "fps_zero": (("fps",), 0, EDITED, None),
    "canvas_text": (("canvas",), "big", EDITED, None),
    "canvas_three": (("canvas",), [1, 2, 3], EDITED, None),
    "body_scale_null": (("body_scale",), None, EDITED, None),
    "stats_text": (("feature_stats",), "x", EDITED, None),
    "stats_missing": (("feature_stats",), None, EDITED, None),
    "stats_unequal": (("feature_stats", "std"), [1.0], EDITED, None),
    "checkpoint_outside": (("checkpoint",), "../lstm/ckpt-00000001-0", "is not a checkpoint folder of this run",
                           "is not a checkpoint folder of this run"),
    "checkpoint_number": (("checkpoint",), 5, "is not a checkpoint folder", "is not a checkpoint folder"),
    "kind_a_list": (("kind",), ["stage1"], "is not dancesynth checkpoint metadata", "is not dancesynth checkpoint"),
    "kind_stgcn": (("kind",), "stgcn", "is an ST-GCN pose classifier", "is an ST-GCN pose classifier"),
    "save_id_number": (("save_id",), 7, "does not belong to", "does not belong to"),
    "method_ren": (("method",), "ren", "RenConfig has no setting", "is a ren run; resume it with --method ren"),
    "step_text": (("step",), "one", None, EDITED),
    "epoch_text": (("epoch",), "one", None, EDITED),
    "epochs_negative": (("epochs",), -3, None, EDITED),
    "batch_index_text": (("batch_index",), "x", None, EDITED),
    "seed_float": (("seed",), 0.5, None, EDITED),
    "window_text": (("window_frames",), "30", None, EDITED),
    "stride_zero": (("stride_frames",), 0, None, EDITED),
}
EDITED_META = [
    *[(["generate", "{in}/song.wav", "--model", "{runs}/" + name, *GENERATE[2:]], says)
      for name, (_, _, says, _) in META_EDITS.items() if says],
    *[(["train-pose", "--out", "{runs}/" + name, *RESUME_LSTM], says)
      for name, (_, _, _, says) in META_EDITS.items() if says],
    (["generate", "{in}/song.wav", "--model", "{runs}/not_json", *GENERATE[2:]], "is not dancesynth checkpoint"),
    (["generate", "{in}/song.wav", "--model", "{runs}/json_list", *GENERATE[2:]], "is not dancesynth checkpoint"),
    (["render", "{in}/poses.npz", "--model", "{runs}/p2p_ngf_8", *RENDER_REAL[2:]], EDITED),
    (["render", "{in}/poses.npz", "--model", "{runs}/p2p_framing_text", *RENDER_REAL[2:]], EDITED),
    (["render", "{in}/poses.npz", "--model", "{runs}/p2p_fps_zero", *RENDER_REAL[2:]], EDITED),
    (["render", "{in}/poses.npz", "--model", "{runs}/p2p_config_missing", *RENDER_REAL[2:]], EDITED),
    (["dance", "{in}/song.wav", "--pose-model", "{runs}/hidden_16", *DANCE[2:]], EDITED),
    (["dance", "{in}/song.wav", "--pose-model", "{lstm}", "--video-model", "{runs}/p2p_ngf_8", *DANCE[4:]], EDITED),
]
MORE_WRONG_RUNS = [
    (["train-pose", "--method", "ren", "--data", "{data}", "--out", "{lstm}", "--resume"],
     "is a lstm run; resume it with --method lstm"),
    (["train-pose", "--method", "lstm", "--data", "{data}", "--out", "{lstm}", "--epochs", "1"],
     "already holds a trained model; pass --resume"),
    (["train-pose", "--method", "lstm", "--data", "{data}", "--out", "{in}/folder", "--resume"],
     "holds no checkpoint"),
    (["generate", "{in}/song.wav", "--model", "{p2p}", *GENERATE[2:]], "is an appearance model"),
    (["render", "{in}/poses.npz", "--model", "{lstm}", *RENDER_REAL[2:]], "is a pose model"),
    (["dance", "{in}/song.wav", "--pose-model", "{p2p}", "--video-model", "{lstm}", *DANCE[4:]],
     "is an appearance model"),
]
UNWRITABLE = [  # {ro}: a read-only file system (or a folder this user may not write); {full}: a full one
    (["generate", "{in}/song.wav", "--model", "{stage1}", "--out", "{ro}/p.npz"], "is read-only or not yours"),
    (["render", "{in}/poses.npz", "--model", "{stage2}", "--out", "{ro}/r.mp4"], "is read-only or not yours"),
    (["dance", "{in}/song.wav", "--pose-model", "{stage1}", "--video-model", "{stage2}", "--out", "{ro}/d.mp4"],
     "is read-only or not yours"),
    (["extract-poses", "{in}/video.mp4", "--out", "{ro}/p.npz"], "is read-only or not yours"),
    (["train-pose", "--method", "lstm", "--data", "{data}", "--out", "{ro}/run"], "is read-only or not yours"),
    (["make-dataset", "--out", "{ro}/ds"], "is read-only or not yours"),
    (["check", "{stage1}", "--json", "{ro}/check.json"], "is read-only or not yours"),
    (["import-dance", "--out", "{ro}/ds", "--aistpp", "{in}/gPO_x.npy", "--audio", "{in}/song.wav"],
     "is read-only or not yours"),
    (["generate", "{in}/song.wav", *GENERATE[:2], "--out", "{full}/p.npz", "--device", "cpu"],
     "free some disk space"),
    (["generate", "{in}/song.wav", *GENERATE[:2], "--out", "{out}/p.npz", "--preview", "{full}/p.mp4",
      "--device", "cpu"], "free some disk space"),
    (["render", "{in}/poses.npz", *RENDER_REAL[:2], "--out", "{full}/r.mp4", *RENDER_REAL[4:]],
     "free some disk space"),
    (["make-dataset", "--out", "{full}/ds", "--clips", "1", "--seconds", "2", "--workers", "1"],
     "free some disk space"),
    (["train-pose", "--method", "lstm", "--data", "{data}", "--out", "{full}/run", "--epochs", "1",
      "--preview-every", "0", "--device", "cpu", "--set", "hidden=8", "--set", "window_frames=30"],
     "free some disk space"),
]
FAKE_DANCE = ["dance", "{in}/song.wav", "--pose-model", "{stage1}", "--video-model", "{stage2}"]
FAKE_DANCE_MP4 = ["dance", "{in}/song.mp4", *FAKE_DANCE[2:]]
OVERWRITES = [  # an output that is an input, another output or not a file; {in}/song_link.mp4 links to song.mp4
    (FAKE_DANCE_MP4 + ["--out", "{in}/song.mp4"],
     "The dance video {in}/song.mp4 is the song {in}/song.mp4; choose another output path so that the song is not "
     "overwritten."),
    (FAKE_DANCE_MP4 + ["--out", "{in}/folder/../song.mp4"], "is the song {in}/song.mp4"),
    (FAKE_DANCE_MP4 + ["--out", "{in}/song_link.mp4"], "The dance video {in}/song_link.mp4 is the song"),
    (["dance", "{in}/song.wav", "--target", "{in}/video.mp4", "--cache", "{out}/cache", "--out", "{in}/video.mp4"],
     "The dance video {in}/video.mp4 is the target video"),
    (FAKE_DANCE + ["--out", "{stage2}/preview.mp4"], "is a file of the appearance model {stage2}"),
    (FAKE_DANCE + ["--out", "{stage1}/preview.mp4"], "is a file of the pose model {stage1}"),
    (FAKE_DANCE + ["--out", "{out}/d.mp4", "--skeleton-preview", "{out}/d.mp4"],
     "The skeleton preview {out}/d.mp4 is also the dance video {out}/d.mp4; give each output its own path."),
    (FAKE_DANCE + ["--out", "{out}/d.mp4", "--side-by-side", "{out}/../out/d.mp4"], "is also the dance video"),
    (FAKE_DANCE + ["--out", "{out}/d.mp4", "--skeleton-preview", "{out}/s.mp4", "--side-by-side", "{out}/s.mp4"],
     "The side-by-side video {out}/s.mp4 is also the skeleton preview"),
    (FAKE_DANCE + ["--out", "{in}/fifo"], "{in}/fifo is a named pipe, not a regular file"),
    (FAKE_DANCE + ["--out", "{out}/d.mp4", "--side-by-side", "{in}/fifo"], "is a named pipe"),
    (["render", "{in}/poses.npz", "--model", "{stage2}", "--audio", "{in}/song.mp4", "--out", "{in}/song_link.mp4"],
     "is the audio {in}/song.mp4"),
    (["render", "{in}/poses.npz", "--model", "{stage2}", "--out", "{stage2}/preview.mp4"],
     "is a file of the appearance model"),
    (["generate", "{in}/song.wav", "--model", "{stage1}", "--out", "{in}/song.wav"], "The pose file {in}/song.wav is "
     "the song"),
    (["generate", "{in}/song.wav", "--model", "{stage1}", "--out", "{out}/p.mp4", "--preview", "{out}/./p.mp4"],
     "The preview {out}/./p.mp4 is also the pose file {out}/p.mp4"),
    (["generate", "{in}/song.wav", "--model", "{stage1}", "--out", "{in}/fifo"], "is a named pipe"),
    (["extract-poses", "{in}/video.mp4", "--out", "{out}/p.npz", "--preview", "{in}/video.mp4"],
     "The preview {in}/video.mp4 is the video {in}/video.mp4"),
    (["extract-poses", "{in}/video.mp4", "--out", "{out}/p.npz", "--preview", "{in}/fifo"], "is a named pipe"),
    (["check", "{stage1}", "--json", "{stage1}/latest.json"], "is a file of the pose model"),
]
FOLDER_OVERWRITES = [  # an output folder that is an input of its command, holds an input folder, or is no folder
    (["train-pose", "--method", "lstm", "--data", "{data}", "--out", "{data}", "--epochs", "1"],
     "The run folder {data} is the dataset {data}; choose another output folder so that the dataset is not "
     "overwritten."),
    (["train-pose", "--method", "lstm", "--data", "{data}", "--out", "{data}/..", "--epochs", "1"],
     "The run folder {data}/.. holds the dataset {data}; choose another output folder"),
    (["train-pose", "--method", "lstm", "--data", "{data}", "--out", "{in}/fifo"], "{in}/fifo is a named pipe, not a "
                                                                                  "folder; give a folder path"),
    (["make-dataset", "--out", "{in}/fifo"], "is a named pipe, not a folder"),
    (["make-dataset", "--out", "/dev/null"], "/dev/null is a device, not a folder"),
    (["prepare", "{in}/videos", "--out", "{in}/videos"], "The dataset folder {in}/videos is the videos folder"),
    (["prepare", "{in}/videos", "--out", "{in}"], "The dataset folder {in} holds the videos folder {in}/videos"),
    (["evaluate", "--data", "{data}", "--models", "{stage1}", "--out", "{stage1}"],
     "The report folder {stage1} is the pose model {stage1}"),
    (["evaluate", "--data", "{data}", "--out", "{data}"], "The report folder {data} is the dataset"),
    (["train-stgcn", "--data", "{data}", "--out", "{data}"], "The run folder {data} is the dataset"),
    (["train-stgcn", "--data", "{data}", "--out", "{in}/a_file.txt"], "is a file, not a folder"),
    (["train-style-classifier", "--data", "{data}", "--out", "{data}"], "The run folder {data} is the dataset"),
]
# A video is written as an MP4 whatever its name: a name players would take for another format is refused.
NOT_AN_MP4 = [
    (["dance", "{in}/song.wav", "--pose-model", "{stage1}", "--video-model", "{stage2}", "--out", "{out}/d.webm"],
     "{out}/d.webm would hold an MP4 video; give a name ending in .mp4"),
    (["dance", "{in}/song.wav", "--pose-model", "{stage1}", "--video-model", "{stage2}", "--out", "{out}/d.mp4",
      "--side-by-side", "{out}/s.gif"], "would hold an MP4 video"),
    (["render", "{in}/poses.npz", "--model", "{stage2}", "--out", "{out}/r"], "would hold an MP4 video"),
    (["render", "{in}/poses.npz", *RENDER, "--skeleton-preview", "{out}/s.avi"], "would hold an MP4 video"),
    (["render", "{in}/poses.npz", "--model", "{stage2}", "--out", "{in}/poses.npz"],
     "{in}/poses.npz would hold an MP4 video"),
    (["generate", "{in}/song.wav", "--model", "{stage1}", "--out", "{out}/p.npz", "--preview", "{out}/p.txt"],
     "would hold an MP4 video"),
    (["extract-poses", "{in}/video.mp4", "--out", "{out}/p.npz", "--preview", "{out}/o.mkv"],
     "would hold an MP4 video"),
]
CATALOGUE = {"out_of_range": OUT_OF_RANGE, "folder_for_file": FOLDER_FOR_FILE, "file_for_folder": FILE_FOR_FOLDER,
             "missing_or_unreadable": MISSING_OR_UNREADABLE, "bad_dataset": BAD_DATASETS,
             "wrong_run": WRONG_RUNS + MORE_WRONG_RUNS, "bad_audio": BAD_AUDIO, "song_segment": SONG_SEGMENT,
             "bad_pose_file": BAD_POSE_FILES, "training_state": TRAINING_STATE, "edited_latest_json": EDITED_META,
             "unwritable_output": UNWRITABLE, "output_overwrites": OVERWRITES,
             "output_folder_overwrites": FOLDER_OVERWRITES, "not_an_mp4": NOT_AN_MP4}
CASES = [(name, argv, says) for name, cases in CATALOGUE.items() for argv, says in cases]


def _song(seconds: float = 3.0) -> np.ndarray:
    t = np.arange(int(seconds * SR)) / SR
    return (0.3 * np.sin(2 * np.pi * 220 * t) * (np.sin(2 * np.pi * 2 * t) > 0)).astype(np.float32)


def _fake_run(folder: Path, kind: str) -> str:
    """A run folder that says it is a ``kind`` run (checks of the kind come before the weights are read)."""
    folder.mkdir()
    (folder / "latest.json").write_text(json.dumps({"kind": kind, "save_id": "0"}))
    (folder / "preview.mp4").write_bytes(b"a run's preview video")
    return str(folder)


def _pose_file(path: Path, keypoints: np.ndarray, fps: float = 15.0, width: int = 64, height: int = 64) -> None:
    np.savez(path, layout="BODY_25", keypoints=keypoints, fps=fps, width=width, height=height)


def _bad_dataset(good: Path, root: Path, **clip0) -> None:
    shutil.copytree(good, root, symlinks=True)
    manifest = json.loads((root / "manifest.json").read_text())
    manifest["clips"][0].update(clip0)
    (root / "manifest.json").write_text(json.dumps(manifest))


@pytest.fixture(scope="module")
def inputs(tmp_path_factory, tiny_stage1_dataset) -> dict[str, str]:
    """Every input the catalogue needs, made once: good files, broken files, fake runs and bad datasets."""
    root = tmp_path_factory.mktemp("bad_input")
    folder = root / "in"
    (folder / "folder").mkdir(parents=True)
    (folder / "videos").mkdir()
    soundfile.write(folder / "song.wav", _song(), SR)
    broken = _song()
    broken[100] = np.nan
    soundfile.write(folder / "nan.wav", broken, SR, subtype="FLOAT")
    broken[100] = 1e30
    soundfile.write(folder / "huge.wav", broken, SR, subtype="FLOAT")
    broken[100] = np.inf
    soundfile.write(folder / "inf.wav", broken, SR, subtype="FLOAT")
    soundfile.write(folder / "loud.wav", _song() * 1000, SR, subtype="FLOAT")
    soundfile.write(folder / "silent.wav", np.zeros(3 * SR, np.float32), SR)
    soundfile.write(folder / "short.wav", _song(0.5), SR)
    soundfile.write(folder / "no_samples.wav", np.zeros(0, np.float32), SR)
    soundfile.write(folder / "song10.wav", _song(10.0), SR)
    write_video(folder / "video_only.mp4", [np.full((32, 32, 3), 90, np.uint8)] * 45, 15.0)
    kp = np.ones((20, 25, 3), np.float32) * 30
    _pose_file(folder / "poses_coco18.npz", kp[:, :18])
    _pose_file(folder / "poses_no_frames.npz", kp[:0])
    _pose_file(folder / "poses_nan.npz", np.where(np.arange(20)[:, None, None] == 5, np.nan, kp))
    _pose_file(folder / "poses_bad_fps.npz", kp, fps=-15.0)
    _pose_file(folder / "poses_bad_canvas.npz", kp, width=0)
    (folder / "empty.npz").write_bytes(b"")
    (folder / "empty.wav").write_bytes(b"")
    (folder / "garbage.npz").write_bytes(np.random.default_rng(0).bytes(4096))
    (folder / "truncated.npz").write_bytes((tiny_stage1_dataset / "poses" / "clip0.npz").read_bytes()[:300])
    (folder / "a_file.txt").write_text("not a folder")
    os.mkfifo(folder / "fifo")
    (folder / "song_link.wav").symlink_to(folder / "song.wav")
    # A song under a video's name (any FFmpeg-readable file is a song): what a video output could overwrite.
    shutil.copy(folder / "song.wav", folder / "song.mp4")
    (folder / "song_link.mp4").symlink_to(folder / "song.mp4")
    (folder / "video.mp4").write_bytes(b"never decoded: the arguments are refused first")
    np.save(folder / "gPO_x.npy", np.ones((90, 17, 3), np.float32))
    shutil.copy(next((tiny_stage1_dataset / "poses").glob("*.npz")), folder / "poses.npz")
    (root / "outside.wav").write_bytes((folder / "song.wav").read_bytes())
    _bad_dataset(tiny_stage1_dataset, folder / "ds_up", audio="../in/song.wav")
    _bad_dataset(tiny_stage1_dataset, folder / "ds_absolute", poses=str(folder / "poses.npz"))
    _bad_dataset(tiny_stage1_dataset, folder / "ds_id", id="../../../X")
    _bad_dataset(tiny_stage1_dataset, folder / "ds_link", audio="audio/link.wav")
    (folder / "ds_link" / "audio" / "link.wav").symlink_to(root / "outside.wav")
    _bad_dataset(tiny_stage1_dataset, folder / "ds_empty_poses")
    (folder / "ds_empty_poses" / "poses" / "clip0.npz").write_bytes(b"")
    _bad_dataset(tiny_stage1_dataset, folder / "ds_features")
    shutil.rmtree(folder / "ds_features" / "features")
    (folder / "ds_features" / "features").symlink_to(folder / "folder")
    return {"in": str(folder), "data": str(tiny_stage1_dataset), "root": str(root),
            "stage1": _fake_run(folder / "stage1_run", "stage1"), "stage2": _fake_run(folder / "stage2_run", "stage2")}


def _save(value: object) -> bytes:
    buffer = io.BytesIO()
    torch.save(value, buffer)
    return buffer.getvalue()


class _RunsCode:
    """Unpickling this runs a command: what a malicious training.pt would hold."""

    def __reduce__(self):
        return os.system, ("touch pwned",)


def _training_state_edits(good: dict, save_id: str, training: bytes) -> dict[str, bytes | None]:
    """Each TRAINING_STATE_EDITS run's training.pt (None: the file is deleted)."""
    state = good["state"]

    def without(key: str) -> bytes:
        return _save({"save_id": save_id, "state": {k: v for k, v in state.items() if k != key}})

    def replaced(key: str, value: object) -> bytes:
        return _save({"save_id": save_id, "state": {**state, key: value}})

    return {"random_bytes": np.random.default_rng(1).bytes(3000), "malicious_pickle": pickle.dumps(_RunsCode()),
            "a_list": _save([1, 2, 3]), "no_state": _save({"save_id": save_id}), "empty_file": b"",
            "truncated": training[:400], "state_is_a_list": _save({"save_id": save_id, "state": [state]}),
            "empty_state": _save({"save_id": save_id, "state": {}}), "no_optimizers": without("optimizers"),
            "no_rng": without("rng"), "no_rows": without("rows"), "bad_rng": replaced("rng", [{"numpy": 1}]),
            "other_optimizer": replaced("optimizers", {"model": {"state": {}, "param_groups": []}}),
            "rows_a_list": replaced("rows", [1]), "extra_a_list": replaced("extra", [1]),
            "two_processes": replaced("rng", state["rng"] * 2), "other_save": _save({"save_id": "0", "state": state}),
            "training_missing": None}


def _edited_run(good: Path, run: Path, entry: tuple[str, ...] = (), value: object = None) -> Path:
    """A copy of the run ``good`` whose latest.json has ``entry`` set to ``value`` (None: removed)."""
    shutil.copytree(good, run)
    if entry:
        meta = json.loads((run / "latest.json").read_text())
        table = meta
        for key in entry[:-1]:
            table = table[key]
        if value is None:
            del table[entry[-1]]
        else:
            table[entry[-1]] = value
        (run / "latest.json").write_text(json.dumps(meta))
    return run


@pytest.fixture(scope="module")
def runs(inputs, tiny_stage1_dataset) -> dict[str, str]:
    """Two real tiny runs (an LSTM pose model, a pix2pixHD appearance model) and damaged copies of them."""
    folder = Path(inputs["root"]) / "runs"
    folder.mkdir()
    lstm, p2p = folder / "lstm", folder / "p2p"
    assert main(["train-pose", "--method", "lstm", "--data", str(tiny_stage1_dataset), "--out", str(lstm), "-q",
                 "--epochs", "1", "--preview-every", "0", "--device", "cpu", "--set", "hidden=8", "--set",
                 "window_frames=30", "--set", "epoch_windows=0"]) == 0
    kp = np.ones((20, 25, 3), np.float32)
    kp[..., :2] = np.random.default_rng(0).uniform(12, 52, (25, 2)) + np.arange(20)[:, None, None] * 0.3
    target = PoseSequence(kp, 15.0, 64, 64)
    target.save(folder / "target.npz")
    write_video(folder / "target.mp4", [draw_pose(np.full((64, 64, 3), 80, np.uint8), k) for k in kp], 15.0)
    small = [f"{key}={value}" for key, value in
             {"ngf": 4, "n_blocks": 1, "ndf": 4, "n_downsample": 1, "num_d": 1, "batch_size": 8}.items()]
    assert main(["train-video", str(folder / "target.mp4"), "--out", str(p2p), "--poses", str(folder / "target.npz"),
                 "--size", "32x32", "--epochs", "1", "--device", "cpu", "-q",
                 *[arg for setting in small for arg in ("--set", setting)]]) == 0
    for name, (entry, value, _, _) in META_EDITS.items():
        _edited_run(lstm, folder / name, entry, value)
    (_edited_run(lstm, folder / "not_json") / "latest.json").write_text("{not json")
    (_edited_run(lstm, folder / "json_list") / "latest.json").write_text("[1, 2]")
    for name, entry, value in [("p2p_ngf_8", ("config", "ngf"), 8), ("p2p_framing_text", ("framing",), "x"),
                               ("p2p_fps_zero", ("fps",), 0), ("p2p_config_missing", ("config",), None)]:
        _edited_run(p2p, folder / name, entry, value)
    checkpoint = json.loads((lstm / "latest.json").read_text())["checkpoint"]
    training = (lstm / checkpoint / "training.pt").read_bytes()
    good = torch.load(lstm / checkpoint / "training.pt", weights_only=True)
    for name, content in _training_state_edits(good, good["save_id"], training).items():
        path = _edited_run(lstm, folder / name) / checkpoint / "training.pt"
        path.unlink() if content is None else path.write_bytes(content)
    (_edited_run(lstm, folder / "weights_random") / checkpoint / "model.safetensors").write_bytes(
        np.random.default_rng(2).bytes(2000))
    (_edited_run(lstm, folder / "weights_missing") / checkpoint / "model.safetensors").unlink()
    return {"runs": str(folder), "lstm": str(lstm), "p2p": str(p2p)}


def _mount(kind: str, folder: Path) -> str:
    """Make ``folder`` read-only ("ro") or full ("full"); returns why not when this machine does not allow it."""
    folder.mkdir()
    if kind == "ro" and os.geteuid() != 0:
        folder.chmod(0o555)
        return ""
    if os.geteuid() != 0 or shutil.which("mount") is None:
        return "needs root to mount a small file system"
    mount = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(folder)], capture_output=True,
                           text=True)
    if mount.returncode != 0:
        return f"mount failed: {mount.stderr.strip()}"
    if kind == "ro":
        subprocess.run(["mount", "-o", "remount,ro", str(folder)], check=True)
    else:
        with contextlib.suppress(OSError), open(folder / "filler", "wb") as f:
            while True:
                f.write(b"x" * 4096)
                f.flush()
    return ""


@pytest.fixture(scope="module")
def disks(inputs):
    """{ro}: a read-only folder, {full}: a folder on a full file system, with the reason each is not possible."""
    root = Path(inputs["root"])
    why = {kind: _mount(kind, root / kind) for kind in ("ro", "full")}
    yield {"ro": str(root / "ro"), "full": str(root / "full"), "why": why}
    for kind in why:
        if os.path.ismount(root / kind):
            subprocess.run(["umount", str(root / kind)], check=False)
        (root / kind).chmod(0o755)


def _files(*folders: str) -> dict[str, int]:
    """Every file (and link) under ``folders`` with its size, and every folder (size -1), links not followed; a
    dataset's feature cache (complete files it may gain on any use) is left out."""
    found = {}
    for top in folders:
        for dirpath, _, filenames in os.walk(top):
            if "features" in Path(dirpath).relative_to(top).parts:
                continue
            found[dirpath] = -1
            for name in filenames:
                path = os.path.join(dirpath, name)
                found[path] = os.lstat(path).st_size
    return found


def _error_line(err: str, command: str) -> str:
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.strip()]
    errors = [line for line in lines if "error:" in line]
    assert len(errors) == 1 and lines[-1] == errors[0], err
    assert errors[0].startswith(f"dancesynth {command}: error: "), err
    return errors[0]


def _needs(request, argv: list[str]) -> dict[str, str]:
    """The fixtures the case's placeholders name (made only when a case needs them)."""
    text = " ".join(argv)
    found = {}
    if any(key in text for key in ("{runs}", "{lstm}", "{p2p}")):
        found.update(request.getfixturevalue("runs"))
    if "{ro}" in text or "{full}" in text:
        disks = request.getfixturevalue("disks")
        kind = "ro" if "{ro}" in text else "full"
        if disks["why"][kind]:
            pytest.skip(disks["why"][kind])
        found.update(ro=disks["ro"], full=disks["full"])
    return found


@pytest.mark.parametrize("kind, argv, says", CASES,
                         ids=[f"{kind}: {' '.join(arg.rsplit('/', 1)[-1] for arg in argv)}" for kind, argv, _ in CASES])
def test_bad_input_is_one_line_exit_1_and_writes_nothing(request, inputs, tmp_path, capsys, kind, argv, says):
    paths = {**inputs, **_needs(request, argv), "out": str(tmp_path / "out")}
    (tmp_path / "out").mkdir()
    before = _files(inputs["root"], inputs["data"], paths["out"])
    code = main([arg.format(**paths) for arg in argv])
    line = _error_line(capsys.readouterr().err, argv[0])
    assert code == 1 and says.format(**paths) in line, line
    assert _files(inputs["root"], inputs["data"], paths["out"]) == before
    assert not Path("pwned").exists()


@pytest.mark.parametrize("device", ["/dev/null", "/dev/full", "/dev/stdout"])
def test_a_device_as_output_is_refused_and_stays_a_device(inputs, capsys, device):
    before = os.stat(device).st_mode
    # The pose model is a fake run: were the output not refused, loading it would fail before anything is written.
    assert main(["generate", f"{inputs['in']}/song.wav", "--model", inputs["stage1"], "--out", device]) == 1
    line = _error_line(capsys.readouterr().err, "generate")
    assert f"{device} is " in line and "give the path of a file to write instead" in line, line
    assert os.stat(device).st_mode == before and os.path.exists(device)


def test_an_os_error_escaping_a_command_is_one_sentence(monkeypatch, tmp_path, capsys):
    def disk_full(args):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp_path / "big.wav"))

    monkeypatch.setattr("apps.commands.make_dataset.run", disk_full)
    assert main(["make-dataset", "--out", str(tmp_path / "ds")]) == 1
    line = _error_line(capsys.readouterr().err, "make-dataset")
    assert "big.wav" in line and "free some disk space" in line


def test_prepare_skips_links_to_videos_outside_the_folder(tmp_path, capsys):
    secret = tmp_path / "secret.mp4"
    secret.write_bytes(b"a video somewhere else")
    (tmp_path / "videos" / "salsa").mkdir(parents=True)
    (tmp_path / "videos" / "salsa" / "a.mp4").symlink_to(secret)
    assert main(["prepare", str(tmp_path / "videos"), "--out", str(tmp_path / "ds")]) == 1
    captured = capsys.readouterr()
    assert "is a link to a file outside" in captured.out + captured.err
    assert "None of the videos" in _error_line(captured.err, "prepare")
    assert not (tmp_path / "ds").exists()


SLOW_WRITE = textwrap.dedent("""
    import pathlib, sys, time
    from apps.cli import main

    def slow_write(path, data):
        with open(path, "wb") as f:
            f.write(data[:100])
        print("writing", flush=True)
        time.sleep(60)

    pathlib.Path.write_bytes = slow_write
    sys.exit(main(["make-dataset", "--out", sys.argv[1], "--clips", "1", "--seconds", "2", "--workers", "1"]))
""")


def test_sigterm_mid_write_cleans_up_like_ctrl_c(tmp_path):
    out = tmp_path / "ds"
    proc = subprocess.Popen([sys.executable, "-c", SLOW_WRITE, str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=Path(__file__).parents[2])
    try:
        assert proc.stdout.readline().strip() == "writing"
        assert any(".part" in p.name for p in (out / "audio").iterdir())
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 130 and "interrupted" in err and "Traceback" not in err
    assert not [p for p in out.rglob("*") if ".part" in p.name]
