"""The sheet stage (by default, or ``reconstruct(focal=...)``): it reads a bending sheet
alike streamed from a file or held in memory, says what it did (a log
line, ``depth.npz``'s ``sheet``), and leaves the network's depth alone,
with its reason, where the video gives the shape nothing to read: too few
frames, no texture, no motion, nothing its points can be held to, or,
by default, no sheet."""

import json
import warnings
from contextlib import contextmanager

import numpy as np
import pytest
import torch

import nrdepth
import nrdepth.model
from nrdepth.model import save_model
from nrdepth import GeneratorConfig, generate_clips
from nrdepth.reconstruct import SheetFallback, reconstruct_file
from nrdepth.reconstruct import SheetSettings

DEFAULT = SheetSettings()
MAX_STRAIN, MIN_CONTRAST, MIN_FRAMES, MIN_FRAMES_BY_DEFAULT = DEFAULT.max_strain, DEFAULT.min_contrast, DEFAULT.min_frames, DEFAULT.min_frames_by_default
MIN_HELD, MIN_MOTION, MIN_READ = DEFAULT.min_held, DEFAULT.min_motion, DEFAULT.min_read
LOOSE = SheetSettings(min_contrast=1.0)  # 36 points over 64×64 pixels: their strain picks no focal length sharply
STEPS = {"mdh_depths": "read", "estimate_focal": "read", "template_strain": "read", "unstrained_points": "find", "moving_points": "find",
         "track_grid": "find", "densify": "fuse", "fuse": "fuse"}
"""Each step's function of the sheet stage, by the module of the stage that calls it."""


def step_module(name):
    import importlib

    return importlib.import_module(f"nrdepth.reconstruct.sheet.{STEPS[name]}")

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
    return nrdepth.reconstruct(video, model, device="cpu", max_side=OPTIONS["max_side"], sheet_stage=False, **options)


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
    
    banded = bending.copy()
    banded[:, 14:41, 14:50] = 0.8  # a flat card still in front of the sheet: the points behind it are found in few of their frames
    np.save(tmp_path / "banded.npy", banded)
    with warnings.catch_warnings():
        warnings.simplefilter("error", SheetFallback)
        reconstruct_file(tmp_path / "banded.npy", tmp_path / "out", model, device="cpu", **OPTIONS, isometric_hold=True, isometric_template="joint")
    with np.load(tmp_path / "out" / "depth.npz") as saved:
        sheet = json.loads(str(saved["sheet"]))
    xy = track_grid(as_uint8(banded), points=OPTIONS["isometric_points"], drop=DROP, margin=DEFAULT.flow_margin, hold=True)
    kept = point_held_shares(xy, banded.shape[1:]) >= DEFAULT.keep_held
    assert sheet["used"] and 0 < kept.sum() < len(kept) and sheet["points"] == kept.sum()


def test_the_stage_solves_each_frame_as_asked(monkeypatch, model, bending):

    stage = step_module("mdh_depths")

    asked, solve = [], stage.mdh_depths
    def asking(*args, **kwargs):
        asked.append((kwargs["each_frame"], kwargs.get("keyframes"), kwargs.get("every"), kwargs.get("neighbours")))
        return solve(*args, **kwargs)

    monkeypatch.setattr(stage, "mdh_depths", asking)
    depths = {each: nrdepth.reconstruct(bending, model, device="cpu", **OPTIONS, isometric_each_frame=each, isometric_template="joint")
              for each in ("program", "lengths")}
    cheaper = (DEFAULT.keyframes, DEFAULT.every, DEFAULT.neighbours)  # the joint template's program, as the cost rules chose it
    assert asked == [("program", *cheaper), ("lengths", *cheaper)]
    assert np.abs(depths["lengths"] - depths["program"]).max() > 1e-3  # the frames' lengths kept change the shape


