"""Training: exact resume, weights round trip, data-parallel ranks in sync."""

import csv
import os
import subprocess
import sys

import numpy as np
import pytest
import torch

import nrdepth
from nrdepth.learning import TrainConfig
from nrdepth.learning.train import train
from nrdepth.model import DEFAULT_MODEL, load_model, predict_depth

TINY = dict(
    base=2, batch_size=2, steps_per_epoch=3, epochs=2, lr=3e-3, validation_clips=2, workers=0, device="cpu",
    generator=nrdepth.GeneratorConfig(frames=4, size=16, grid=16, texture_size=32),
)


def rows(folder):
    with open(folder / "metrics.csv") as f:
        return list(csv.DictReader(f))


def test_resuming_from_a_checkpoint_takes_the_same_steps_as_not_stopping(tmp_path):
    config = TrainConfig(loss="aligned", **TINY)
    train(tmp_path / "straight", config, progress=False)
    train(tmp_path / "resumed", config, progress=False, max_epochs=1)
    assert len(rows(tmp_path / "resumed")) == 1
    train(tmp_path / "resumed", config, progress=False)
    a, b = rows(tmp_path / "straight"), rows(tmp_path / "resumed")
    assert len(a) == len(b) == 2
    for key in ("first_step_loss", "last_step_loss", "train_loss", "val_mae_sn_frame"):
        assert a[1][key] == b[1][key], key
    weights = [torch.load(tmp_path / d / "last.pt", weights_only=False)["model"] for d in ("straight", "resumed")]
    assert all(torch.equal(weights[0][k], weights[1][k]) for k in weights[0])


def test_the_moving_average_of_the_weights_is_scored_saved_and_resumed(tmp_path):
    from nrdepth.model import build_model

    one_step = TrainConfig(loss="aligned", ema=0.25, **{**TINY, "epochs": 1, "steps_per_epoch": 1})
    train(tmp_path / "one", one_step, progress=False)
    torch.manual_seed(one_step.seed)
    start = build_model(one_step.arch, **one_step.model_config()).state_dict()
    checkpoint = torch.load(tmp_path / "one" / "last.pt", weights_only=False)
    saved = load_model(tmp_path / "one" / "model.safetensors").state_dict()
    assert any(not torch.equal(w, start[k]) for k, w in checkpoint["model"].items()), "the step changed the weights"
    for k, w in checkpoint["model"].items():
        expected = torch.lerp(start[k], w, 0.75) if w.is_floating_point() else w
        assert torch.equal(checkpoint["ema"][k], expected) and torch.equal(saved[k], expected), k
    # A run stopped after its first epoch resumes to the same average.
    config = TrainConfig(loss="aligned", ema=0.9, **TINY)
    train(tmp_path / "straight", config, progress=False)
    train(tmp_path / "resumed", config, progress=False, max_epochs=1)
    train(tmp_path / "resumed", config, progress=False)
    a, b = (torch.load(tmp_path / d / "last.pt", weights_only=False)["ema"] for d in ("straight", "resumed"))
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert rows(tmp_path / "straight")[-1]["val_mae_sn_frame"] == rows(tmp_path / "resumed")[-1]["val_mae_sn_frame"]
    assert not TrainConfig(loss="aligned", **TINY).resumable_as(config.as_dict())


def test_weights_round_trip_through_safetensors(tmp_path):
    config = TrainConfig(loss="gbr", **{**TINY, "epochs": 1})
    summary = train(tmp_path, config, progress=False)
    assert summary["val_mae_sn_flat_frame"] > 0 and np.isfinite(summary["val_mae_sn_frame"])
    model = load_model(tmp_path / "model.safetensors")
    state = torch.load(tmp_path / "best.pt", weights_only=False)["model"]
    assert all(torch.equal(model.state_dict()[k], state[k]) for k in state)
    clips = nrdepth.generate_clips(1, seed=3, config=TINY["generator"])
    assert predict_depth(model, clips.video).shape == (1, 4, 8, 8)
    with pytest.raises(ValueError, match="missing.safetensors: not found"):
        load_model(tmp_path / "missing.safetensors")


def test_a_folder_with_another_config_is_refused(tmp_path):
    train(tmp_path, TrainConfig(loss="gbr", **{**TINY, "epochs": 1}), progress=False)
    with pytest.raises(ValueError, match="^out:"):
        train(tmp_path, TrainConfig(loss="tr_sc", **{**TINY, "epochs": 1}), progress=False)


