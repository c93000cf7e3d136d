import argparse
import errno
import multiprocessing
import os
import re
import socket
import stat
import subprocess
import threading

import numpy as np
import pytest

from apps.arguments import output_file, output_folder
from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import (
    PART_MARKER,
    atomic_path,
    check_outputs,
    not_a_folder,
    os_error_sentence,
    require_file,
    special_file,
    temporary_sibling,
)
from dancesynth.core.skeleton import PoseSequence


def test_temporary_names_are_unique_beside_the_output_and_keep_its_extension(tmp_path):
    out = tmp_path / "same.mp4"
    names = {temporary_sibling(out) for _ in range(100)}
    assert len(names) == 100
    for name in names:
        assert name.parent == tmp_path and name.suffix == ".mp4" and PART_MARKER in name.name
        assert name.name != out.name


def test_two_overlapping_writers_end_with_one_complete_file(tmp_path):
    out = tmp_path / "same.bin"
    both_half_written = threading.Barrier(2)
    payloads = {"a": b"A" * 100_000, "b": b"B" * 50_000}

    def write(key: str) -> None:
        with atomic_path(out) as tmp, open(tmp, "wb") as f:
            data = payloads[key]
            f.write(data[: len(data) // 2])
            f.flush()
            both_half_written.wait(timeout=10)
            f.write(data[len(data) // 2:])

    threads = [threading.Thread(target=write, args=(k,)) for k in payloads]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert out.read_bytes() in payloads.values()
    assert [p.name for p in tmp_path.iterdir()] == ["same.bin"]


def _save_repeatedly(path: str, value: float) -> None:
    seq = PoseSequence(np.full((200, 25, 3), value, np.float32), 15.0, 64, 64)
    for _ in range(20):
        seq.save(path)


def test_two_processes_saving_one_pose_file_leave_a_valid_file(tmp_path):
    out = tmp_path / "poses.npz"
    ctx = multiprocessing.get_context("spawn")
    procs = [ctx.Process(target=_save_repeatedly, args=(str(out), v)) for v in (1.0, 2.0)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(timeout=120)
    assert [p.exitcode for p in procs] == [0, 0]
    keypoints = PoseSequence.load(out).keypoints
    assert len(np.unique(keypoints)) == 1 and keypoints.flat[0] in (1.0, 2.0)
    assert [p.name for p in tmp_path.iterdir()] == ["poses.npz"]


@pytest.mark.parametrize("failure", [RuntimeError("boom"), KeyboardInterrupt()])
def test_a_failed_or_interrupted_write_leaves_nothing_and_keeps_the_old_file(tmp_path, failure):
    out = tmp_path / "report.json"
    out.write_text("old")
    with pytest.raises(type(failure)):
        with atomic_path(out) as tmp:
            tmp.write_text("half")
            raise failure
    assert out.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["report.json"]


def test_a_folder_or_missing_folder_as_output_is_refused_before_writing(tmp_path):
    (tmp_path / "video.mp4").mkdir()
    with pytest.raises(DancesynthError, match="is a folder"):
        with atomic_path(tmp_path / "video.mp4"):
            pytest.fail("the body must not run")
    with pytest.raises(DancesynthError, match="does not exist"):
        with atomic_path(tmp_path / "no" / "out.npz"):
            pytest.fail("the body must not run")


def test_a_missing_input_file_or_a_folder_in_its_place_is_one_sentence_naming_it(tmp_path):
    (tmp_path / "song.wav").write_bytes(b"RIFF")
    assert require_file(str(tmp_path / "song.wav")) == tmp_path / "song.wav"
    missing = tmp_path / "clip.mp4"
    with pytest.raises(DancesynthError, match=re.escape(f"Target video {missing} does not exist; check the path.")):
        require_file(missing, "Target video")
    with pytest.raises(DancesynthError, match=re.escape(f"{tmp_path} does not exist; check the path.")):
        require_file(tmp_path)


def test_folder_outputs_replace_the_previous_folder_whole(tmp_path):
    out = tmp_path / "json"
    for count in (3, 2):
        with atomic_path(out, folder=True) as tmp:
            tmp.mkdir()
            for i in range(count):
                (tmp / f"{i}.json").write_text("{}")
    assert sorted(p.name for p in out.iterdir()) == ["0.json", "1.json"]
    assert [p.name for p in tmp_path.iterdir()] == ["json"]


def test_read_only_disk_is_one_sentence_even_when_cleanup_fails(tmp_path, monkeypatch):
    def read_only(*args, **kwargs):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS))

    monkeypatch.setattr(os, "replace", read_only)
    monkeypatch.setattr(os, "unlink", read_only)
    with pytest.raises(DancesynthError, match="read-only") as info:
        with atomic_path(tmp_path / "out.txt") as tmp:
            tmp.write_text("x")
    assert "out.txt" in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("code, hint", [(errno.ENOSPC, "free some disk space"), (errno.EROFS, "read-only"),
                                        (errno.EACCES, "permissions"), (errno.EIO, "check the path")])
def test_os_errors_become_a_sentence_with_what_to_do(code, hint):
    message = os_error_sentence(OSError(code, os.strerror(code), "/data/out.mp4"))
    assert "/data/out.mp4" in message and hint in message and message.endswith(".")


def _plain_mode(folder: bool = False) -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return (0o777 if folder else 0o666) & ~mask


def test_outputs_get_the_mode_a_plain_open_would_give(tmp_path):
    """Writers that create 0600 files (safetensors, tempfile) still leave the output readable like any other."""
    new, existing = tmp_path / "new.bin", tmp_path / "existing.bin"
    existing.write_bytes(b"old")
    existing.chmod(0o640)
    for path in (new, existing):
        with atomic_path(path) as tmp:
            tmp.write_bytes(b"data")
            tmp.chmod(0o600)
    assert new.stat().st_mode & 0o777 == _plain_mode()
    assert existing.stat().st_mode & 0o777 == 0o640
    with atomic_path(tmp_path / "run", folder=True) as tmp:
        (tmp / "inner").mkdir(parents=True)
        (tmp / "inner" / "weights").write_bytes(b"w")
        (tmp / "inner" / "weights").chmod(0o600)
        tmp.chmod(0o700)
    assert (tmp_path / "run").stat().st_mode & 0o777 == _plain_mode(folder=True)
    assert (tmp_path / "run" / "inner").stat().st_mode & 0o777 == _plain_mode(folder=True)
    assert (tmp_path / "run" / "inner" / "weights").stat().st_mode & 0o777 == _plain_mode()


def test_an_output_naming_an_input_by_any_name_is_refused(tmp_path, monkeypatch):
    song = tmp_path / "song.wav"
    song.write_bytes(b"RIFF")
    (tmp_path / "link.wav").symlink_to(song)
    os.link(song, tmp_path / "hard.wav")
    (tmp_path / "sub").mkdir()
    monkeypatch.chdir(tmp_path)
    for out in (song, "song.wav", "./sub/../song.wav", tmp_path / "link.wav", tmp_path / "hard.wav"):
        with pytest.raises(DancesynthError, match=re.escape(
                f"The dance video {out} is the song {song}; choose another output path so that the song is not "
                "overwritten.")):
            check_outputs({"dance video": out}, {"song": song, "pose model": None})
    check_outputs({"dance video": tmp_path / "dance.mp4", "preview": None}, {"song": song})


def test_an_existing_file_of_an_input_folder_is_refused_as_output_but_a_new_one_is_not(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / "latest.json").write_text("{}")
    with pytest.raises(DancesynthError, match="is a file of the appearance model"):
        check_outputs({"video": run / "latest.json"}, {"appearance model": run})
    with pytest.raises(DancesynthError, match="is the appearance model"):
        check_outputs({"video": tmp_path / "." / "run"}, {"appearance model": run})
    check_outputs({"video": run / "replay.mp4"}, {"appearance model": run})


def test_two_outputs_naming_one_file_are_refused(tmp_path):
    a, b = tmp_path / "a.mp4", tmp_path / "b.mp4"
    with pytest.raises(DancesynthError, match=re.escape(
            f"The side-by-side video {tmp_path}/./a.mp4 is also the dance video {a}; give each output its own path.")):
        check_outputs({"dance video": a, "skeleton preview": b, "side-by-side video": f"{tmp_path}/./a.mp4"})
    b.write_bytes(b"old")
    (tmp_path / "b_link.mp4").symlink_to(b)
    with pytest.raises(DancesynthError, match="is also the skeleton preview"):
        check_outputs({"dance video": a, "skeleton preview": b, "side-by-side video": tmp_path / "b_link.mp4"})
    check_outputs({"dance video": a, "skeleton preview": b, "side-by-side video": None})


def _kinds(tmp_path):
    """A named pipe and a socket in ``tmp_path`` (the socket kept open by the caller)."""
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    server = socket.socket(socket.AF_UNIX)
    server.bind(str(tmp_path / "sock"))
    return fifo, server


def test_a_pipe_socket_or_device_is_refused_as_output_and_kept(tmp_path):
    fifo, server = _kinds(tmp_path)
    (tmp_path / "null_link").symlink_to("/dev/null")
    with server:
        for path, kind in ((fifo, "a named pipe"), (tmp_path / "sock", "a socket"), ("/dev/null", "a device"),
                           (tmp_path / "null_link", "a device"), ("/dev/full", "a device"),
                           ("/dev/new.mp4", "in /dev, a folder of the system's devices and processes"),
                           ("/proc/new.mp4", "in /proc")):
            assert special_file(path).startswith(kind)
            with pytest.raises(DancesynthError, match=re.escape(f"The video {path} is {kind}")):
                check_outputs({"video": path})
            # Were it not refused, the failing body would leave the path as it is: this test replaces nothing.
            with pytest.raises(DancesynthError, match=re.escape(f"{path} is {kind}")):
                with atomic_path(path):
                    pytest.fail("the body must not run")
            with pytest.raises(argparse.ArgumentTypeError, match=re.escape(f"{path} is {kind}")):
                output_file(str(path))
    assert stat.S_ISFIFO(os.stat(fifo).st_mode) and stat.S_ISSOCK(os.lstat(tmp_path / "sock").st_mode)
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode) and stat.S_ISCHR(os.stat("/dev/full").st_mode)
    assert not os.path.lexists("/dev/new.mp4")
    for path in (tmp_path / "new.mp4", tmp_path, "/dev/shm/new.mp4"):
        assert special_file(path) is None


def test_an_output_folder_that_is_no_folder_is_refused_and_kept(tmp_path):
    fifo, server = _kinds(tmp_path)
    (tmp_path / "notes.txt").write_text("mine")
    with server:
        for path, kind in ((tmp_path / "notes.txt", "a file"), (fifo, "a named pipe"), (tmp_path / "sock", "a socket"),
                           ("/dev/null", "a device"), ("/proc/runs", "in /proc")):
            assert not_a_folder(path).startswith(kind)
            with pytest.raises(DancesynthError, match=re.escape(f"The run folder {path} is {kind}")):
                check_outputs({}, folders={"run folder": path})
            with pytest.raises(argparse.ArgumentTypeError, match=re.escape(f"{path} is {kind}")):
                output_folder(str(path))
    assert (tmp_path / "notes.txt").read_text() == "mine" and stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


def test_an_output_folder_that_is_or_holds_an_input_is_refused(tmp_path, monkeypatch):
    data = tmp_path / "data"
    (data / "audio").mkdir(parents=True)
    (tmp_path / "data_link").symlink_to(data)
    video = tmp_path / "videos" / "me.mp4"
    video.parent.mkdir()
    video.write_bytes(b"video")
    monkeypatch.chdir(tmp_path)
    for out in (data, "data", "./videos/../data", tmp_path / "data_link"):
        with pytest.raises(DancesynthError, match=re.escape(
                f"The run folder {out} is the dataset {data}; choose another output folder so that the dataset is "
                "not overwritten.")):
            check_outputs({}, {"dataset": data}, folders={"run folder": out})
    for out, source in ((tmp_path, data), (".", "data")):
        with pytest.raises(DancesynthError, match=re.escape(f"The run folder {out} holds the input {source}; ")):
            check_outputs({}, {"input": source}, folders={"run folder": out})
    check_outputs({}, {"input": video}, folders={"run folder": tmp_path / "videos"})  # writes its own names there


def test_an_output_folder_beside_or_inside_its_inputs_or_existing_is_accepted(tmp_path):
    data, run = tmp_path / "data", tmp_path / "runs" / "lstm"
    run.mkdir(parents=True)
    (run / "latest.json").write_text("{}")  # a run resumed in place
    data.mkdir()
    for out in (run, tmp_path / "runs" / "new", data / "run", tmp_path / "data_and_more", None):
        check_outputs({}, {"dataset": data, "config": None}, folders={"run folder": out})


def test_a_write_removes_temporary_files_of_killed_writers_and_nothing_else(tmp_path):
    killed = subprocess.Popen(["sleep", "30"])
    killed.kill()  # SIGKILL: the writer could not delete its temporary file
    killed.wait()
    dead, alive = killed.pid, os.getppid()
    stale = tmp_path / f".dance.{dead}-0123abcd{PART_MARKER}.mp4"
    kept = [tmp_path / f".dance.{alive}-0123abcd{PART_MARKER}.mp4",  # its writer still runs
            tmp_path / f".dance.{dead}-not-hex{PART_MARKER}.mp4",  # not a name temporary_sibling makes
            tmp_path / f"dance.{dead}-0123abcd{PART_MARKER}.mp4",  # not hidden: the user's file
            tmp_path / f".other.{dead}-0123abcd{PART_MARKER}"]  # a folder
    for path in [stale, *kept[:3]]:
        path.write_bytes(b"partial")
    kept[3].mkdir()
    with atomic_path(tmp_path / "dance.mp4") as tmp:
        tmp.write_bytes(b"video")
    assert not stale.exists() and all(path.exists() for path in kept)
    assert (tmp_path / "dance.mp4").read_bytes() == b"video"
