"""Fault campaign: real `dancesynth` processes under concurrency, kill -9, a full disk and a read-only disk.

    python benchmarks/fault_campaign.py [--kills 6] [--writers 3] [--work DIR]

Cases (each trial runs the CLI as a subprocess, so nothing is shared with this script):

* two writers: two `generate` processes write the same pose file and preview video at once; both must exit 0
  and leave one complete, valid file of each (the last rename wins) and no temporary file;
* kill -9 while saving: `train-pose --method lstm --checkpoint-every 1` killed at a random moment after its
  first checkpoint; `--resume` must finish the run and `generate` must load it, every time, leaving exactly one
  checkpoint folder and no temporary file;
* disk full: commands writing onto a tmpfs of 2 MB that is already full must exit 1 with one error line and
  leave the disk as it was (needs root to mount; skipped with the reason otherwise); once space is freed, the
  `--resume` that failed must succeed with a clean metrics table;
* read-only: the same tmpfs remounted read-only, including `--resume` of a run stored on it.

A tiny dataset (`make-dataset --clips 6 --seconds 10`) and LSTM runs keep it to a few minutes on one CPU core.
It prints one row per case: trials run, trials passed, tracebacks seen, leftovers found.
"""

from __future__ import annotations

import argparse
import csv
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from dancesynth.core.media import probe_video  # noqa: E402
from dancesynth.core.skeleton import PoseSequence  # noqa: E402

LSTM = ["--method", "lstm", "--preview-every", "0", "--device", "cpu", "--set", "hidden=8",
        "--set", "window_frames=30", "--batch-size", "4"]


@dataclass
class Tally:
    """One row of the table."""

    case: str
    ran: int = 0
    passed: int = 0
    tracebacks: int = 0
    leftovers: int = 0
    note: str = ""

    def add(self, ok: bool, errors: list[str], leftovers: list[str]) -> None:
        self.ran += 1
        self.tracebacks += sum("Traceback" in err for err in errors)
        self.leftovers += len(leftovers)
        self.passed += int(ok and not leftovers and not any("Traceback" in err for err in errors))
        if leftovers:
            print(f"  leftovers in {self.case}: {leftovers}", flush=True)


def cli(*args: str, wait: bool = True) -> subprocess.CompletedProcess | subprocess.Popen:
    """Run `dancesynth ARGS` in a fresh interpreter (or start it when not ``wait``)."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}
    command = [sys.executable, "-m", "apps.cli", *args]
    if not wait:
        return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    return subprocess.run(command, capture_output=True, text=True, env=env)


def one_error_line(done: subprocess.CompletedProcess) -> bool:
    """Exit 1 with exactly one `dancesynth CMD: error:` line, the last thing on stderr."""
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    return done.returncode == 1 and bool(lines) and sum("error:" in line for line in lines) == 1 \
        and "error:" in lines[-1] and "Traceback" not in done.stderr


def temporaries(folder: Path) -> list[str]:
    return [str(p) for p in folder.rglob("*") if ".part" in p.name]


def listing(folder: Path) -> dict[str, int]:
    return {str(p.relative_to(folder)): (p.stat().st_size if p.is_file() else -1) for p in folder.rglob("*")}


def two_writers(work: Path, run: Path, song: Path, trials: int) -> Tally:
    tally = Tally("two writers, one output")
    out = work / "writers"
    out.mkdir()
    for trial in range(trials):
        procs = [cli("generate", str(song), "--model", str(run), "--out", str(out / "same.npz"), "--preview",
                     str(out / "same.mp4"), "--seed", str(seed), "--device", "cpu", wait=False) for seed in (1, 2)]
        results = [proc.communicate() for proc in procs]
        errors = [err for _, err in results]
        ok = all(proc.returncode == 0 for proc in procs)
        try:
            poses = PoseSequence.load(out / "same.npz")
            ok = ok and probe_video(out / "same.mp4").num_frames == len(poses) > 0
        except Exception as e:  # a corrupt file is what this case looks for
            print(f"  trial {trial}: output unreadable: {e}", flush=True)
            ok = False
        tally.add(ok, errors, temporaries(out))
    return tally


def kill_during_saves(work: Path, data: Path, song: Path, kills: int, rng: random.Random) -> Tally:
    tally = Tally("kill -9 while checkpointing")
    for trial in range(kills):
        run = work / f"killed_{trial}"
        proc = cli("train-pose", *LSTM, "--data", str(data), "--out", str(run), "--epochs", "3",
                   "--checkpoint-every", "1", wait=False)
        while not (run / "latest.json").exists() and proc.poll() is None:
            time.sleep(0.01)
        time.sleep(rng.uniform(0.0, 1.5))
        finished_first = proc.poll() is not None
        proc.send_signal(signal.SIGKILL)
        _, err = proc.communicate()
        resumed = cli("train-pose", *LSTM, "--data", str(data), "--out", str(run), "--epochs", "3", "--resume")
        generated = cli("generate", str(song), "--model", str(run), "--out", str(work / f"killed_{trial}.npz"),
                        "--device", "cpu")
        checkpoints = [p.name for p in run.iterdir() if p.name.startswith("ckpt-")]
        leftovers = temporaries(run) + (checkpoints[1:] if len(checkpoints) > 1 else [])
        ok = resumed.returncode == 0 and generated.returncode == 0
        if not ok:
            print(f"  trial {trial}: resume {resumed.returncode} {resumed.stderr.strip()[-300:]} | generate "
                  f"{generated.returncode} {generated.stderr.strip()[-300:]}", flush=True)
        if finished_first:
            tally.note = "some trainings finished before the kill"
        tally.add(ok, [err, resumed.stderr, generated.stderr], leftovers)
    return tally


def mount_small_disk(folder: Path) -> str:
    """Mount a 2 MB tmpfs on ``folder``; returns why not ('' when mounted)."""
    folder.mkdir()
    if os.geteuid() != 0 or shutil.which("mount") is None:
        return "needs root and mount(8)"
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(folder)], capture_output=True,
                          text=True)
    return "" if done.returncode == 0 else f"mount failed: {done.stderr.strip()}"


def fill(folder: Path) -> None:
    """Write a filler file until ``folder``'s file system is full."""
    with open(folder / "filler", "wb", buffering=0) as f:
        try:
            while True:
                f.write(b"x" * 4096)
        except OSError:
            pass