def test_a_cone_program_without_an_answer_sends_the_stage_aside_with_its_status(monkeypatch, model, bending):

    from nrdepth.isometric import NotSolved

    stage = step_module("mdh_depths")

    def unsolved(*args, **kwargs):
        raise NotSolved("InsufficientProgress")  # what Clarabel said to a focal length of 10⁹ px, before such a focal was refused

    monkeypatch.setattr(stage, "mdh_depths", unsolved)
    # every reading tried gives way, each saying why
    no_answer = r"the sheet's cone program found no answer \(InsufficientProgress\)"
    with pytest.warns(SheetFallback, match=rf"sheet: the network's depth alone \(the sheet's held points through refined: {no_answer}.*; held points through refined: "
                      rf"{no_answer}.*; the flow's points through joint: {no_answer}"):
        depth = nrdepth.reconstruct(bending, model, device="cpu", **OPTIONS)
    np.testing.assert_array_equal(depth, network_alone(bending, model))
    with pytest.raises(ValueError, match=r"focal: f_x = 1e\+09 px sees .*° across the frame's 64 pixels; the sheet's shape needs perspective"):
        nrdepth.reconstruct(bending, model, device="cpu", **{**OPTIONS, "focal": 1e9})


def decide(video, model, **options):
    """The depth and the sheet stage's decision (``with_decision``); a stage that steps aside warns (an error here) only where it was asked for."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", SheetFallback)
        return nrdepth.reconstruct(video, model, device="cpu", with_decision=True, **options)


def test_auto_reads_held_points_through_refined_where_their_lengths_hold_and_the_joint_template_where_not(monkeypatch, model, bending):
    auto, refined = decide(bending, model, **OPTIONS)
    joint = decide(bending, model, **OPTIONS, isometric_template="joint").depth
    assert refined.used and refined.template == "refined" and refined.strain <= MAX_STRAIN and refined.scale == DEFAULT.refined_scale
    assert np.abs(auto - joint).max() > 1e-3  # another reading of the sheet
    # A sheet whose pairs keep no length: the joint template, as if asked for, and the log says why
    stretched, fallback = decide(bending, model, **OPTIONS, sheet_settings=SheetSettings(max_strain=0.0))
    assert fallback.used and fallback.template == "joint" and fallback.held is None and fallback.scale == DEFAULT.joint_scale
    assert fallback.strain is None  # the joint reading's own values: none of the refined reading's that gave way
    assert f"not held points through refined: their pairs do not keep their lengths (strain {refined.strain:.4f}" in fallback.line()
    np.testing.assert_array_equal(stretched, joint)
    # Held points for the joint reading too: the tracks the first reading followed, not followed again
    stage = step_module("track_grid")
    followed, follow = [], stage.track_grid
    monkeypatch.setattr(stage, "track_grid", lambda *a, **k: followed.append(k["hold"]) or follow(*a, **k))
    stiff = SheetSettings(max_strain=0.0)
    held, decision = decide(bending, model, **OPTIONS, isometric_hold=True, sheet_settings=stiff)
    assert followed == [True] and decision.template == "joint" and decision.held is not None
    np.testing.assert_array_equal(held, nrdepth.reconstruct(bending, model, device="cpu", **OPTIONS, isometric_hold=True, isometric_template="joint"))


def test_by_default_the_stage_reads_a_sheet_and_leaves_what_is_no_sheet_alone(tmp_path, model, bending, capsys):
    options = {key: value for key, value in OPTIONS.items() if key != "focal"}  # nothing given
    noise = np.random.default_rng(0).integers(0, 256, (MIN_FRAMES_BY_DEFAULT, 48, 56), dtype=np.uint8)  # nothing that stays
    short = bending[: MIN_FRAMES_BY_DEFAULT - 1]  # a sheet, but too short a clip to be found by default
    still = np.repeat(bending[:1], MIN_FRAMES_BY_DEFAULT, axis=0)  # every point held, none moves
    # not asked for: where it steps aside, it says so in its line, not a warning (decide)
    (vague, unsure), (lost, faint), (brief, few), (stands, unmoved) = (decide(video, model, **options) for video in (bending, noise, short, still))
    sheet, read = decide(bending, model, **options, sheet_settings=LOOSE)
    # a sheet whose pairs keep no length: no sheet, and no other reading
    stretching, stretched = decide(bending, model, **options, sheet_settings=LOOSE.replace(max_strain=0.0))
    assert not unsure.used and 1.0 <= unsure.contrast < MIN_CONTRAST and unsure.reason.startswith("no focal length keeps their pairs' lengths")
    np.testing.assert_array_equal(vague, network_alone(bending, model))
    assert read.used and read.guessed and read.template == "refined" and read.strain <= MAX_STRAIN and read.contrast == unsure.contrast
    assert read.focal_estimate == unsure.focal_estimate > 0 and f"focal estimate px {read.focal_estimate:.1f}" in read.line()  # said in the line
    assert np.abs(sheet - network_alone(bending, model)).max() > 0.1  # the sheet's shape did change the depth
    assert not faint.used and "of the 36 asked for: too faint a texture" in faint.reason
    assert not stretched.used and stretched.strain == read.strain and stretched.reason.startswith("their pairs do not keep their lengths")
    assert not few.used and f"fewer than the {MIN_FRAMES_BY_DEFAULT} a sheet found by default needs" in few.reason
    np.testing.assert_array_equal(lost, network_alone(noise, model))
    assert not unmoved.used and unmoved.reason.startswith("the video does not move")
    np.testing.assert_array_equal(brief, network_alone(short, model))
    np.testing.assert_array_equal(stands, network_alone(still, model))
    np.testing.assert_array_equal(stretching, network_alone(bending, model))
    from nrdepth.cli import main

    np.save(tmp_path / "clip.npy", bending)
    save_model(model, tmp_path / "model.safetensors")
    command = ["reconstruct", str(tmp_path / "clip.npy"), "--model", str(tmp_path / "model.safetensors"), "--device", "cpu", "--max-side", "32"]
    assert main([*command, "-o", str(tmp_path / "on"), "--isometric-points", "36"]) == 0
    assert f"sheet: the network's depth alone ({unsure.reason}" in capsys.readouterr().out  # by default, the stage's line
    with np.load(tmp_path / "on" / "depth.npz") as saved:
        said = json.loads(str(saved["sheet"]))
        assert said["contrast"] == unsure.contrast and said["focal_estimate"] == unsure.focal_estimate
    assert main([*command, "-o", str(tmp_path / "off"), "--no-sheet"]) == 0
    assert "sheet: the network's depth alone (the sheet stage is off" in capsys.readouterr().out  # off: said too
    with np.load(tmp_path / "off" / "depth.npz") as saved:
        said = json.loads(str(saved["sheet"]))
        assert not said["used"] and said["focal"] is None and said["frames"] == len(bending)


@contextmanager
def spied(**steps):
    """Each of ``steps``' functions of the stage (:data:`STEPS`) replaced meanwhile."""
    with pytest.MonkeyPatch.context() as patch:
        for name, value in steps.items():
            patch.setattr(step_module(name), name, value)
        yield


