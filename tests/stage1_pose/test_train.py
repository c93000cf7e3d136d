import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import torch

# The machine is shared: one intra-op thread avoids OpenMP contention that makes tiny ops take milliseconds.
torch.set_num_threads(1)

from dancesynth.core.checkpoint import load_checkpoint  # noqa: E402
from dancesynth.core.errors import DancesynthError  # noqa: E402
from dancesynth.core.runs import epoch_order  # noqa: E402
from stage1_pose.train import TrainerConfig, rank_batches, train  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
TINY_DR = dict(d_model=16, heads=2, d_k=8, d_v=8, d_ff=32, layers=1, window=6, dropout=0.1, lstm_hidden=32,
               window_frames=30, batch_size=4, lam=1.0, q=3, epoch_windows=0)
# No dropout of either kind: its masks are drawn per process, so two processes could not equal one.
TINY_LSTM = dict(hidden=16, layers=2, dropout=0.0, feature_dropout=0.0, window_frames=30, batch_size=4, epoch_windows=0)


def _weights(run: Path) -> dict[str, torch.Tensor]:
    return load_checkpoint(run, "stage1")[0]


def test_data_order_depends_only_on_seed_and_epoch():
    assert epoch_order(50, 0, 3) == epoch_order(50, 0, 3) != epoch_order(50, 0, 4)
    # A fixed-size epoch passes over a small dataset again, every window as often as the others (+-1).
    longer = epoch_order(10, 0, 3, 25)
    assert len(longer) == 25 and longer[:10] == epoch_order(10, 0, 3)
    assert sorted(longer.count(i) for i in range(10)) == [2] * 5 + [3] * 5
    batches = [rank_batches(list(range(10)), 4, r, 2) for r in (0, 1)]
    assert batches == [[[0, 1], [4, 5]], [[2, 3], [6, 7]]]


def test_run_folder_outputs(tiny_stage1_dataset, tmp_path):
    meta = train("dance_revolution", tiny_stage1_dataset, tmp_path / "run", overrides=TINY_DR, epochs=2,
                 options=TrainerConfig(preview_every=2, preview_seconds=2, preview_gap_minutes=0))
    run = tmp_path / "run"
    assert meta["epoch"] == 2 and meta["curriculum"]["p"] == 1 and meta["feature_kind"] == "dance_revolution"
    assert len(meta["feature_stats"]["mean"]) == 438 and meta["canvas"] == [1280, 720] and meta["fps"] == 15.0
    rows = (run / "metrics.csv").read_text().splitlines()
    assert rows[0] == "epoch,step,seconds,accel,bone_rows,kl,l1,p,speed" and len(rows) == 3
    assert (run / "loss.png").stat().st_size > 0 and (run / "previews" / "epoch_0002.mp4").stat().st_size > 0
    with pytest.raises(DancesynthError, match="already holds"):
        train("dance_revolution", tiny_stage1_dataset, run, overrides=TINY_DR, epochs=2)
    with pytest.raises(DancesynthError, match="--method dance_revolution"):
        train("lstm", tiny_stage1_dataset, run, resume=True)
    with pytest.raises(DancesynthError, match="no setting"):
        train("lstm", tiny_stage1_dataset, tmp_path / "other", overrides={"hiden": 3})


def test_metrics_columns_of_a_later_training_phase_are_labelled(tiny_stage1_dataset, tmp_path):
    """Dancing2Music logs other losses in its composition phase: metrics.csv grows the columns, never shifts them."""
    import csv

    tiny = dict(gru_hidden=16, mlp_hidden=16, z_mov=4, z_dan=4, noise_dim=2, epochs=2, decomp_epochs=1, epoch_windows=0,
                batch_size=4, window_frames=60)
    # Previews are due every epoch but the gap since the start is never reached: none is drawn.
    train("dancing2music", tiny_stage1_dataset, tmp_path / "run", overrides=tiny,
          options=TrainerConfig(preview_every=1, preview_gap_minutes=60))
    assert not (tmp_path / "run" / "previews").exists()
    with open(tmp_path / "run" / "metrics.csv", newline="") as f:
        first, second = list(csv.DictReader(f))
    phase1 = {k for k, v in first.items() if v}
    phase2 = {k for k, v in second.items() if v}
    assert {"epoch", "step"} <= phase1 & phase2 and phase2 - phase1 and phase1 - phase2
    assert all(float(v) == float(v) for v in second.values() if v)  # every logged value is a number