@pytest.mark.parametrize(
    "changes, name",
    [({"loss": "l2"}, "loss"), ({"batch_size": 0}, "batch_size"), ({"lr": -1.0}, "lr"), ({"device": "tpu"}, "device"),
     ({"target": "truth"}, "target"), ({"init": "no/such/model.safetensors"}, "init"), ({"real": "no/such/video.npz"}, "real"),
     ({"keep_every": -1}, "keep_every"), ({"ema": 1.0}, "ema"), ({"anchor": -1.0}, "anchor"),
     ({"anchor": 1e3, "init": str(DEFAULT_MODEL)}, "anchor"), ({"rehearsal": 1.0}, "rehearsal"), ({"rehearsal": 0.1}, "rehearsal"),  # 0.2 of a clip
     ({"rehearsal": 0.5, "batch_size": 1}, "rehearsal"), ({"rehearsal": True}, "rehearsal")],  # lr · anchor = 3: past the start
)
def test_bad_train_config_is_named(changes, name):
    with pytest.raises(ValueError) as info:
        TrainConfig(**{**TINY, **changes})
    assert str(info.value).startswith(name)


def test_a_real_video_is_scored_every_epoch_by_the_weights_of_that_epoch(tmp_path):
    from nrdepth.learning.evaluate import load_real_video, score_real_video

    clip = nrdepth.generate_clips(1, seed=9)
    depth = clip.depth[0].copy()
    depth[:, :8, :8] = np.nan  # pixels without ground truth are left out
    np.savez(tmp_path / "real.npz", video=clip.video[0], depth=depth)
    config = TrainConfig(loss="aligned", real=str(tmp_path / "real.npz"), keep_every=2, **TINY)
    train(tmp_path / "run", config, progress=False)
    assert sorted(p.name for p in (tmp_path / "run" / "epochs").iterdir()) == ["epoch_2.json", "epoch_2.safetensors"]
    kept = load_model(tmp_path / "run" / "epochs" / "epoch_2.safetensors")
    assert all(torch.equal(kept.state_dict()[k], v) for k, v in torch.load(tmp_path / "run" / "last.pt", weights_only=False)["model"].items())
    expected = score_real_video(kept, *load_real_video(tmp_path / "real.npz"))
    last = rows(tmp_path / "run")[-1]
    for column, key in (("real_mae_sn_frame", "frame"), ("real_mae_sn_first", "first"), ("real_flat_frame", "flat_frame"), ("real_sign_correct", "sign_correct")):
        assert float(last[column]) == pytest.approx(expected[key], rel=1e-6), column
    assert float(last["real_flat_frame"]) == pytest.approx(nrdepth.flat_baseline(depth, "frame", mask=np.isfinite(depth)), rel=1e-6)
    # Watching changes nothing that is computed: a resume may add or drop it.
    assert TrainConfig(loss="aligned", **TINY).resumable_as(config.as_dict())
    # A run saved before the generator had its camera fields resumes under their defaults.
    older = config.as_dict()
    older["generator"] = {k: v for k, v in older["generator"].items() if k not in ("blur", "gamma")}
    assert config.resumable_as(older)
    assert not TrainConfig(loss="aligned", **{**TINY, "generator": TINY["generator"].replace(gamma=(0.5, 1.0))}).resumable_as(older)
    np.savez(tmp_path / "bad.npz", video=clip.video[0].astype(np.float32), depth=depth)
    with pytest.raises(ValueError, match="^real: .*'video' must be uint8"):
        TrainConfig(loss="aligned", real=str(tmp_path / "bad.npz"), **TINY)
    np.save(tmp_path / "single.npy", clip.video[0])
    (tmp_path / "text.npz").write_text("not an archive")
    for name, expected in (("single.npy", "single .npy array"), ("text.npz", "not a readable .npz"), ("missing.npz", "not a readable .npz")):
        with pytest.raises(ValueError, match=f"^real: .*{expected}"):
            TrainConfig(loss="aligned", real=str(tmp_path / name), **TINY)


