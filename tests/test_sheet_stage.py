"""The sheet stage (``reconstruct(focal=...)``): it reads a bending sheet
alike streamed from a file or held in memory, says what it did (a log
line, ``depth.npz``'s ``sheet``), and leaves the network's depth alone,
with its reason, where the video gives the shape nothing to read: too few
frames, no texture, no motion, nothing its points can be held to."""

import json
import warnings

import numpy as np
import pytest
import torch

import nrdepth
import nrdepth.model
from nrdepth.model import save_model
from nrdepth import GeneratorConfig, generate_clips
from nrdepth.reconstruct import SheetFallback, reconstruct_file
from nrdepth.reconstruct.sheet import MIN_FRAMES, MIN_MOTION

OPTIONS = {"max_side": 32, "focal": 60.0, "isometric_points": 36}


@pytest.fixture(scope="module")
def model():
    torch.manual_seed(0)
    return nrdepth.model.UNet3D(base=2)


@pytest.fixture(scope="module")
def bending():
    """A generated sheet bending two ways over 37 frames (3 chunks), 64×64."""
    config = GeneratorConfig(frames=37, size=64, grid=64, sheet_probability=1.0, sheet_phases=2, camera_fov=(1.0, 1.0), crop_share=(1.0, 1.0))
    return generate_clips(1, seed=5, config=config).video[0]


def network_alone(video, model, **options):
    return nrdepth.reconstruct(video, model, device="cpu", max_side=OPTIONS["max_side"], **options)


def test_a_bending_sheet_streamed_from_a_file_reads_as_in_memory_and_says_so(tmp_path, model, bending, capsys):
    options = {**OPTIONS, "roi": (4, 2, 56, 52), "frames": slice(3, None)}
    with warnings.catch_warnings():
        warnings.simplefilter("error", SheetFallback)  # it must not fall back
        expected = nrdepth.reconstruct(bending, model, device="cpu", **options)
    np.save(tmp_path / "clip.npy", bending)
    reconstruct_file(tmp_path / "clip.npy", tmp_path / "out", model, device="cpu", **options)
    with np.load(tmp_path / "out" / "depth.npz") as saved:
        np.testing.assert_allclose(saved["depth"], expected, atol=1e-5)
        sheet = json.loads(str(saved["sheet"]))
    assert sheet["used"] and sheet["frames"] == 34 and sheet["focal"] == [60.0, 60.0] and sheet["motion"] >= MIN_MOTION
    assert 20 <= sheet["points"] <= 40  # about 36 on the grid, a fifth left out
    without = network_alone(bending, model, roi=options["roi"], frames=options["frames"])
    assert np.abs(expected - without).max() > 0.1  # the sheet's shape did change the depth
    from nrdepth.cli import main

    save_model(model, tmp_path / "model.safetensors")
    np.save(tmp_path / "grey.npy", np.full((24, 48, 56), 128, np.uint8))
    for clip, says in (("clip", "the sheet's shape from inextensibility (the video moves the textured sheet"), ("grey", "the network's depth alone (the sheet's region has no texture")):
        assert main(["reconstruct", str(tmp_path / f"{clip}.npy"), "-o", str(tmp_path / f"cli_{clip}"), "--model", str(tmp_path / "model.safetensors"),
                     "--device", "cpu", "--max-side", "32", "--focal", "60", "--isometric-points", "36"]) == 0
        out, err = capsys.readouterr()
        assert f"sheet: {says}" in out and "SheetFallback" not in err  # one line, not a warning as well


def test_a_sheet_given_without_a_focal_length_is_read_through_the_guessed_pinhole_and_says_so(tmp_path, model, bending):
    box = (2, 2, 60, 60)
    options = {key: value for key, value in OPTIONS.items() if key != "focal"}
    with warnings.catch_warnings():
        warnings.simplefilter("error", SheetFallback)
        guessed = nrdepth.reconstruct(bending, model, device="cpu", **options, sheet=box)
    through = nrdepth.Camera.guessed(bending.shape[1:])
    np.testing.assert_array_equal(guessed, nrdepth.reconstruct(bending, model, device="cpu", **options, sheet=box, focal=through.focal))
    assert np.abs(guessed - network_alone(bending, model)).max() > 0.1  # the sheet's shape did change the depth
    np.save(tmp_path / "clip.npy", bending)
    reconstruct_file(tmp_path / "clip.npy", tmp_path / "out", model, device="cpu", **options, sheet=box)
    with np.load(tmp_path / "out" / "depth.npz") as saved:
        sheet = json.loads(str(saved["sheet"]))
    assert sheet["used"] and sheet["guessed"] and sheet["focal"] == list(through.focal)