KILLER = """
import os, signal, sys, torch
torch.set_num_threads(1)
import dancesynth.core.checkpoint as ckpt
import stage1_pose.train as t
saves = []
real_save = ckpt.save_checkpoint
def save_then_die(*args, **kwargs):
    real_save(*args, **kwargs)
    saves.append(1)
    if len(saves) == 2:
        os.kill(os.getpid(), signal.SIGKILL)
ckpt.save_checkpoint = save_then_die
t.train("dance_revolution", sys.argv[1], sys.argv[2], overrides={overrides!r}, epochs=2,
        options=t.TrainerConfig(checkpoint_every=3, preview_every=0))
"""


def test_resume_after_kill_9_gives_the_same_weights(tiny_stage1_dataset, tmp_path):
    options = TrainerConfig(checkpoint_every=3, preview_every=0)
    train("dance_revolution", tiny_stage1_dataset, tmp_path / "straight", overrides=TINY_DR, epochs=2, options=options)
    script = tmp_path / "killer.py"
    script.write_text(textwrap.dedent(KILLER.format(overrides=TINY_DR)))
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.run([sys.executable, str(script), str(tiny_stage1_dataset), str(tmp_path / "killed")],
                          env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == -9, proc.stderr[-2000:]
    meta = train("dance_revolution", tiny_stage1_dataset, tmp_path / "killed", resume=True, options=options)
    assert meta["epoch"] == 2 and meta["curriculum"]["p"] == 1
    straight, resumed = _weights(tmp_path / "straight"), _weights(tmp_path / "killed")
    assert straight.keys() == resumed.keys()
    for k in straight:
        assert torch.equal(straight[k], resumed[k]), k
    csv_rows = (tmp_path / "killed" / "metrics.csv").read_text().splitlines()
    assert [r.split(",")[0] for r in csv_rows[1:]] == ["0", "1"]


def _ddp_worker(rank: int, data: str, out: str, port: int) -> None:
    os.environ.update(MASTER_ADDR="127.0.0.1", MASTER_PORT=str(port), RANK=str(rank), WORLD_SIZE="2")
    torch.set_num_threads(1)
    from dancesynth.core.device import resolve_device
    from dancesynth.core.runs import RunFolder
    from stage1_pose.registry import make_config
    from stage1_pose.train import KIND, PoseTrainer

    device = resolve_device("cpu")
    trainer = PoseTrainer("lstm", Path(data), RunFolder(out, KIND, device), make_config("lstm", "small", TINY_LSTM),
                      TrainerConfig(epochs=1, preview_every=0), device)
    trainer.run()
    torch.save(trainer.method.state_dict(), Path(out).parent / f"rank{rank}.pt")
    assert not torch.distributed.is_initialized()  # the run left the group it joined


def test_two_process_training_equals_one_process_on_the_same_global_batch(tiny_stage1_dataset, tmp_path):
    train("lstm", tiny_stage1_dataset, tmp_path / "single", overrides=TINY_LSTM, epochs=1,
          options=TrainerConfig(preview_every=0))
    port = 29500 + os.getpid() % 1000
    torch.multiprocessing.spawn(_ddp_worker, args=(str(tiny_stage1_dataset), str(tmp_path / "ddp" / "run"), port),
                                nprocs=2)
    ranks = [torch.load(tmp_path / "ddp" / f"rank{r}.pt", weights_only=True) for r in (0, 1)]
    single = _weights(tmp_path / "single")
    for k in single:
        assert torch.equal(ranks[0][k], ranks[1][k]), k
        # Gradients summed in another order: float32 rounding, amplified a little by the kinematic output's norms.
        torch.testing.assert_close(ranks[0][k], single[k], rtol=1e-5, atol=1e-5)
    assert _weights(tmp_path / "ddp" / "run").keys() == single.keys()