def test_several_real_videos_dense_and_sparse_are_scored_in_their_own_columns(tmp_path):
    from nrdepth.learning.evaluate import load_real, score_real

    clip = nrdepth.generate_clips(2, seed=9)
    np.savez(tmp_path / "cloth.npz", video=clip.video[0], depth=clip.depth[0])
    rng = np.random.default_rng(0)
    frames = np.array([1, 5, 9])
    uv = rng.uniform(0, 63, (3, 2, 40))
    z = np.stack([clip.depth[1][f][np.rint(v).astype(int), np.rint(u).astype(int)] for f, (u, v) in zip(frames, uv)])
    np.savez(tmp_path / "sheet.npz", video=clip.video[1], frames=frames, uv=uv, z=z)
    config = TrainConfig(loss="aligned", real=[str(tmp_path / "cloth.npz"), str(tmp_path / "sheet.npz")], keep_every=1, **TINY)
    train(tmp_path / "run", config, progress=False)
    last = rows(tmp_path / "run")[-1]
    model = load_model(tmp_path / "run" / "epochs" / f"epoch_{last['epoch']}.safetensors")  # the weights the last row scored
    for stem, columns in (("cloth", {"mae_sn_frame": "frame", "mae_sn_first": "first", "flat_frame": "flat_frame", "sign_correct": "sign_correct"}),
                          ("sheet", {"mae": "mae", "flat_mae": "flat_mae", "sign_correct": "sign_correct"})):
        expected = score_real(model, load_real(tmp_path / f"{stem}.npz"))
        for column, key in columns.items():
            assert float(last[f"real_{stem}_{column}"]) == pytest.approx(expected[key], rel=1e-6), (stem, column)
    assert "real_mae_sn_frame" not in last
    np.savez(tmp_path / "outside.npz", video=clip.video[1], frames=frames, uv=uv + 100, z=z)
    with pytest.raises(ValueError, match="^real: .*inside the 64×64 frame"):
        TrainConfig(loss="aligned", real=str(tmp_path / "outside.npz"), **TINY)
    with pytest.raises(ValueError, match="^real: expected one or more .npz files with different names"):
        TrainConfig(loss="aligned", real=[str(tmp_path / "cloth.npz"), str(tmp_path / "cloth.npz")], **TINY)