@pytest.mark.parametrize("case", ["short", "grey", "still", "noise"])
def test_a_video_with_nothing_to_read_falls_back_to_the_network_and_says_why(case, model, bending):
    video, says = {
        "short": (bending[: MIN_FRAMES - 1], f"fewer than the {MIN_FRAMES}"),
        "grey": (np.full((24, 48, 56), 128, np.uint8), "no texture"),
        "still": (np.repeat(bending[:1], 24, axis=0), "does not move"),
        # steps of texture, motion from the flow, but nothing that stays: no point is found again
        "noise": (np.random.default_rng(0).integers(0, 256, (24, 48, 56), dtype=np.uint8), "found again in only"),
    }[case]
    with pytest.warns(SheetFallback, match=f"sheet: the network's depth alone \\(.*{says}"):
        depth = nrdepth.reconstruct(video, model, device="cpu", **OPTIONS, isometric_hold=case == "noise")  # held points see it
    np.testing.assert_array_equal(depth, network_alone(video, model))


def test_held_points_read_the_sheet_and_a_frame_without_them_sends_the_stage_aside(model, bending):
    with warnings.catch_warnings():
        warnings.simplefilter("error", SheetFallback)  # held, the bending sheet is read
        held = nrdepth.reconstruct(bending, model, device="cpu", **OPTIONS, isometric_hold=True)
    assert np.abs(held - network_alone(bending, model)).max() > 0.1
    blank = bending.copy()
    blank[20] = 128  # one grey frame: no point is found again there, too few for its program
    with pytest.warns(SheetFallback, match=r"too few points held in frames \[20\]"):
        depth = nrdepth.reconstruct(blank, model, device="cpu", **OPTIONS, isometric_hold=True)
    np.testing.assert_array_equal(depth, network_alone(blank, model))


def test_held_the_stage_reads_only_the_points_found_again_in_most_of_their_frames(tmp_path, model, bending):
    from nrdepth.isometric import DROP, point_held_shares, track_grid
    from nrdepth.reconstruct.frames import as_uint8
    from nrdepth.reconstruct.sheet import FLOW_MARGIN, KEEP_HELD

    banded = bending.copy()
    banded[:, 14:41, 14:50] = 0.8  # a flat card still in front of the sheet: the points behind it are found in few of their frames
    np.save(tmp_path / "banded.npy", banded)
    with warnings.catch_warnings():
        warnings.simplefilter("error", SheetFallback)
        reconstruct_file(tmp_path / "banded.npy", tmp_path / "out", model, device="cpu", **OPTIONS, isometric_hold=True, isometric_template="joint")
    with np.load(tmp_path / "out" / "depth.npz") as saved:
        sheet = json.loads(str(saved["sheet"]))
    xy = track_grid(as_uint8(banded), points=OPTIONS["isometric_points"], drop=DROP, margin=FLOW_MARGIN, hold=True)
    kept = point_held_shares(xy, banded.shape[1:]) >= KEEP_HELD
    assert sheet["used"] and 0 < kept.sum() < len(kept) and sheet["points"] == kept.sum()


