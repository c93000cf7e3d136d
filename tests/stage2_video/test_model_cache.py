"""The appearance-model cache: an interrupted training leaves an entry that resumes, and only for its own video."""

import json
import multiprocessing
import os
import shutil
import signal

import pytest

from dancesynth.core.errors import DancesynthError
from stage2_video.model_cache import appearance_model_for, entry_path, list_entries, read_entry, train_for
from stage2_video.train import VideoTrainer
from stage2_video.training_data import video_digest


def _train_until_interrupted(video, poses, run) -> None:
    """Child process: a cache training (one minute asked for) that Ctrl-C hits in the middle of step 3."""
    real_step, calls = VideoTrainer.train_step, []

    def signalled(self, batch):
        calls.append(1)
        if len(calls) == 3:
            os.kill(os.getpid(), signal.SIGINT)
        return real_step(self, batch)

    VideoTrainer.train_step = signalled
    try:
        train_for(video, run, 1.0, "small", device="cpu", poses=poses)
    except KeyboardInterrupt:
        os._exit(130)
    os._exit(0)


def test_an_interrupted_training_leaves_a_resumable_entry_of_its_own_video(tiny_target, tmp_path):
    video, poses = tiny_target
    cache = tmp_path / "cache"
    entry = entry_path(video, "small", cache)
    # A fresh process, as a user's: this one may hold native libraries (OpenVINO) that other tests loaded.
    child = multiprocessing.get_context("spawn").Process(target=_train_until_interrupted, args=(video, poses, entry))
    child.start()
    child.join(120)
    assert child.exitcode == 130, "Ctrl-C ended the training"
    stopped = read_entry(entry)
    assert stopped is not None and not stopped.finished and 0 < stopped.trained_seconds < 60
    assert [e.path for e in list_entries(cache)] == [entry]

    # Another video (other content, same name) looks up another entry and finds nothing trained.
    other = tmp_path / "other" / video.name
    other.parent.mkdir()
    shutil.copy(video, other)
    with open(other, "ab") as f:
        f.write(b"\0")
    assert video_digest(other) != video_digest(video)
    assert read_entry(entry_path(other, "small", cache)) is None

    # The same video resumes the entry for the seconds it lacks instead of starting again.
    before = (entry / "latest.json").read_text()
    train_for(video, entry, stopped.trained_seconds / 60 + 0.02, "small", device="cpu", poses=poses)
    resumed = read_entry(entry)
    assert (entry / "latest.json").read_text() != before
    assert resumed.trained_seconds > stopped.trained_seconds


def test_a_target_that_fails_before_its_first_checkpoint_leaves_no_entry(tiny_target, tmp_path, monkeypatch):
    video, _ = tiny_target
    cache = tmp_path / "cache"

    def no_person(*args, **kwargs):
        (entry_path(video, "small", cache) / "poses.npz").write_bytes(b"partial")
        raise DancesynthError("No person was found in the target video.")

    monkeypatch.setattr("stage2_video.model_cache.check_target_video", lambda video: None)  # the tiny target is short
    monkeypatch.setattr("stage2_video.model_cache.train_video", no_person)
    with pytest.raises(DancesynthError, match="No person"):
        appearance_model_for(video, 1.0, "small", cache, device="cpu")
    assert not entry_path(video, "small", cache).exists() and list(cache.iterdir()) == []


def test_a_damaged_cache_entry_says_to_delete_its_folder(tiny_target, tmp_path):
    video, _ = tiny_target
    entry = entry_path(video, "small", tmp_path / "cache")
    entry.mkdir(parents=True)
    (entry / "latest.json").write_text("[1, 2]")
    with pytest.raises(DancesynthError, match="not dancesynth checkpoint metadata") as raised:
        read_entry(entry)
    assert f"if {entry} is a model that `dance --target` cached, delete that folder so it is trained again" in (
        str(raised.value))


def test_a_cache_entry_whose_source_json_is_no_object_names_that_file(tmp_path):
    entry = tmp_path / "cache" / f"{'0' * 24}-small"
    entry.mkdir(parents=True)
    (entry / "latest.json").write_text(json.dumps({"kind": "stage2", "epoch": 1, "total_epochs": 4}))
    (entry / "source.json").write_text(json.dumps(["a", "list"]))
    with pytest.raises(DancesynthError) as raised:
        read_entry(entry)
    assert str(raised.value) == (f"{entry}/source.json holds a JSON list, not an object; it was edited or damaged, so "
                                 f"delete the folder {entry} and its model is trained again.")