def test_two_process_torchrun_on_the_cpu_keeps_ranks_in_sync(tmp_path):
    args = [
        "--nproc_per_node", "2", "--standalone", "-m", "nrdepth", "train", str(tmp_path), "--loss", "aligned",
        "--epochs", "1", "--steps", "2", "--batch-size", "2", "--base", "2", "--validation-clips", "2",
        "--workers", "0", "--device", "cpu", "--frames", "4", "--size", "16", "--grid", "16", "--quiet",
    ]
    env = dict(os.environ, OMP_NUM_THREADS="1")
    result = subprocess.run([sys.executable, "-m", "torch.distributed.run", *args], capture_output=True, text=True, env=env, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
    (row,) = rows(tmp_path)
    assert row["ranks_in_sync"] == "True"


def test_evaluate_writes_per_clip_scores_and_a_summary(tmp_path):
    from nrdepth.cli import main

    train(tmp_path / "run", TrainConfig(loss="aligned", **{**TINY, "epochs": 1}), progress=False)
    args = ["evaluate", str(tmp_path / "run"), "-o", str(tmp_path / "eval"), "--clips", "3", "--frames", "4", "--size", "16", "--grid", "16", "--device", "cpu"]
    assert main(args) == 0
    with open(tmp_path / "eval" / "per_clip.csv") as f:
        per_clip = list(csv.DictReader(f))
    assert len(per_clip) == 3
    summary = __import__("json").loads((tmp_path / "eval" / "summary.json").read_text())
    assert summary["mae_sn_frame"]["mean"] == pytest.approx(np.mean([float(r["mae_sn_frame"]) for r in per_clip]))


def test_training_from_a_stored_dataset(tmp_path):
    from nrdepth.engine.dataset import write_dataset

    write_dataset(tmp_path / "data", 20, seed=2, config=TINY["generator"], shard_size=8, progress=False)
    config = TrainConfig(loss="gbr", data=str(tmp_path / "data"), **{**TINY, "epochs": 1})
    summary = train(tmp_path / "run", config, progress=False)
    assert np.isfinite(summary["train_loss"]) and summary["val_mae_sn_flat_frame"] > 0
    # The stored run is as reproducible as the online one.
    assert train(tmp_path / "again", config, progress=False)["train_loss"] == summary["train_loss"]


def _files(folder):
    """What a run leaves that must not depend on interruptions: metrics rows
    (but the wall-clock column) and the bytes of its weights."""
    return (
        [{k: v for k, v in r.items() if k != "train_seconds"} for r in rows(folder)],
        (folder / "model.safetensors").read_bytes(),
        (folder / "model.json").read_text(),
        {k: v for k, v in torch.load(folder / "last.pt", weights_only=False)["model"].items()},
    )


def test_a_kill_at_every_write_point_resumes_to_the_uninterrupted_result(tmp_path, monkeypatch):
    config = TrainConfig(loss="aligned_both_signed", arch="unet2p1d", **{**TINY, "base": 4})
    train(tmp_path / "straight", config, progress=False)
    expected = _files(tmp_path / "straight")
    real_replace = os.replace
    writes = {"count": 0}

    def counting(src, dst):
        writes["count"] += 1
        real_replace(src, dst)

    monkeypatch.setattr(os, "replace", counting)
    train(tmp_path / "count", config, progress=False)
    total = writes["count"]
    assert total >= 2 * 4  # per epoch at least last.pt, metrics.csv and, when improved, best.pt and the model
    for kill_at in range(1, total + 1):
        folder = tmp_path / f"killed-{kill_at}"
        writes["count"] = 0

        def dying(src, dst, kill_at=kill_at):
            writes["count"] += 1
            if writes["count"] == kill_at:
                raise KeyboardInterrupt(f"killed before write {kill_at}")
            real_replace(src, dst)

        monkeypatch.setattr(os, "replace", dying)
        with pytest.raises(KeyboardInterrupt):
            train(folder, config, progress=False)
        monkeypatch.setattr(os, "replace", real_replace)
        train(folder, config, progress=False)
        got = _files(folder)
        assert got[0] == expected[0], f"kill before write {kill_at}: metrics"
        assert got[1] == expected[1] and got[2] == expected[2], f"kill before write {kill_at}: model"
        assert all(torch.equal(got[3][k], expected[3][k]) for k in expected[3]), f"kill before write {kill_at}: last.pt"


def test_a_resume_may_change_workers_device_and_with_a_constant_schedule_epochs_and_lr(tmp_path):
    base = {**TINY, "epochs": 1}
    train(tmp_path, TrainConfig(loss="aligned", schedule="constant", **base), progress=False)
    train(tmp_path, TrainConfig(loss="aligned", schedule="constant", **{**base, "workers": 1, "epochs": 2, "lr": 1e-3}), progress=False)
    (first, second) = rows(tmp_path)
    assert float(first["lr"]) == TINY["lr"] and float(second["lr"]) == 1e-3
    with pytest.raises(ValueError, match="^out:"):
        train(tmp_path, TrainConfig(loss="aligned", schedule="constant", **{**base, "epochs": 3, "batch_size": 3}), progress=False)
    cosine = tmp_path / "cosine"
    train(cosine, TrainConfig(loss="aligned", **base), progress=False)
    with pytest.raises(ValueError, match="^out:"):
        train(cosine, TrainConfig(loss="aligned", **{**base, "epochs": 2}), progress=False)


def test_the_observable_target_is_the_depth_of_the_surface_that_never_moves_along_the_optical_axis():
    from nrdepth.engine.surface import SurfaceParams

    config = nrdepth.GeneratorConfig(size=32, frames=4, grid=32, texture_size=64)
    clip = nrdepth.generate_clips(1, seed=5, config=config)
    params = clip.params[0]
    triangles = nrdepth.grid_triangles(config.grid)

    def cast(surface):
        positions = nrdepth.synthesize_surface(SurfaceParams.from_dict(surface), config.frames, config.grid)
        return np.stack([nrdepth.raycast_depth(p.reshape(-1, 3), triangles, config.size, params["window"]) for p in positions])

    drift = params["surface"]["drift"]
    still = cast({**params["surface"], "drift": [drift[0], drift[1], 0.0]})
    assert np.abs(nrdepth.observable_depth(clip.depth[0], params) - still).max() < 1e-5
    assert np.abs(clip.depth[0] - still).max() > 1e-2  # the clip did move along z


def test_a_warm_start_begins_from_the_given_weights_and_refuses_another_network(tmp_path):
    config = TrainConfig(loss="aligned_both_signed", arch="unet2p1d", **{**TINY, "epochs": 1})
    train(tmp_path / "first", config, progress=False)
    warm = TrainConfig(loss="aligned_both_signed", arch="unet2p1d", target="observable", init=str(tmp_path / "first"), **{**TINY, "epochs": 1, "lr": 1e-12})
    train(tmp_path / "warm", warm, progress=False)
    # At a vanishing learning rate the warm run's weights are the first run's.
    before, after = load_model(tmp_path / "first").state_dict(), load_model(tmp_path / "warm").state_dict()
    assert all(torch.allclose(before[k].float(), after[k].float(), atol=1e-6) for k in before)
    with pytest.raises(ValueError, match="^init:.*another network"):
        train(tmp_path / "other", TrainConfig(loss="aligned", init=str(tmp_path / "first"), **{**TINY, "epochs": 1}), progress=False)
    assert not (tmp_path / "other").exists()
    # A network with an added module starts from one without it, computing the same depth.
    grown = TrainConfig(loss="aligned_signed_first", arch="unet2p1d_global", init=str(tmp_path / "first"), **{**TINY, "epochs": 1, "lr": 1e-12})
    train(tmp_path / "grown", grown, progress=False)
    video = torch.rand(1, 1, 4, 16, 16)
    with torch.no_grad():
        assert torch.allclose(load_model(tmp_path / "grown")(video), load_model(tmp_path / "first")(video), atol=1e-5)
    with pytest.raises(ValueError, match="^init:.*another network"):  # but not the other way round
        train(tmp_path / "shrunk", TrainConfig(loss="aligned", arch="unet2p1d", init=str(tmp_path / "grown"), **{**TINY, "epochs": 1}), progress=False)


def test_the_anchor_pulls_every_step_back_toward_the_warm_start(tmp_path):
    train(tmp_path / "start", TrainConfig(loss="aligned_both_signed", arch="unet2p1d", **{**TINY, "epochs": 1}), progress=False)
    one_step = {**TINY, "epochs": 1, "steps_per_epoch": 1, "lr": 1e-2}
    runs = {}
    for name, anchor in (("free", 0.0), ("pulled", 25.0)):  # lr · anchor = 0.25
        config = TrainConfig(loss="aligned_both_signed", arch="unet2p1d", init=str(tmp_path / "start"), anchor=anchor, **one_step)
        train(tmp_path / name, config, progress=False)
        runs[name] = torch.load(tmp_path / name / "last.pt", weights_only=False)["model"]
    start = load_model(tmp_path / "start").state_dict()
    moved = [k for k, w in start.items() if w.is_floating_point() and not torch.equal(runs["free"][k], w)]
    assert moved, "the step changed the weights"
    # The first step's gradient is the same in both runs; the pull then takes a quarter of the way back.
    for k in moved:
        expected = start[k] + 0.75 * (runs["free"][k] - start[k])
        assert torch.allclose(runs["pulled"][k], expected, atol=1e-7, rtol=1e-5), k
    with pytest.raises(ValueError, match="^anchor:.*needs init"):
        TrainConfig(anchor=1.0, **TINY)
    # A run stopped after its first epoch pulls toward the same start when it resumes: the same bytes.
    config = TrainConfig(loss="aligned_both_signed", arch="unet2p1d", init=str(tmp_path / "start"), anchor=25.0, **{**TINY, "lr": 1e-2})
    train(tmp_path / "straight", config, progress=False)
    train(tmp_path / "resumed", config, progress=False, max_epochs=1)
    train(tmp_path / "resumed", config, progress=False)
    a, b = (torch.load(tmp_path / d / "last.pt", weights_only=False)["model"] for d in ("straight", "resumed"))
    assert all(torch.equal(a[k], b[k]) for k in a)


def test_an_amplitude_run_trains_on_window_widths_and_its_warm_start_is_calibrated(tmp_path):
    from nrdepth.learning.evaluate import relief_ratio
    from nrdepth.engine.generate import window_widths
    from nrdepth.learning.train import CALIBRATION_CLIPS, VALIDATION_SEED_OFFSET, targets

    generator = TINY["generator"]
    clips = nrdepth.generate_clips(3, seed=1, config=generator)
    widths = window_widths(clips.params)
    # The window is square, and its side lies in the range it was drawn from.
    assert np.allclose(widths, [p["window"][3] - p["window"][1] for p in clips.params])
    assert all(generator.window_width[0] <= w <= generator.window_width[1] for w in widths)
    scaled = targets("observable", clips.depth, clips.params, window_units=True)
    assert np.allclose(scaled * widths[:, None, None, None], targets("observable", clips.depth, clips.params), rtol=1e-6)

    config = TrainConfig(loss="aligned_both_signed", arch="unet2p1d", **{**TINY, "epochs": 1})
    train(tmp_path / "first", config, progress=False)
    assert load_model(tmp_path / "first").depth_units is None
    warm = TrainConfig(loss="aligned_both_signed", arch="unet2p1d", amplitude=0.5, init=str(tmp_path / "first"), **{**TINY, "epochs": 1, "lr": 1e-12})
    train(tmp_path / "warm", warm, progress=False)
    model = load_model(tmp_path / "warm")
    assert model.depth_units == "window"
    # The warm start's scale was set so that its relief matches the truth's on average.
    check = nrdepth.generate_clips(CALIBRATION_CLIPS, seed=warm.seed + VALIDATION_SEED_OFFSET, config=generator)
    truth = torch.nn.functional.avg_pool2d(torch.from_numpy(check.depth).float(), 2).numpy() / window_widths(check.params)[:, None, None, None]
    before = relief_ratio(predict_depth(load_model(tmp_path / "first"), check.video), truth)
    assert abs(before - 1) > 0.1 and abs(relief_ratio(predict_depth(model, check.video), truth) - 1) < 1e-3
    assert float(rows(tmp_path / "warm")[0]["val_relief_ratio"]) > 0
    summary = nrdepth.learning.evaluate.evaluate(tmp_path / "warm", clips=2, config=generator, device="cpu")
    assert summary["relief_ratio"]["geometric_mean"] > 0 and "relief_ratio" not in nrdepth.learning.evaluate.evaluate(tmp_path / "first", clips=2, config=generator, device="cpu")
    with pytest.raises(ValueError, match="^amplitude:"):
        TrainConfig(amplitude=-1.0)


def test_rehearsed_clips_join_each_batch_from_the_default_generators_own_run(tmp_path):
    from nrdepth.learning.train import REHEARSAL_SEED_OFFSET, OnlineBatches, targets, to_tensors

    recipe = nrdepth.GeneratorConfig(frames=4, size=16, grid=16, texture_size=32, texture_families=("print",), camera_fov=(0.7, 1.4))
    default = nrdepth.GeneratorConfig(frames=4, size=16, grid=16)
    config = TrainConfig(loss="aligned", rehearsal=0.25, **{**TINY, "batch_size": 4, "generator": recipe})
    assert config.rehearsed_clips == 1
    batches = OnlineBatches(recipe, 7, 4, "observable", rehearsed=config.rehearsed_clips)
    for k in (0, 5):  # batch k: the recipe's clips 3k .. 3k+2, then the default generator's clip k of its own run
        fresh = nrdepth.generate_clips(3, seed=7, config=recipe, start=3 * k)
        old = nrdepth.generate_clips(1, seed=7 + REHEARSAL_SEED_OFFSET, config=default, start=k)
        video, depth = batches[k]
        expected = [to_tensors(c.video, targets("observable", c.depth, c.params)) for c in (fresh, old)]
        assert torch.equal(video, torch.cat([e[0] for e in expected])) and torch.equal(depth, torch.cat([e[1] for e in expected]))
    # Without rehearsal a batch is the recipe's clips alone, as before the option.
    video, _ = OnlineBatches(recipe, 7, 4, "observable")[2]
    assert torch.equal(video, to_tensors(nrdepth.generate_clips(4, seed=7, config=recipe, start=8).video, np.zeros((4, 4, 16, 16)))[0])
    # A rehearsing run resumes to the same bytes, and a run saved before the option resumes as one without it.
    train(tmp_path / "straight", config, progress=False)
    train(tmp_path / "resumed", config, progress=False, max_epochs=1)
    train(tmp_path / "resumed", config, progress=False)
    a, b = (torch.load(tmp_path / d / "last.pt", weights_only=False)["model"] for d in ("straight", "resumed"))
    assert all(torch.equal(a[k], b[k]) for k in a)
    saved = TrainConfig(loss="aligned", **TINY).as_dict()
    del saved["rehearsal"]
    assert TrainConfig(loss="aligned", **TINY).resumable_as(saved) and not config.resumable_as(saved)