def noise_beside(video, width=48):
    """``video`` with a strip of coloured noise beside it, new in every frame: nothing there is held."""
    T, H, _ = video.shape
    return np.concatenate([video, np.random.default_rng(1).integers(0, 256, (T, H, width), dtype=np.uint8)], axis=2)


def test_by_default_held_points_are_counted_where_they_are_read_so_a_frame_half_background_still_reads_its_sheet(model, bending):
    from nrdepth.isometric import mdh_depths

    T, H, W = bending.shape
    still = np.concatenate([bending, np.repeat(bending[:1, :, ::-1][:, :, :48], T, axis=0)], axis=2)  # a still background beside it: held, not moving
    options = {key: value for key, value in OPTIONS.items() if key != "focal"}
    starts = []
    # MIN_CONTRAST as above: a clip too small for the strain to pick a focal length sharply
    with spied(mdh_depths=lambda xy, *a, **k: starts.append(xy[0]) or mdh_depths(xy, *a, **k)):
        (_, lost), (_, held) = (decide(video, model, **options, sheet_settings=LOOSE) for video in (noise_beside(bending), still))
    assert lost.held < MIN_HELD  # most of the frame's point-frames are lost, which given a sheet would send the stage aside...
    assert lost.used and lost.template == "refined" and MIN_READ * OPTIONS["isometric_points"] <= lost.points  # ...but the sheet's are read
    assert held.used and held.held > 0.9  # the still background's points are held in every frame...
    assert (starts[1][:, 0] < W).all()  # ...but not read: every point read starts on the sheet


