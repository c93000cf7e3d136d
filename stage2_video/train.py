"""Training the appearance model (pix2pixHD + Everybody Dance Now temporal smoothing) on one target video.

Run folder layout (``RUN_DIR``, a :class:`dancesynth.core.runs.RunFolder`):
  latest.json + ckpt-<step>-<id>/                         checkpoint (kind "stage2"), resumable exactly
  poses.npz                                               the target's poses (extracted once, or given)
  frames_<W>x<H>.npy                                      framed training frames (uint8 memory map)
  background.png                                          the target's scene without the person (stage2_video.composite)
  losses.csv, validation.csv, losses.png                  per-step losses, held-out (and selection) SSIM/PSNR, plot
  frames_<2W>x<2H>.npy, masks_<2W>x<2H>.npy               with the warped prior: the frame bank and person masks
  samples/step_XXXXXXX.png                                held-out frames: real | skeleton | (prior |) generated

With a ``select_fraction`` the checkpoint keeps, beside the latest weights, those of the step that scored best on the
selection frames (the warped prior alone, step 0, included); the model renders with those.

Each step takes consecutive frame pairs (t-1, t): G renders t-1 from its skeleton and a black previous
frame, then t from its skeleton and that generated frame, as at render time. Torchrun-ready: with
WORLD_SIZE > 1 each rank takes its DistributedSampler share, gradients are averaged, rank 0 writes.
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import torch
import torch.nn.functional as F
from torch.utils.data import DistributedSampler

from dancesynth.core.checkpoint import POINTER, load_checkpoint, run_file_contents
from dancesynth.core.config import config_from_dict, config_to_dict
from dancesynth.core.device import precision_name, resolve_device, resolve_precision
from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import atomic_path, require_file
from dancesynth.core.runs import RunFolder, TrainingSession
from stage2_video.composite import cache_plate
from stage2_video.framing import FollowFraming, framing_from_dict, video_framing
from stage2_video.masks import cache_masks
from stage2_video.models.pix2pixhd import (
    LABEL_CHANNELS,
    Pix2PixHD,
    Pix2PixHDConfig,
    blend_base,
    carry_correction,
    feature_matching_loss,
    foreground_target,
    lsgan_loss,
    preset,
)
from stage2_video.normalize import body_stats
from stage2_video.prior import scaled_framing
from stage2_video.quality import box_scores, psnr, ssim
from stage2_video.retarget import target_bone_lengths
from stage2_video.training_data import (
    KIND,
    FramePairs,
    TargetVideo,
    cache_frames,
    check_poses_match,
    frame_bank,
    load_or_extract_poses,
    selection_split,
    split_ranges,
    to_image,
    to_tensor,
)
from stage2_video.vgg import VGGLoss, build_vgg_loss

METHOD = "pix2pixhd"
# What a kept checkpoint's select_ssim measures for a model repairing the warped prior: since 2026-12-06 the
# person's box at the output's size (before, the whole crop at the model's size; not comparable, so a run resumed
# from then scores its kept weights again).
SCORE_MEASURE = "person box at output size"


@dataclass
class TrainOptions:
    """How long and how often: ``minutes`` (wall-clock training time of the run in all, every call together:
    :mod:`dancesynth.core.runs`) and/or ``epochs`` (total); ``max_steps`` stops this invocation after that many
    steps (smoke tests, resume checks). A budget without a step left (0 minutes, or 0 steps) takes no step: it
    prepares the run (poses, frames, masks, plate) and saves the model, untrained on a new run, which renders the
    warped prior alone (:attr:`Pix2PixHDConfig.prior`)."""

    minutes: float | None = None
    epochs: int | None = None
    checkpoint_every: int = 200
    sample_every: int = 200
    val_frames: int = 64
    seed: int = 0
    max_steps: int | None = None


class VideoTrainer:
    """Holds the model, optimizers, data and position of one run; :meth:`fit` trains until a budget is spent."""

    def __init__(self, config: Pix2PixHDConfig, target: TargetVideo, run: RunFolder, device: torch.device,
                 vgg: VGGLoss | None, options: TrainOptions, source_video: str,
                 precision: torch.dtype = torch.float32) -> None:
        self.config, self.target, self.folder, self.device = config, target, run, device
        # Forward passes and losses run under autocast to ``precision``; the weights stay float32.
        self.precision = precision
        # fp16 gradients underflow without loss scaling; bf16 has float32's exponent range and needs none.
        self.scaler = torch.amp.GradScaler(device.type, enabled=precision == torch.float16)
        self.options, self.source_video = options, source_video
        self.vgg = vgg.to(device) if vgg is not None else None
        self.run_dir, self.rank, self.world = run.path, run.rank, run.world
        train_range, self.val_range = split_ranges(len(target.poses), config.val_fraction)
        learnt_range, self.select_range = selection_split(train_range, config.select_fraction)
        self.train_set = FramePairs(target, learnt_range)
        if not len(self.train_set):
            raise DancesynthError("The person's body is found in too few consecutive frames of the target video to "
                                  "learn from; use a video where one person stays fully visible.")
        # The step that scored best on the selection frames with its validation scores, and its weights (CPU).
        self.best: dict | None = None
        self.best_weights: dict[str, torch.Tensor] | None = None
        self._validated: tuple[int, dict[str, float]] | None = None
        torch.manual_seed(options.seed)
        if device.type == "cpu":
            # A residual generator's last layer starts at zero, so its first gradients are subnormal floats, which
            # CPUs compute about ten times slower (14 s instead of 1.2 s per step for the first 24 steps, dancer clip).
            torch.set_flush_denormal(True)
        self.model = Pix2PixHD(config).to(device)
        d_params = list(self.model.discriminator.parameters())
        if self.model.temporal_discriminator is not None:
            d_params += list(self.model.temporal_discriminator.parameters())
        betas = (config.beta1, 0.999)
        self.opt_g = torch.optim.Adam(self.model.generator.parameters(), lr=config.lr, betas=betas)
        self.opt_d = torch.optim.Adam(d_params, lr=config.lr, betas=betas)
        self.epoch, self.position, self.step = 0, 0, 0
        self.total_epochs = options.epochs or (config.epochs_constant + config.epochs_decay)

    # --- schedule -------------------------------------------------------------------------------------------
    def lr(self) -> float:
        """pix2pixHD schedule scaled to ``total_epochs``: constant for the ``epochs_constant`` share, then linear
        to 0."""
        const_share = self.config.epochs_constant / max(1, self.config.epochs_constant + self.config.epochs_decay)
        constant = round(self.total_epochs * const_share)
        if self.epoch < constant:
            return self.config.lr
        return self.config.lr * max(0.0, 1.0 - (self.epoch - constant) / max(1, self.total_epochs - constant))

    def _batches(self) -> list[list[int]]:
        sampler = DistributedSampler(self.train_set, num_replicas=self.world, rank=self.rank, shuffle=True,
                                     seed=self.options.seed)
        sampler.set_epoch(self.epoch)
        order = list(sampler)
        bs = self.config.batch_size
        return [order[i:i + bs] for i in range(0, len(order), bs)]

    # --- one update -----------------------------------------------------------------------------------------
    def _sync(self, optimizer: torch.optim.Optimizer) -> None:
        self.folder.average_gradients(p for group in optimizer.param_groups for p in group["params"])

    def train_step(self, batch: list[torch.Tensor]) -> dict[str, float]:
        """One generator and one discriminator update on a batch of consecutive pairs."""
        cfg, model = self.config, self.model
        label_p, real_p, label_c, real_c = (x.to(self.device) for x in batch)
        with torch.autocast(self.device.type, dtype=self.precision, enabled=self.precision != torch.float32):
            fake_p, mask_p = model.generate_with_mask(label_p)
            fake_c, mask_c = model.generate_with_mask(label_c, fake_p)
            labels, reals = torch.cat([label_p, label_c]), torch.cat([real_p, real_c])
            fakes = torch.cat([fake_p, fake_c])
            pairs = [(model.discriminator, torch.cat([labels, reals], 1), torch.cat([labels, fakes], 1))]
            if not cfg.adversarial:
                pairs = []
            elif model.temporal_discriminator is not None:
                pairs.append((model.temporal_discriminator, torch.cat([label_p, label_c, real_p, real_c], 1),
                              torch.cat([label_p, label_c, fake_p, fake_c], 1)))
            loss_d = fakes.new_zeros((), dtype=torch.float32)
            g_gan = fakes.new_zeros((), dtype=torch.float32)
            g_feat = fakes.new_zeros((), dtype=torch.float32)
            for disc, real_in, fake_in in pairs:
                pred_real = disc(real_in)
                pred_fake = disc(fake_in)
                g_gan = g_gan + lsgan_loss(pred_fake, True) * cfg.lambda_gan
                g_feat = g_feat + feature_matching_loss(pred_fake, pred_real, cfg.n_layers_d, cfg.lambda_feat)
                loss_d = loss_d + 0.5 * (lsgan_loss(pred_real, True) + lsgan_loss(disc(fake_in.detach()), False))
            g_vgg = self.vgg(fakes, reals) * cfg.lambda_vgg if self.vgg is not None else g_gan.new_zeros(())
            g_l1 = F.l1_loss(fakes.float(), reals) * cfg.lambda_l1
            loss_g = g_gan + g_feat + g_vgg + g_l1
            if cfg.blend and not cfg.repairs and cfg.lambda_mask:
                target = foreground_target(labels, reals, cfg.prior)
                g_mask = F.l1_loss(torch.cat([mask_p, mask_c]).float(), target) * cfg.lambda_mask
                loss_g = loss_g + g_mask
        self.opt_g.zero_grad(set_to_none=True)
        self.scaler.scale(loss_g).backward()
        self._sync(self.opt_g)
        self.scaler.step(self.opt_g)
        if cfg.adversarial:
            # The generator's backward also reached the discriminators; clear that before their own update.
            self.opt_d.zero_grad(set_to_none=True)
            self.scaler.scale(loss_d).backward()
            self._sync(self.opt_d)
            self.scaler.step(self.opt_d)
        self.scaler.update()
        losses = {"d": loss_d.item(), "g_gan": g_gan.item(), "g_feat": g_feat.item(), "g_vgg": g_vgg.item(),
                  "g_l1": g_l1.item()}
        return {**losses, "g_mask": g_mask.item()} if cfg.blend and not cfg.repairs and cfg.lambda_mask else losses

    # --- loop -----------------------------------------------------------------------------------------------
    def fit(self) -> dict:
        """Train until ``epochs`` are done or the ``minutes`` budget is spent; checkpoint at the end. Ctrl-C or
        SIGTERM saves quickly (no validation), then raises :class:`KeyboardInterrupt`."""
        total_steps = self.total_epochs * len(self._batches())
        if self.step == 0 and self.best is None and self.config.prior and self.folder.writer:
            # The warped prior alone is the first candidate: training that makes it worse is not kept.
            self._track_best(self._log_validation())
        with self.folder.training(lambda: self.checkpoint(validate=False), self.options.minutes, total_steps,
                                  self.step, "training") as session:
            self._loop(session)
        self.write_samples()
        meta = self.checkpoint()
        self.folder.close()
        return meta

    def _loop(self, session: TrainingSession) -> None:
        last_step = self.step + self.options.max_steps if self.options.max_steps is not None else math.inf
        while self.epoch < self.total_epochs and not session.stopped and self.step < last_step:
            for g in (*self.opt_g.param_groups, *self.opt_d.param_groups):
                g["lr"] = self.lr()
            batches = self._batches()
            while self.position < len(batches):
                items = [self.train_set[i] for i in batches[self.position]]
                batch = [torch.stack(xs) for xs in zip(*items)]
                losses = self.train_step(batch)
                self.position += 1
                self.step += 1
                stop = session.step_done(self.step, d=f"{losses['d']:.3f}", l1=f"{losses['g_l1']:.3f}")
                self._log(losses)
                if self.step % self.options.sample_every == 0:
                    self.write_samples()
                if self.step % self.options.checkpoint_every == 0:
                    self.checkpoint()
                if stop or self.step >= last_step:
                    return
            self.epoch, self.position = self.epoch + 1, 0

    # --- outputs (rank 0 only) ------------------------------------------------------------------------------
    def _log(self, losses: dict[str, float]) -> None:
        self.folder.log("losses", {"step": self.step, "epoch": self.epoch, "lr": self.lr(), **losses,
                                   "seconds": round(self.folder.trained_seconds, 1)})

    def _generate(self, label: torch.Tensor, previous: torch.Tensor | None = None) -> torch.Tensor:
        """The model's frame for a ``[1, C, H, W]`` condition; before its first step a model conditioned on the warped
        prior renders the prior alone, as :func:`stage2_video.render.load_appearance_model` does."""
        if self.step == 0 and self.config.prior:
            return blend_base(label, True)
        return self.model.generate(label, previous)

    @torch.no_grad()
    def validate(self) -> dict[str, float]:
        """Mean SSIM / PSNR over up to ``val_frames`` held-out frames, and as ``select_ssim`` / ``select_psnr``
        over the selection frames (each warped only from bank frames more than 1 s away), generated in sequence
        as at render time; a model repairing the warped prior is scored at its output size in the person's box
        (:meth:`_frame_scores`)."""
        scores = self._scores(self.val_range)
        if len(self.select_range):
            scores |= {f"select_{k}": v for k, v in self._scores(self.select_range).items()}
        return scores

    def _scores(self, frames: range) -> dict[str, float]:
        self.model.eval()
        scores, previous = [], None
        pairs = FramePairs(self.target, frames)
        renderer = self.target.renderer()
        for t in [t for t in frames if self.target.usable[t]][:self.options.val_frames]:
            label, _, prior = pairs.sample(t, renderer)
            label = label[None].to(self.device)
            previous = self._generate(label, previous)
            scores.append(self._frame_scores(t, label, previous, prior))
        self.model.train()
        if not scores:
            return {"ssim": math.nan, "psnr": math.nan}
        return dict(zip(("ssim", "psnr"), np.mean(scores, axis=0).tolist()))

    def _frame_scores(self, t: int, label: torch.Tensor, frame: torch.Tensor,
                      prior: np.ndarray | None) -> tuple[float, float]:
        """(SSIM, PSNR) of the model's ``[1, 3, H, W]`` ``frame`` for frame ``t``: for a model that repairs the warped
        prior, at the size it renders (its correction carried onto the bank-size ``prior``) inside the person's box,
        as the real-footage benchmark scores the composited frame (the whole crop at the model's size favoured steps
        that smoothed the person); otherwise over the model's frame."""
        if prior is None or not self.config.repairs:
            fake, real = to_image(frame[0]), np.asarray(self.target.frames[t])
            return ssim(fake, real), psnr(fake, real)
        base_high = to_tensor(prior[..., :3])[None].to(self.device)
        high = to_image(carry_correction(frame.float(), blend_base(label, True), base_high)[0])
        bank = self.target.bank
        return box_scores(high, np.asarray(bank.frames[t]), bank.keypoints[t])

    def _log_validation(self) -> dict[str, float]:
        """This step's validation scores, computed and logged once (a budget of no step validates step 0 once)."""
        if self._validated is None or self._validated[0] != self.step:
            scores = self.validate()
            self.folder.log("validation", {"step": self.step, "epoch": self.epoch, **scores})
            self._validated = (self.step, scores)
        return self._validated[1]

    def _track_best(self, scores: dict[str, float]) -> None:
        """Remember this step's weights when they score best so far on the selection frames."""
        score = scores.get("select_ssim", math.nan)
        if not math.isnan(score) and (self.best is None or score > self.best["select_ssim"]):
            self.best = {"step": self.step, **scores} | ({"measure": SCORE_MEASURE} if self.config.repairs else {})
            self.best_weights = {k: v.detach().to("cpu", copy=True) for k, v in self.model.state_dict().items()}

    def _rescore_best(self) -> None:
        """Score the kept weights again as checkpoints are scored now (a run saved before :data:`SCORE_MEASURE`)."""
        latest = {k: v.detach().clone() for k, v in self.model.state_dict().items()}
        step, self.step = self.step, int(self.best["step"])  # step 0 renders the warp alone
        self.model.load_state_dict(self.best_weights)
        try:
            scores = self.validate()
        finally:
            self.model.load_state_dict(latest)
            self.step = step
        self.best = {"step": int(self.best["step"]), **scores, "measure": SCORE_MEASURE}

    @torch.no_grad()
    def write_samples(self, count: int = 3) -> None:
        """PNG grid of held-out frames, one row each: real | skeleton | (warped prior |) generated (two-frame
        warm-up)."""
        val = FramePairs(self.target, self.val_range)
        if self.rank != 0 or not len(val):
            return
        self.model.eval()
        rows = []
        for t in [val.starts[i] + 1 for i in np.linspace(0, len(val) - 1, count).astype(int)]:
            renderer = self.target.renderer()
            label_p, _ = val.item(t - 1, renderer)
            label, real = val.item(t, renderer)
            previous = self._generate(label_p[None].to(self.device))
            fake = self._generate(label[None].to(self.device), previous)
            row = [to_image(real), to_image(label[:LABEL_CHANNELS])]
            if self.config.prior:
                row.append(to_image(blend_base(label[None], True)[0]))
            rows.append(np.concatenate([*row, to_image(fake[0])], axis=1))
        self.model.train()
        folder = self.run_dir / "samples"
        folder.mkdir(exist_ok=True)
        with atomic_path(folder / f"step_{self.step:07d}.png") as tmp:
            cv2.imwrite(str(tmp), cv2.cvtColor(np.concatenate(rows), cv2.COLOR_RGB2BGR))

    def meta(self) -> dict:
        poses = self.target.poses
        try:
            stats = body_stats(poses).to_dict()
        except DancesynthError:
            stats = None  # the target never shows head and ankles together: render with --no-normalize only
        return {"kind": KIND, "method": METHOD, "config": config_to_dict(self.config), "epoch": self.epoch,
                "position": self.position, "step": self.step, "total_epochs": self.total_epochs,
                "framing": self.target.framing.to_dict(), "target_stats": stats, "fps": poses.fps,
                "canvas": [poses.width, poses.height], "video": self.source_video, "vgg": self.vgg is not None,
                "seed": self.options.seed, "precision": precision_name(self.precision),
                "bone_lengths": target_bone_lengths(poses).tolist()}

    def optimizers(self) -> dict[str, torch.optim.Optimizer]:
        return {"g": self.opt_g, "d": self.opt_d}

    def checkpoint(self, validate: bool = True) -> dict:
        """Append held-out (and selection) SSIM/PSNR to validation.csv (rank 0; unless not ``validate``), then save
        weights + meta + optimizer/RNG state (every rank), the best weights where an earlier step scored better
        on the selection frames, and redraw losses.png."""
        meta = self.meta()
        if self.folder.writer and validate:
            meta["validation"] = self._log_validation()
            self._track_best(meta["validation"])
        best = None
        if self.best is not None:
            meta["best"] = self.best
            best = self.best_weights if self.best["step"] != self.step else None
        meta = self.folder.save(self.model, meta, self.optimizers(), {"scaler": self.scaler.state_dict()}, best)
        self.folder.plot("losses.png")
        return meta

    def restore(self) -> None:
        """Continue from the run folder's latest checkpoint exactly where it stopped."""
        meta, extra = self.folder.restore(self.model, self.optimizers())
        if meta.get("best") is not None:
            self.best = dict(meta["best"])
            self.best_weights = load_checkpoint(self.folder.path, KIND, best=True)[0]
        # A run resumed in fp16 continues with its loss scale; in another precision there is none to restore.
        if self.scaler.is_enabled() and extra.get("scaler"):
            self.scaler.load_state_dict(extra["scaler"])
        with run_file_contents(self.folder.path / POINTER):
            self.epoch, self.position, self.step, total = (int(meta[key]) for key in
                                                           ("epoch", "position", "step", "total_epochs"))
        self.total_epochs = self.options.epochs or total
        if self.best is not None and self.config.repairs and self.folder.writer and \
                self.best.get("measure") != SCORE_MEASURE:
            self._rescore_best()


