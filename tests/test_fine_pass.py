"""The tiled fine pass (``nrdepth.reconstruct``): tiles partition the video,
windows cut from a field agree with brute force, tiles with the default
margins give back one untiled pass (and without margins they would not),
the two fine passes agree on a generated video, the working resolution and
progress, and bad arguments are named."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import nrdepth
import nrdepth.model
from nrdepth.reconstruct import MARGIN, _spans, field_frames, field_windows, inference_model, reconstruct_file, tile_plan, working_shape


@pytest.mark.parametrize("length, core, margin, align", [(480, 320, 64, 8), (640, 320, 64, 8), (16, 32, 8, 1), (191, 32, 8, 1), (200, 64, 0, 4), (8, 8, 8, 8)])
def test_tile_cores_partition_the_axis_on_the_alignment_grid(length, core, margin, align):
    spans = _spans(length, core, margin, align)
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
        parts = list(field_frames(video, shipped, dev, tile, margin))
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


def test_an_interrupted_streaming_run_leaves_no_folder(tmp_path):
    torch.manual_seed(0)
    np.save(tmp_path / "clip.npy", (np.random.default_rng(2).random((40, 32, 32)) * 255).astype(np.uint8))

    def interrupt(done, total):
        if done >= 16:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        reconstruct_file(tmp_path / "clip.npy", tmp_path / "out", nrdepth.model.UNet3D(base=2), device="cpu", progress=interrupt, tile=(8, 32, 32))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["clip.npy"]
