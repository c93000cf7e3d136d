import csv
import json
import logging
import os
import random
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from torch import nn

import dancesynth.core.checkpoint as ckpt
from dancesynth.core import progress
from dancesynth.core.errors import DancesynthError
from dancesynth.core.runs import RunFolder

REPO = Path(__file__).resolve().parents[2]
CPU = torch.device("cpu")
STEPS, EVERY = 6, 2


def toy_training(run_dir: Path, resume: bool = False) -> nn.Module:
    """A tiny run using every RNG (python, numpy, torch), an optimizer with state and a metrics table."""
    torch.manual_seed(0)
    np.random.seed(0)
    random.seed(0)
    model = nn.Linear(3, 1)
    opt = torch.optim.Adam(model.parameters(), lr=0.1)
    run = RunFolder(run_dir, "toy", CPU, resume=resume)
    step = 0
    if resume:
        meta, extra = run.restore(model, {"adam": opt})
        step = meta["step"]
        assert extra == {"position": step}
    while step < STEPS:
        x = torch.randn(4, 3) + float(np.random.rand()) + random.random()
        loss = (model(x) - 1.0).pow(2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        step += 1
        run.log("metrics", {"step": step, "loss": loss.item()})
        if step % EVERY == 0:
            run.save(model, {"step": step}, {"adam": opt}, {"position": step})
    run.close()
    return model


def _rows(run_dir: Path) -> list[dict[str, str]]:
    with open(run_dir / "metrics.csv", newline="") as f:
        return list(csv.DictReader(f))


def _assert_same_run(straight: Path, resumed: Path) -> None:
    a, b = ckpt.load_checkpoint(straight, "toy")[0], ckpt.load_checkpoint(resumed, "toy")[0]
    for k in a:
        assert torch.equal(a[k], b[k]), k
    assert _rows(straight) == _rows(resumed)
    # Nothing an interrupted save left behind survives the resumed run's saves.
    assert _entries(resumed) == _entries(straight) == ["ckpt-00000006", "latest.json", "metrics.csv"]


def _entries(run_dir: Path) -> list[str]:
    """Names in a run folder, without the random id of checkpoint folders."""
    return sorted(p.name.rsplit("-", 1)[0] if p.name.startswith("ckpt-") else p.name for p in run_dir.iterdir())


@pytest.fixture(scope="module")
def straight(tmp_path_factory) -> Path:
    run = tmp_path_factory.mktemp("straight") / "run"
    toy_training(run)
    return run


def test_refuses_to_overwrite_a_trained_run_and_to_resume_an_empty_folder(straight, tmp_path):
    with pytest.raises(DancesynthError, match="already holds a trained model; pass --resume"):
        RunFolder(straight, "toy", CPU)
    with pytest.raises(DancesynthError, match="does not exist"):
        RunFolder(tmp_path / "new", "toy", CPU, resume=True)
    with pytest.raises(DancesynthError, match="holds no checkpoint"):
        RunFolder(tmp_path, "toy", CPU, resume=True)


def test_a_fresh_run_in_a_folder_without_checkpoint_starts_its_tables_empty(tmp_path):
    """A run killed before its first checkpoint is started again, not appended to."""
    (tmp_path / "metrics.csv").write_text("step,loss\n1,0.5\n")
    run = RunFolder(tmp_path, "toy", CPU)
    run.log("metrics", {"step": 1, "loss": 0.25})
    assert _rows(tmp_path) == [{"step": "1", "loss": "0.25"}]


def test_a_table_grows_columns_a_later_phase_logs(tmp_path):
    run = RunFolder(tmp_path, "toy", CPU)
    run.log("metrics", {"step": 1, "a": 1.0})
    run.log("metrics", {"step": 2, "b": 2.0})
    assert _rows(tmp_path) == [{"step": "1", "a": "1.0", "b": ""}, {"step": "2", "a": "", "b": "2.0"}]
    run.plot("loss.png")
    assert (tmp_path / "loss.png").stat().st_size > 0


def test_tensorboard_gets_the_numbers_and_drops_what_a_resumed_run_logs_again(straight, tmp_path, monkeypatch):
    """With the optional tensorboard package (replaced here by a recorder) every number goes to event files too."""
    import types

    writers = []

    class SummaryWriter:
        def __init__(self, log_dir, purge_step=None):
            self.log_dir, self.purge_step, self.scalars, self.closed = log_dir, purge_step, [], False
            writers.append(self)

        def add_scalar(self, tag, value, step):
            self.scalars.append((tag, value, step))

        def close(self):
            self.closed = True

    monkeypatch.setitem(sys.modules, "torch.utils.tensorboard", types.SimpleNamespace(SummaryWriter=SummaryWriter))
    shutil.copytree(straight, tmp_path / "run")
    run = RunFolder(tmp_path / "run", "toy", CPU, resume=True)
    run.restore(nn.Linear(3, 1), {})
    run.log("metrics", {"step": 7, "epoch": 0, "loss": 0.5})
    run.close()
    (writer,) = writers
    assert writer.log_dir == str(tmp_path / "run" / "tensorboard") and writer.purge_step == STEPS + 1
    assert writer.scalars == [("metrics/loss", 0.5, 7)] and writer.closed


class Crash(BaseException):
    """Stands for the process dying: not an Exception, so nothing on the way handles it."""


# The file operations of a save, in order: weights, training state, folder rename, pointer switch, old folder removal.
OPERATIONS = [("dancesynth.core.checkpoint.save_file", 1), ("torch.save", 1), ("os.replace", 1), ("os.replace", 2),
              ("shutil.rmtree", 1)]


@pytest.mark.parametrize("after", [False, True], ids=["before", "after"])
@pytest.mark.parametrize("operation", range(len(OPERATIONS)), ids=[f"{n}#{k}" for n, k in OPERATIONS])
def test_a_save_interrupted_at_any_operation_resumes_exactly(straight, tmp_path, monkeypatch, operation, after):
    """The second save dies just before or just after one of its file operations; resume ends as if it had not."""
    target, nth = OPERATIONS[operation]
    module_name, attr = target.rsplit(".", 1)
    module = sys.modules[module_name] if module_name in sys.modules else __import__(module_name)
    real_op, real_save = getattr(module, attr), ckpt.save_checkpoint
    state = {"saves": 0, "calls": 0}

    def op(*args, **kwargs):
        armed = state["saves"] == 2
        state["calls"] += armed
        if armed and state["calls"] == nth and not after:
            raise Crash
        result = real_op(*args, **kwargs)
        if armed and state["calls"] == nth:
            raise Crash
        return result

    def save(*args, **kwargs):
        state["saves"] += 1
        state["calls"] = 0
        return real_save(*args, **kwargs)

    monkeypatch.setattr(module, attr, op)
    monkeypatch.setattr(ckpt, "save_checkpoint", save)
    with pytest.raises(Crash):
        toy_training(tmp_path / "run")
    monkeypatch.undo()
    # Whichever checkpoint is current (step 2 or 4), training continues from it to the same end.
    assert ckpt.load_meta(tmp_path / "run", "toy")["step"] in (2, 4)
    toy_training(tmp_path / "run", resume=True)
    _assert_same_run(straight, tmp_path / "run")


KILL_POINTS = ("inside_weights", "before_switch", "after_switch", "after_save")


@pytest.fixture(scope="module")
def killed_runs(tmp_path_factory) -> Path:
    """One run folder per kill point, each SIGKILLed during its second save (one interpreter start for all)."""
    root = tmp_path_factory.mktemp("killed")
    proc = subprocess.run([sys.executable, __file__, str(root), *KILL_POINTS],
                          env={**os.environ, "PYTHONPATH": str(REPO)}, capture_output=True, text=True, timeout=300)
    assert proc.stdout.split() == [f"{point}:{int(signal.SIGKILL)}" for point in KILL_POINTS], proc.stderr[-2000:]
    return root


@pytest.mark.parametrize("point", KILL_POINTS)
def test_kill_9_at_any_point_of_a_save_resumes_exactly(straight, killed_runs, point):
    """SIGKILL during the second save: leftovers stay on disk as they would after a real crash."""
    run = killed_runs / point
    if point == "inside_weights":  # a half-written checkpoint folder is on disk, not yet named as complete
        assert [p for p in run.iterdir() if p.name.startswith(".ckpt-")]
    toy_training(run, resume=True)
    _assert_same_run(straight, run)


def _train_and_die(run_dir: Path, point: str) -> None:
    """Run :func:`toy_training`, SIGKILLing this process at ``point`` of its second save."""
    saves = []

    def die() -> None:
        os.kill(os.getpid(), signal.SIGKILL)

    real_save, real_save_file, real_replace, real_rmtree = (ckpt.save_checkpoint, ckpt.save_file, os.replace,
                                                            shutil.rmtree)

    def save(*args, **kwargs):
        saves.append(1)
        real_save(*args, **kwargs)
        if len(saves) == 2 and point == "after_save":
            die()

    def save_file(tensors, path, metadata=None):
        real_save_file(tensors, path, metadata=metadata)
        if len(saves) == 2 and point == "inside_weights":
            with open(path, "r+b") as f:
                f.truncate(os.path.getsize(path) // 2)
            die()

    def replace(src, dst):
        if len(saves) == 2 and point == "before_switch" and Path(dst).name == ckpt.POINTER:
            die()
        real_replace(src, dst)

    def rmtree(path, *args, **kwargs):
        if len(saves) == 2 and point == "after_switch":
            die()
        real_rmtree(path, *args, **kwargs)

    ckpt.save_checkpoint, ckpt.save_file, os.replace, shutil.rmtree = save, save_file, replace, rmtree
    toy_training(run_dir)


if __name__ == "__main__":
    # Each kill point in a forked child (cheap: torch is imported once and has run nothing yet).
    for point in sys.argv[2:]:
        child = os.fork()
        if child == 0:
            _train_and_die(Path(sys.argv[1]) / point, point)
            os._exit(0)
        print(f"{point}:{os.WTERMSIG(os.waitpid(child, 0)[1])}", flush=True)


def test_every_file_a_run_writes_has_the_same_mode(straight):
    """safetensors creates its files 0600; a run's files are readable like the rest (0644 with umask 022)."""
    modes = {path.relative_to(straight).as_posix(): path.stat().st_mode & 0o777
             for path in straight.rglob("*") if path.is_file()}
    assert len(set(modes.values())) == 1, modes
    mask = os.umask(0o022)
    os.umask(mask)
    assert set(modes.values()) == {0o666 & ~mask}


def test_an_edited_pointer_naming_another_folder_deletes_no_checkpoint(straight, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(straight, run)
    meta = (run / "latest.json").read_text()
    current = next(p.name for p in run.iterdir() if p.name.startswith("ckpt-"))
    for name in ("../elsewhere", "ckpt-00000009-0", 5):
        (run / "latest.json").write_text(meta.replace(f'"{current}"', json.dumps(name)))
        with pytest.raises(DancesynthError, match="latest.json|is missing"):
            RunFolder(run, "toy", CPU, resume=True).restore(nn.Linear(3, 1), {})
        assert (run / current / "model.safetensors").is_file()


def test_training_progress_counts_steps_or_the_budget_with_time_left(tmp_path, monkeypatch, caplog):
    monkeypatch.setattr(progress, "LOG_INTERVAL_S", 0.0)  # a line at every step
    caplog.set_level(logging.INFO, logger=progress.__name__)
    with RunFolder(tmp_path / "steps", "toy", CPU).training(lambda: None, None, 4, 0, "toy") as session:
        assert not any(session.step_done(step, loss="0.5") for step in range(1, 3))
    line = caplog.messages[-2]  # the last line before the closing one ("took ...")
    assert line.startswith("toy: 2/4 step (50%)") and line.endswith(" left, step=2, loss=0.5")
    with RunFolder(tmp_path / "budget", "toy", CPU).training(lambda: None, 1.5, 4, 0, "toy") as session:
        session.step_done(1)
    assert caplog.messages[-2].startswith("toy: 0/90 s (0%)")
