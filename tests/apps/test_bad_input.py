"""A catalogue of bad input, run through the CLI: each case ends with exit status 1, one error line on stderr,
no traceback, and no file written or left anywhere (outputs, inputs, datasets, run folders)."""

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import soundfile

from apps.cli import main

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
CASES = OUT_OF_RANGE + FOLDER_FOR_FILE + FILE_FOR_FOLDER + MISSING_OR_UNREADABLE + BAD_DATASETS + WRONG_RUNS


def _song(seconds: float = 3.0) -> np.ndarray:
    t = np.arange(int(seconds * SR)) / SR
    return (0.3 * np.sin(2 * np.pi * 220 * t) * (np.sin(2 * np.pi * 2 * t) > 0)).astype(np.float32)


def _fake_run(folder: Path, kind: str) -> str:
    """A run folder that says it is a ``kind`` run (checks of the kind come before the weights are read)."""
    folder.mkdir()
    (folder / "latest.json").write_text(json.dumps({"kind": kind, "save_id": "0"}))
    return str(folder)


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
    (folder / "empty.npz").write_bytes(b"")
    (folder / "empty.wav").write_bytes(b"")
    (folder / "garbage.npz").write_bytes(np.random.default_rng(0).bytes(4096))
    (folder / "truncated.npz").write_bytes((tiny_stage1_dataset / "poses" / "clip0.npz").read_bytes()[:300])
    (folder / "a_file.txt").write_text("not a folder")
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


@pytest.mark.parametrize("argv, says", CASES, ids=[" ".join(a[:1] + a[-2:]) for a, _ in CASES])
def test_bad_input_is_one_line_exit_1_and_writes_nothing(inputs, tmp_path, capsys, argv, says):
    paths = {**inputs, "out": str(tmp_path / "out")}
    (tmp_path / "out").mkdir()
    before = _files(inputs["root"], inputs["data"], paths["out"])
    code = main([arg.format(**paths) for arg in argv])
    line = _error_line(capsys.readouterr().err, argv[0])
    assert code == 1 and says.format(**paths) in line, line
    assert _files(inputs["root"], inputs["data"], paths["out"]) == before


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
    import sys, time
    import soundfile
    from apps.cli import main

    def slow_write(path, *args, **kwargs):
        with open(path, "wb") as f:
            f.write(b"RIFF half a file")
        print("writing", flush=True)
        time.sleep(60)

    soundfile.write = slow_write
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