@pytest.mark.parametrize("least", [4, 1])
def test_by_default_the_sheet_found_is_read_through_the_focal_length_its_strain_picks_where_its_valley_lies_inside(model, bending, least):
    from nrdepth.isometric import FocalEstimate, mdh_depths

    focals = tuple(40.0 * 1.3**k for k in range(9))
    strains = tuple(0.001 * (1 + (k - least) ** 2) for k in range(9))  # a valley at `least`, contrast 5
    picked = FocalEstimate(focals[least], strains[least], focals, strains)
    options = {key: value for key, value in OPTIONS.items() if key != "focal"}
    seen = []
    with spied(mdh_depths=lambda xy, camera, *a, **k: seen.append(camera.focal) or mdh_depths(xy, camera, *a, **k),
               estimate_focal=lambda *a, **k: picked):
        found = decide(bending, model, **options).sheet  # nothing given
        read_first = len(seen)
        given = decide(bending, model, **options, focal=picked.focal).sheet  # the estimate given as the focal length
    guess = nrdepth.Camera.guessed(bending.shape[1:]).focal
    assert found.used and found.guessed and found.focal_estimate == picked.focal and picked.contrast >= MIN_CONTRAST
    if picked.inside:  # the gates through the guess, the shape through the estimate
        assert found.focal == (picked.focal,) * 2 and seen[:read_first] == [guess, found.focal] and " px estimated," in found.line()
    else:  # a valley at the grid's edge: the guess (the shape again from the points smoothed in time)
        assert found.focal == guess and seen[:read_first] == [guess, guess] and " px guessed," in found.line()
    assert given.used and not given.guessed and set(seen[read_first:]) == {(picked.focal,) * 2}  # given, that focal length alone


def test_the_shape_fused_is_solved_from_the_points_smoothed_in_time_while_every_gate_reads_them_as_tracked(model, bending):
    from scipy.ndimage import gaussian_filter1d

    from nrdepth.isometric import estimate_focal, mdh_depths, unstrained_points

    options = {key: value for key, value in OPTIONS.items() if key != "focal"}
    solved, gated = [], []
    # MIN_CONTRAST: a clip too small for the strain to pick a focal length sharply
    with spied(mdh_depths=lambda xy, *a, **k: solved.append(xy) or mdh_depths(xy, *a, **k),
               unstrained_points=lambda xy, *a, **k: gated.append(xy) or unstrained_points(xy, *a, **k),
               estimate_focal=lambda xy, *a, **k: gated.append(xy) or estimate_focal(xy, *a, **k)):
        decision = decide(bending, model, **options, sheet_settings=LOOSE).sheet
    assert decision.used and decision.template == "refined" and len(solved) == 2
    tracked, fused = solved
    trimmed_from = [gated[0][:, j] for j in range(gated[0].shape[1])]
    assert all(any(np.array_equal(tracked[:, i], column) for column in trimmed_from) for i in range(tracked.shape[1]))  # the trim: as tracked
    assert np.array_equal(gated[-1], tracked)  # the estimate: as tracked
    assert LOOSE.read_smooth > 0 and np.array_equal(fused, gaussian_filter1d(tracked, LOOSE.read_smooth, axis=0, mode="nearest"))
    assert np.abs(fused - tracked).max() > 1e-3  # smoothed: the points moved


def test_with_a_focal_length_but_no_sheet_the_sheet_is_found_first_as_by_default(model, bending):
    from nrdepth.isometric import mdh_depths

    T, H, W = bending.shape
    beside = noise_beside(bending)
    starts = []
    # MIN_CONTRAST: a clip too small for the strain to pick a focal length sharply
    with spied(mdh_depths=lambda xy, *a, **k: starts.append(xy[0]) or mdh_depths(xy, *a, **k)):
        found = decide(beside, model, **OPTIONS, sheet_settings=LOOSE).sheet  # the focal length alone
        boxed = decide(beside, model, **OPTIONS, sheet_settings=LOOSE, sheet=(0, 0, W + 48, H)).sheet  # the same region given as the sheet
        short = decide(beside[: MIN_FRAMES_BY_DEFAULT - 1], model, **OPTIONS, sheet_settings=LOOSE).sheet  # too short a clip to find the sheet in
    assert found.used and not found.guessed and found.focal == (OPTIONS["focal"],) * 2 and found.template == "refined"
    assert found.held < MIN_HELD and found.contrast >= 1.0 and (starts[0][:, 0] < W).all()  # the noise's points lost, the sheet's found and read
    assert boxed.used and boxed.template == "joint" and boxed.contrast is None  # given as the sheet: its point-frames held, no finding
    assert "not held points through refined: the points are found again in only" in boxed.reason
    assert "the sheet's held points" not in short.reason + boxed.reason and short.contrast is None


