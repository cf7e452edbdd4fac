"""The tiled fine pass (``nrdepth.reconstruct``): tiles partition the video,
windows cut from a field agree with brute force, tiles with the default
margins give back one untiled pass (and without margins they would not),
the two fine passes agree on a generated video, the working resolution and
progress, and bad arguments are named."""

from __future__ import annotations

import importlib

import numpy as np
import pytest
import torch

import nrdepth
import nrdepth.model
from nrdepth.reconstruct.fine import axis_spans
from nrdepth.reconstruct import MARGIN, field_frames, field_windows, inference_model, reconstruct_file, tile_plan, working_shape


@pytest.mark.parametrize("length, core, margin, align", [(480, 320, 64, 8), (640, 320, 64, 8), (16, 32, 8, 1), (191, 32, 8, 1), (200, 64, 0, 4), (8, 8, 8, 8)])
def test_tile_cores_partition_the_axis_on_the_alignment_grid(length, core, margin, align):
    spans = axis_spans(length, core, margin, align)
    kept = [(a, b) for _, _, a, b in spans]
    assert kept[0][0] == 0 and kept[-1][1] == length and all(b == c for (_, b), (c, _) in zip(kept, kept[1:]))
    for lo, hi, a, b in spans:
        assert a % align == 0 and b - a <= core + align and lo == max(0, a - margin) and hi == min(length, b + margin)


@pytest.mark.parametrize("shape", [(16, 64, 64), (5, 37, 70), (23, 96, 40), (1, 8, 8)])
@pytest.mark.parametrize("span", [1, 7, 40])
def test_windows_cut_from_streamed_spans_are_the_padded_videos_windows(shape, span):
    depth = np.random.default_rng(sum(shape)).standard_normal(shape).astype(np.float32)
    layout = nrdepth.patch_layout(shape)
    spans = ((t0, depth[t0 : t0 + span]) for t0 in range(0, shape[0], span))
    back = [layout.padded[a] - layout.shape[a] - layout.pad[a] for a in range(3)]
    padded = np.pad(depth, [(layout.pad[a], back[a]) for a in range(3)], mode="symmetric")
    seen = []
    for origins, windows in field_windows(layout, spans, chunk=5):
        assert windows.flags.c_contiguous and windows.dtype == np.float32
        for (t, y, x), window in zip(origins, windows):
            np.testing.assert_array_equal(window, padded[t : t + 16, y : y + 64, x : x + 64])
        seen.append(origins)
    np.testing.assert_array_equal(np.concatenate(seen), layout.origins)


def test_spans_that_skip_or_stop_short_are_named():
    layout = nrdepth.patch_layout((20, 64, 64))
    frames = np.zeros((20, 64, 64), np.float32)
    with pytest.raises(ValueError, match="^spans: ended"):
        list(field_windows(layout, iter([(0, frames[:10])])))
    with pytest.raises(ValueError, match="^spans: expected frames from 10"):
        list(field_windows(layout, iter([(0, frames[:10]), (12, frames[12:])])))


@pytest.fixture(scope="module")
def shipped():
    return inference_model(None, torch.device("cpu"))


def test_tiles_with_the_default_margins_give_back_one_untiled_pass(shipped):
    video = nrdepth.generate_clips(1, seed=11, config=nrdepth.GeneratorConfig(size=256)).video[0][:, :, :200]
    dev = torch.device("cpu")

    def field(tile, margin):
        parts = list(field_frames(video, shipped, dev, tile, margin, precision="float32"))  # the tiling's error alone
        assert [t0 for t0, _ in parts] == list(np.cumsum([0] + [len(d) for _, d in parts[:-1]]))
        return np.concatenate([d for _, d in parts])

    untiled = field(video.shape, (0, 0, 0))
    assert untiled.shape == video.shape and len(tile_plan(video.shape, shipped, (8, 96, 64), MARGIN)) == 2 * 3 * 4
    tiled = field((8, 96, 64), MARGIN)
    seamed = field((8, 96, 64), (0, 0, 0))
    scale = untiled.std()
    # One statistic for the whole video and margins past most of the network's reach: the tiles are one
    # pass, nearly (measured: mean 0.0038, max 0.17 standard deviations, with 24 tiles on a 256×200 video).
    assert np.abs(tiled - untiled).mean() < 0.01 * scale and np.abs(tiled - untiled).max() < 0.25 * scale
    # Without margins the same tiles leave seams (measured: mean 0.41): the comparison can fail.
    assert np.abs(seamed - untiled).mean() > 10 * np.abs(tiled - untiled).mean()


def test_both_fine_passes_read_a_generated_video_alike_and_beat_the_flat_plane(shipped):
    clip = nrdepth.generate_clips(1, seed=5, config=nrdepth.GeneratorConfig(size=128))
    video, truth = clip.video[0], clip.depth[0]
    calls = []
    field = nrdepth.reconstruct(video, shipped, device="cpu", progress=lambda done, total: calls.append((done, total)))
    patches = nrdepth.reconstruct(video, shipped, device="cpu", fine="patches")
    assert calls[-1] == (16, 16) and all(a <= b for (a, _), (b, _) in zip(calls, calls[1:]))
    scores = [nrdepth.mae_sn(d, truth) for d in (field, patches)]
    assert abs(scores[0] - scores[1]) < 0.05 and max(scores) < nrdepth.flat_baseline(truth)