def refused_cleanly(tally: Tally, disk: Path, commands: list[list[str]], may_grow: str = "") -> None:
    """Each command must fail with one error line and leave ``disk`` as it was (except the file ``may_grow``)."""
    for args in commands:
        before = listing(disk)
        done = cli(*args)
        after = listing(disk)
        changed = sorted({name for name, _ in set(after.items()) ^ set(before.items())} - {may_grow})
        if not one_error_line(done):
            print(f"  {' '.join(args[:1])}: exit {done.returncode}: {done.stderr.strip()[-400:]}", flush=True)
        tally.add(one_error_line(done), [done.stderr], changed)


def full_and_read_only(work: Path, data: Path, run: Path, song: Path) -> list[Tally]:
    full, read_only = Tally("disk full"), Tally("read-only output")
    disk = work / "disk"
    why = mount_small_disk(disk)
    if why:
        full.note = read_only.note = f"skipped: {why}"
        return [full, read_only]
    try:
        shutil.copytree(run, disk / "run")
        fill(disk)
        writes = [["generate", str(song), "--model", str(run), "--out", str(disk / "p.npz"), "--device", "cpu"],
                  ["generate", str(song), "--model", str(run), "--out", str(work / "ok.npz"), "--preview",
                   str(disk / "p.mp4"), "--device", "cpu"],
                  ["make-dataset", "--out", str(disk / "ds"), "--clips", "2", "--seconds", "4", "--workers", "1"],
                  ["train-pose", *LSTM, "--data", str(data), "--out", str(disk / "new_run"), "--epochs", "1"],
                  ["train-pose", *LSTM, "--data", str(data), "--out", str(disk / "run"), "--epochs", "4",
                   "--resume"]]
        # A resumed run logs each epoch before its checkpoint fails; the next --resume drops those rows (checked).
        refused_cleanly(full, disk, writes, may_grow="run/metrics.csv")
        (disk / "filler").unlink()
        resumed = cli("train-pose", *LSTM, "--data", str(data), "--out", str(disk / "run"), "--epochs", "4",
                      "--resume")
        with open(disk / "run" / "metrics.csv", newline="") as f:
            epochs = [int(row["epoch"]) for row in csv.DictReader(f)]
        full.add(resumed.returncode == 0 and epochs == list(range(4)), [resumed.stderr], temporaries(disk))
        done = subprocess.run(["mount", "-o", "remount,ro", str(disk)], capture_output=True, text=True)
        if done.returncode != 0:
            read_only.note = f"skipped: remount read-only failed: {done.stderr.strip()}"
            return [full, read_only]
        refused_cleanly(read_only, disk, writes + [["extract-poses", str(song), "--out", str(disk / "p.npz")]])
    finally:
        subprocess.run(["umount", "-l", str(disk)], check=False)
    return [full, read_only]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--kills", type=int, default=6, help="kill -9 trials (default 6)")
    parser.add_argument("--writers", type=int, default=3, help="two-writer trials (default 3)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--work", type=Path, help="work folder (default: a new temporary one, deleted after)")
    args = parser.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix="fault_campaign_"))
    work.mkdir(parents=True, exist_ok=True)
    rng = random.Random(args.seed)
    start = time.time()
    try:
        data, run = work / "data", work / "lstm"
        for setup in (["make-dataset", "--out", str(data), "--clips", "6", "--seconds", "10", "--workers", "1"],
                      ["train-pose", *LSTM, "--data", str(data), "--out", str(run), "--epochs", "1"]):
            done = cli(*setup, "-q")
            if done.returncode != 0:
                sys.exit(f"setup failed: {' '.join(setup[:1])}: {done.stderr}")
        song = sorted((data / "audio").iterdir())[0]
        print(f"setup done in {time.time() - start:.0f} s", flush=True)
        tallies = [two_writers(work, run, song, args.writers), kill_during_saves(work, data, song, args.kills, rng),
                   *full_and_read_only(work, data, run, song)]
    finally:
        if args.work is None:
            shutil.rmtree(work, ignore_errors=True)
    print("\n| case | ran | passed | tracebacks | leftovers | note |\n|---|---|---|---|---|---|")
    for t in tallies:
        print(f"| {t.case} | {t.ran} | {t.passed} | {t.tracebacks} | {t.leftovers} | {t.note} |")
    print(f"\n{time.time() - start:.0f} s in all")
    sys.exit(0 if all(t.passed == t.ran for t in tallies) else 1)


if __name__ == "__main__":
    main()