def train_video(video: str | os.PathLike, run_dir: str | os.PathLike, preset_name: str = "small",
                options: TrainOptions | None = None, resume: bool = False, poses: str | os.PathLike | None = None,
                vgg_weights: str | os.PathLike | None = None, device: str = "auto",
                overrides: dict | None = None, precision: str = "auto") -> dict:
    """Train (or with ``resume`` continue) an appearance model of the person in ``video``; returns the last meta.

    ``poses``: a pose file for ``video`` (same canvas) used instead of extracting poses.
    ``overrides``: config fields replacing the preset's (e.g. ``{"width": 256, "height": 256}``).
    ``precision``: ``auto`` (bf16 on CPUs with AMX/AVX-512-BF16 and on GPUs, fp16 on GPUs without bf16, else
    fp32), ``fp32``, ``bf16`` or ``fp16`` (CUDA): what the forward passes compute in; weights stay float32.
    """
    return video_trainer(video, run_dir, preset_name, options, resume, poses, vgg_weights, device, overrides,
                         precision).fit()


def video_trainer(video: str | os.PathLike, run_dir: str | os.PathLike, preset_name: str = "small",
                  options: TrainOptions | None = None, resume: bool = False, poses: str | os.PathLike | None = None,
                  vgg_weights: str | os.PathLike | None = None, device: str = "auto",
                  overrides: dict | None = None, precision: str = "auto") -> VideoTrainer:
    """The trainer :func:`train_video` fits (same arguments), with the run's data prepared and its checkpoint
    restored when ``resume``: benchmarks time its :meth:`VideoTrainer.train_step` alone."""
    video, run_dir = Path(video), Path(run_dir)
    options = options or TrainOptions()
    require_file(video, "Target video")
    if options.minutes is None and options.epochs is None:
        raise DancesynthError("Give a time budget with --minutes or a length with --epochs.")
    dev = resolve_device(device)
    dtype = resolve_precision(precision, dev)
    run = RunFolder(run_dir, KIND, dev, resume=resume, tables=("losses", "validation"))
    if run.meta is not None:
        with run_file_contents(run.path / POINTER):
            config = config_from_dict(Pix2PixHDConfig, run.meta["config"])
            framing = framing_from_dict(run.meta["framing"])
    else:
        config = preset(preset_name, **(overrides or {}))
        framing = None
    # Rank 0 extracts and caches poses, frames and the background plate; the other ranks then read the caches.
    if not run.writer:
        run.barrier()
    seq = check_poses_match(load_or_extract_poses(video, run_dir, Path(poses) if poses else None), video)
    if framing is None:
        framing = video_framing(seq, config.width, config.height)
        # The plate's crop helped where the scene moves through a following crop and cost a fixed one (docs/methods).
        if isinstance(framing, FollowFraming) and "background" not in (overrides or {}):
            config = dataclasses.replace(config, background=True, blend=(overrides or {}).get("blend", True))
    frames = cache_frames(video, framing, run_dir, seq)
    # made by rank 0; the other ranks read it after the barrier
    plate = cache_plate(video, seq, run_dir, segment=config.prior)
    if config.prior:
        bank_framing = scaled_framing(framing, config.prior_scale)
        bank_frames = cache_frames(video, bank_framing, run_dir, seq)
        masks = cache_masks(video, bank_framing, run_dir, seq)
    if run.writer:
        run.barrier()
    bank = None
    if config.prior:
        bank = frame_bank(bank_frames, masks, seq, bank_framing, split_ranges(len(seq), config.val_fraction)[0],
                          config.prior_candidates)
    target = TargetVideo(frames, seq, framing, plate if config.background else None, bank, config.prior_scale)
    # A zero-minute budget trains nothing: no perceptual loss to load, and no notice of its absence.
    vgg = None if options.minutes == 0 else build_vgg_loss(vgg_weights)
    trainer = VideoTrainer(config, target, run, dev, vgg, options, str(video), dtype)
    if resume:
        trainer.restore()
    return trainer