def test_bfloat16_reads_a_generated_video_as_float32_does_and_auto_follows_the_hardware(shipped, monkeypatch):
    network = importlib.import_module("nrdepth.reconstruct.network")
    clip = nrdepth.generate_clips(1, seed=6, config=nrdepth.GeneratorConfig(size=128))
    video, truth = clip.video[0], clip.depth[0]
    read = {p: nrdepth.reconstruct(video, shipped, device="cpu", precision=p) for p in ("float32", "bfloat16")}
    gap = np.abs(read["bfloat16"] - read["float32"])
    # Another arithmetic (the depth has unit standard deviation), which reads the video alike (experiments/precision.py:
    # +0.0000 ± 0.0000 per frame on 3 × 64 generated videos).
    assert 0 < gap.mean() < 0.02
    assert abs(nrdepth.mae_sn(read["bfloat16"], truth) - nrdepth.mae_sn(read["float32"], truth)) < 0.005
    for native, expected in ((False, "float32"), (True, "bfloat16")):
        monkeypatch.setattr(network, "native_bfloat16", lambda device, native=native: native)
        np.testing.assert_array_equal(nrdepth.reconstruct(video, shipped, device="cpu"), read[expected])


def test_working_resolution_keeps_the_aspect_and_gives_the_frames_size_back():
    assert working_shape((1080, 1920), 640) == (360, 640) and working_shape((480, 640), 960) == (480, 640)
    assert working_shape((100, 50), None) == (100, 50)
    torch.manual_seed(0)
    model = nrdepth.model.UNet3D(base=2)
    video = (np.random.default_rng(0).random((6, 90, 160)) * 255).astype(np.uint8)
    depth = nrdepth.reconstruct(video, model, device="cpu", max_side=64)
    assert depth.shape == video.shape and np.isfinite(depth).all()
    assert depth.mean() == pytest.approx(0, abs=1e-5) and depth.std() == pytest.approx(1, rel=1e-4)


@pytest.mark.parametrize("options, message", [
    ({"fine": "tiles"}, "^fine:"),
    ({"max_side": 4}, "^max_side:"),
    ({"max_side": 64.5}, "^max_side:"),
    ({"tile": (8, 60, 64)}, "^tile:"),
    ({"tile": (8, 64)}, "^tile:"),
    ({"precision": "half"}, "^precision:"),
])
def test_bad_fine_pass_arguments_are_named(options, message):
    torch.manual_seed(0)
    video = np.zeros((4, 32, 32), np.uint8)
    with pytest.raises(ValueError, match=message):
        nrdepth.reconstruct(video, nrdepth.model.UNet3D(base=2), device="cpu", **options)


def test_a_file_streamed_to_a_folder_matches_the_in_memory_reconstruction(tmp_path):
    torch.manual_seed(0)
    model = nrdepth.model.UNet3D(base=2)
    video = (np.random.default_rng(1).random((37, 40, 56)) * 255).astype(np.uint8)
    np.save(tmp_path / "clip.npy", video)
    options = {"roi": (4, 2, 48, 36), "frames": slice(3, None), "max_side": 32}
    expected = nrdepth.reconstruct(video, model, device="cpu", **options)
    reconstruct_file(tmp_path / "clip.npy", tmp_path / "out", model, device="cpu", flip=True, png16=True, **options)
    with np.load(tmp_path / "out" / "depth.npz") as saved:
        np.testing.assert_allclose(saved["depth"], -expected, atol=1e-5)
        lo, hi = saved["png16_range"]
        assert lo <= saved["depth"].min() and saved["depth"].max() <= hi
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [".nrdepth-reconstruction", "depth.mp4", "depth.npz", "png16", "side_by_side.mp4", "viewer.html"]
    assert len(list((tmp_path / "out" / "png16").iterdir())) == 34