def test_the_stage_solves_each_frame_as_asked(monkeypatch, model, bending):
    import importlib

    stage = importlib.import_module("nrdepth.reconstruct.sheet")  # nrdepth.reconstruct is also the function

    asked, solve = [], stage.mdh_depths
    def asking(*args, **kwargs):
        asked.append((kwargs["each_frame"], kwargs.get("keyframes"), kwargs.get("every"), kwargs.get("neighbours")))
        return solve(*args, **kwargs)

    monkeypatch.setattr(stage, "mdh_depths", asking)
    depths = {each: nrdepth.reconstruct(bending, model, device="cpu", **OPTIONS, isometric_each_frame=each, isometric_template="joint")
              for each in ("program", "lengths")}
    cheaper = (stage.KEYFRAMES, stage.EVERY, stage.NEIGHBOURS)  # the joint template's program, as the cost rules chose it
    assert asked == [("program", *cheaper), ("lengths", *cheaper)]
    assert np.abs(depths["lengths"] - depths["program"]).max() > 1e-3  # the frames' lengths kept change the shape


def test_a_cone_program_without_an_answer_sends_the_stage_aside_with_its_status(monkeypatch, model, bending):
    import importlib

    from nrdepth.isometric import NotSolved

    stage = importlib.import_module("nrdepth.reconstruct.sheet")

    def unsolved(*args, **kwargs):
        raise NotSolved("InsufficientProgress")  # what Clarabel said to a focal length of 10⁹ px, before such a focal was refused

    monkeypatch.setattr(stage, "mdh_depths", unsolved)
    # every reading tried gives way, each saying why
    with pytest.warns(SheetFallback, match=r"sheet: the network's depth alone \(held points through refined: the sheet's cone program found no answer "
                      r"\(InsufficientProgress\).*; the flow's points through joint: the sheet's cone program found no answer \(InsufficientProgress\)"):
        depth = nrdepth.reconstruct(bending, model, device="cpu", **OPTIONS)
    np.testing.assert_array_equal(depth, network_alone(bending, model))
    with pytest.raises(ValueError, match=r"focal: f_x = 1e\+09 px sees .*° across the frame's 64 pixels; the sheet's shape needs perspective"):
        nrdepth.reconstruct(bending, model, device="cpu", **{**OPTIONS, "focal": 1e9})


def test_auto_reads_held_points_through_refined_where_their_lengths_hold_and_the_joint_template_where_not(monkeypatch, model, bending):
    import importlib

    from nrdepth.reconstruct.options import REFINED_SCALE

    stage = importlib.import_module("nrdepth.reconstruct.sheet")
    decisions, decide = [], stage.sheet_depth
    monkeypatch.setattr(importlib.import_module("nrdepth.reconstruct.api"), "sheet_depth", lambda *a, **k: decisions.append(decide(*a, **k)) or decisions[-1])
    with warnings.catch_warnings():
        warnings.simplefilter("error", SheetFallback)
        auto = nrdepth.reconstruct(bending, model, device="cpu", **OPTIONS)
        joint = nrdepth.reconstruct(bending, model, device="cpu", **OPTIONS, isometric_template="joint")
    refined, _ = decisions
    assert refined.used and refined.template == "refined" and refined.strain <= stage.MAX_STRAIN and refined.scale == REFINED_SCALE
    assert np.abs(auto - joint).max() > 1e-3  # another reading of the sheet
    # A sheet whose pairs keep no length: the joint template, as if asked for, and the log says why
    monkeypatch.setattr(stage, "MAX_STRAIN", 0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", SheetFallback)
        stretched = nrdepth.reconstruct(bending, model, device="cpu", **OPTIONS)
    fallback = decisions[-1]
    assert fallback.used and fallback.template == "joint" and fallback.strain == refined.strain and fallback.held is None
    assert "not held points through refined: their pairs do not keep their lengths" in fallback.line()
    np.testing.assert_array_equal(stretched, joint)
    # Held points for the joint reading too: the tracks the first reading followed, not followed again
    followed, follow = [], stage.track_grid
    monkeypatch.setattr(stage, "track_grid", lambda *a, **k: followed.append(k["hold"]) or follow(*a, **k))
    with warnings.catch_warnings():
        warnings.simplefilter("error", SheetFallback)
        held = nrdepth.reconstruct(bending, model, device="cpu", **OPTIONS, isometric_hold=True)
    assert followed == [True] and decisions[-1].template == "joint" and decisions[-1].held is not None
    np.testing.assert_array_equal(held, nrdepth.reconstruct(bending, model, device="cpu", **OPTIONS, isometric_hold=True, isometric_template="joint"))