def test_points_are_followed_in_frames_shrunk_to_the_tracking_side_and_come_back_in_the_videos_pixels(monkeypatch):
    import importlib

    stage = importlib.import_module("nrdepth.reconstruct.sheet.find")
    texture = np.random.default_rng(2).random((96, 160))
    texture = np.real(np.fft.ifft2(np.fft.fft2(texture) * np.exp(-0.5 * (np.fft.fftfreq(96)[:, None] ** 2 + np.fft.fftfreq(160) ** 2) / 0.04**2)))
    texture = np.rint(255 * (texture - texture.min()) / np.ptp(texture)).astype(np.uint8)
    video = np.stack([np.roll(texture, 2 * t, axis=1)[:, 32:128] for t in range(8)])  # 2 px a frame to the right, 96×96
    region = np.zeros((96, 96), bool)
    region[24:72, 24:72] = True
    seen = []
    follow = stage.track_grid
    monkeypatch.setattr(stage, "track_grid", lambda frames, *a, **k: follow([seen.append(f.shape) or f for f in frames], *a, **k))
    native = stage.tracked(iter(video), region, 25, 0.0, False, DEFAULT)
    shrunk = stage.tracked(iter(video), region, 25, 0.0, False, DEFAULT.replace(track_side=48))
    assert seen == [(96, 96)] * 8 + [(48, 48)] * 8
    np.testing.assert_allclose(np.nanmedian(shrunk[-1] - shrunk[0], axis=0), [14.0, 0.0], atol=0.3)  # in the video's pixels
    assert shrunk.shape == native.shape and np.abs(shrunk[0] - native[0]).max() <= 0.5  # the same grid, within half a video pixel


def test_the_reading_beside_the_network_gives_the_bytes_read_in_turn_passes_on_its_errors_and_stops_with_the_job(model, bending):
    import importlib
    import time
    from concurrent.futures import CancelledError

    stage = importlib.import_module("nrdepth.reconstruct.sheet")
    options = nrdepth.ReconstructOptions.of(**OPTIONS)
    region, camera = stage.sheet_region(options, bending.shape[1:]), options.sheet_camera(bending.shape[1:])
    raw = network_alone(bending, model)  # the working resolution's depth, (37, 32, 32)
    frames = lambda: iter(bending)  # noqa: E731
    in_turn = raw.copy()
    decision = stage.sheet_depth(in_turn, raw.shape[1:], options, camera, region, frames)
    beside = raw.copy()
    with stage.read_beside(len(bending), options, camera, region, frames) as reading:
        assert stage.sheet_depth(beside, raw.shape[1:], options, camera, region, frames, reading) == decision
    assert decision.used and np.array_equal(in_turn, beside) and not np.array_equal(in_turn, raw)

    def failing():
        yield from bending[:20]
        raise ValueError("video: frame 20 is broken")

    with pytest.raises(ValueError, match="frame 20 is broken"), stage.read_beside(len(bending), options, camera, region, failing) as reading:
        stage.sheet_depth(raw.copy(), raw.shape[1:], options, camera, region, failing, reading)

    pulled = []

    def endless():  # a stream that never ends: only the job's end stops the reading
        while True:
            pulled.append(1)
            yield bending[len(pulled) % len(bending)]

    with pytest.raises(KeyboardInterrupt), stage.read_beside(10**6, options, camera, region, endless) as reading:
        while len(pulled) < 5 and not reading.done():  # a reading that failed at once fails the asserts below, not hangs
            time.sleep(0.01)
        raise KeyboardInterrupt  # the job interrupted while the reading is under way
    assert reading.done() and isinstance(reading.exception(), CancelledError)  # stopped and waited for: no thread runs on
    stopped_at = len(pulled)
    time.sleep(0.2)
    assert len(pulled) == stopped_at  # nothing read after it stopped