def test_a_mask_file_streamed_to_a_folder_matches_the_in_memory_masked_reconstruction_and_every_output_marks_it(tmp_path, capsys):
    import base64
    import struct

    import av

    from nrdepth.cli import main
    from nrdepth.engine.preview import save_png
    from nrdepth.model import save_model
    from nrdepth.io import read_video, select
    from nrdepth.io.viewer import HOLE, ViewerFrames, _block_mean

    torch.manual_seed(0)
    model = nrdepth.model.UNet3D(base=2)
    video = (np.random.default_rng(3).random((26, 40, 56)) * 255).astype(np.uint8)
    np.save(tmp_path / "clip.npy", video)
    still = np.zeros((40, 56), bool)
    still[6:34, 8:50] = True
    moving = np.stack([np.roll(still, k - 13, axis=1) for k in range(26)])
    save_png(tmp_path / "still.png", np.repeat(np.where(still, 255, 0).astype(np.uint8)[..., None], 3, axis=-1))
    np.save(tmp_path / "moving.npy", np.where(moving, 200, 30).astype(np.uint8))  # 128 or more is on the surface
    options = {"roi": (4, 2, 48, 36), "frames": slice(3, None), "max_side": 32}
    for given, file in ((still, "still.png"), (moving, "moving.npy")):
        expected = nrdepth.reconstruct(video, model, device="cpu", mask=given, **options)
        out = tmp_path / f"out_{file}"
        reconstruct_file(tmp_path / "clip.npy", out, model, device="cpu", png16=True, ply=True, mask=tmp_path / file, **options)
        with np.load(out / "depth.npz") as saved:
            depth, png16_range = saved["depth"], saved["png16_range"]
        off = ~select(given[None] if given.ndim == 2 else given, None if given.ndim == 2 else options["frames"], options["roi"])
        assert np.isnan(depth[np.broadcast_to(off, depth.shape)]).all() and np.isfinite(depth[~np.broadcast_to(off, depth.shape)]).all()
        np.testing.assert_allclose(depth, expected, atol=1e-5)  # NaN where the other is NaN
        assert png16_range[0] <= np.nanmin(depth) and np.nanmax(depth) <= png16_range[1]
        with av.open(str(out / "png16" / "depth_0005.png")) as c:
            v = next(c.decode(video=0)).to_ndarray(format="gray16le").astype(np.float64)
        nan = np.isnan(depth[5])
        assert (v[nan] == 0).all() and (v[~nan] >= 1).all()
        lo, hi = png16_range
        assert np.abs(lo + (v[~nan] - 1) / 65534 * (hi - lo) - depth[5][~nan]).max() <= (hi - lo) / 65534
        header, body = (out / "ply" / "frame_0005.ply").read_bytes().split(b"end_header\n")
        assert f"element vertex {int((~nan).sum())}".encode() in header and len(body) == int((~nan).sum()) * 15
        assert all(np.isfinite(struct.unpack_from("<fff", body, 15 * i)).all() for i in range(0, int((~nan).sum()), 97))
        colour = read_video(out / "depth.mp4").frames
        assert colour[np.broadcast_to(off, colour.shape) & (np.roll(np.broadcast_to(off, colour.shape), 3, axis=2))].mean() < 20  # black, away from the edge
    frames = ViewerFrames(depth.shape, side=12)
    frames.add(depth)
    z = np.frombuffer(base64.b64decode(frames.payload("depth")["z"]), "<i2").reshape(len(depth), *frames.mesh)
    blocks = np.isnan(_block_mean(depth, frames.step))
    assert blocks.any() and (z[blocks] == HOLE).all() and (z[~blocks] > HOLE).all()
    # The command line takes the same file; a mask of another size or frame count is refused, naming --mask.
    save_model(model, tmp_path / "m.safetensors")
    assert main(["reconstruct", str(tmp_path / "clip.npy"), "-o", str(tmp_path / "cli"), "--device", "cpu", "--quiet", "--no-viewer",
                 "--mask", str(tmp_path / "still.png"), "--max-side", "32", "--model", str(tmp_path / "m.safetensors")]) == 0
    with np.load(tmp_path / "cli" / "depth.npz") as saved:
        assert np.isnan(saved["depth"][:, ~still]).all() and np.isfinite(saved["depth"][:, still]).all()
    assert main(["reconstruct", str(tmp_path / "clip.npy"), "-o", str(tmp_path / "cli2"), "--device", "cpu", "--quiet",
                 "--mask", str(tmp_path / "nothing.png"), "--model", str(tmp_path / "m.safetensors")]) == 2
    assert "error: --mask: " in capsys.readouterr().err
    np.save(tmp_path / "short.npy", np.where(moving[:20], 255, 0).astype(np.uint8))
    save_png(tmp_path / "small.png", np.zeros((40, 50, 3), np.uint8))
    np.save(tmp_path / "none.npy", np.zeros((26, 40, 56), bool))
    for bad, says in (("short.npy", "the input's 26 frames"), ("small.png", "input's size"), ("none.npy", "no pixel on the surface")):
        with pytest.raises(ValueError, match=f"^mask: .*{says}"):
            reconstruct_file(tmp_path / "clip.npy", tmp_path / "bad", model, device="cpu", mask=tmp_path / bad)
        assert not (tmp_path / "bad").exists()
    with pytest.raises(ValueError, match="^mask: .*alignment='joint'"):
        reconstruct_file(tmp_path / "clip.npy", tmp_path / "bad", model, device="cpu", mask=tmp_path / "still.png", alignment="coarse")


def test_an_interrupted_streaming_run_leaves_no_folder(tmp_path):
    torch.manual_seed(0)
    np.save(tmp_path / "clip.npy", (np.random.default_rng(2).random((40, 32, 32)) * 255).astype(np.uint8))

    def interrupt(done, total):
        if done >= 16:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        reconstruct_file(tmp_path / "clip.npy", tmp_path / "out", nrdepth.model.UNet3D(base=2), device="cpu", progress=interrupt, tile=(8, 32, 32))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["clip.npy"]
