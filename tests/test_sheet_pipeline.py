"""The sheet stage as one pipeline: fail-safe at every step, one gate whatever
its options, and a decision in every output."""

import json
import warnings

import numpy as np
import pytest

import nrdepth
import nrdepth.model
from nrdepth import GeneratorConfig, SheetSettings, generate_clips
from nrdepth.reconstruct import reconstruct_file

from test_sheet_stage import LOOSE, OPTIONS, bending, model, step_module  # noqa: F401 (bending and model: the same fixtures)

NOTHING_GIVEN = {key: value for key, value in OPTIONS.items() if key != "focal"}


@pytest.fixture(scope="module")
def noise():
    """A generated surface of coloured noise that deforms freely (no sheet), 36 frames."""
    config = GeneratorConfig(frames=36, size=64, grid=64, sheet_probability=0.0, camera_fov=(1.0, 1.0), crop_share=(1.0, 1.0))
    return generate_clips(1, seed=3, config=config).video[0]


@pytest.fixture(scope="module")
def alone(model, bending, noise):
    """The network's depth alone of each video."""
    return {name: nrdepth.reconstruct(video, model, device="cpu", max_side=32, sheet_stage=False) for name, video in (("bending", bending), ("noise", noise))}


@pytest.fixture(scope="module")
def defaults(model, bending, noise):
    """The default's decision on each video (nothing given), and whether it reads the bending sheet with the looser contrast."""
    return {"noise": reconstructed(noise, model, **NOTHING_GIVEN).sheet, "bending": reconstructed(bending, model, **NOTHING_GIVEN).sheet,
            "loose": reconstructed(bending, model, **NOTHING_GIVEN, sheet_settings=LOOSE).sheet}


def reconstructed(video, model, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return nrdepth.reconstruct(video, model, device="cpu", with_decision=True, **options)


# Each step of the stage, with the call of it that fails (the fusion's on its second chunk: the first is already fused by then).
FAILING = [("track_grid", 1), ("moving_points", 1), ("unstrained_points", 1), ("mdh_depths", 1), ("template_strain", 1), ("mdh_depths", 2),
           ("estimate_focal", 1), ("densify", 2), ("fuse", 2)]


GIVEN_TOO = ("track_grid", "mdh_depths", "densify")
"""A step of each module: where it fails with focal or sheet given, the error names that option (the same handler serves every step)."""


@pytest.mark.parametrize("step,call", FAILING)
def test_a_failure_at_any_step_keeps_the_networks_depth_by_default_and_names_the_option_where_one_was_given(monkeypatch, model, bending, alone,
                                                                                                          defaults, step, call):
    module = step_module(step)
    real, calls = getattr(module, step), []

    def failing(*args, **kwargs):
        calls.append(1)
        if len(calls) == call:
            raise RuntimeError(f"injected at {step}")
        return real(*args, **kwargs)

    assert defaults["loose"].used  # unbroken, the stage reads this sheet: every step below is reached
    monkeypatch.setattr(module, step, failing)
    depth, decision = reconstructed(bending, model, **NOTHING_GIVEN, sheet_settings=LOOSE)
    assert len(calls) >= call and not decision.used and decision.scale is None
    assert f"RuntimeError: injected at {step}" in decision.reason and decision.reason.startswith("the stage failed")
    np.testing.assert_array_equal(depth, alone["bending"])  # all or nothing: not one frame fused
    if step not in GIVEN_TOO:
        return
    for given, option in (({"focal": 60.0}, "focal"), ({"sheet": (2, 2, 60, 60)}, "sheet")):
        calls.clear()
        try:
            reconstructed(bending, model, **NOTHING_GIVEN, **given, sheet_settings=LOOSE)
        except ValueError as error:
            assert error.option == option and isinstance(error.__cause__, RuntimeError)
            assert str(error).startswith(f"{option}: the sheet stage failed") and f"injected at {step}" in str(error)
        else:  # a given sheet is not looked for: the finder's steps are never reached
            assert len(calls) < call and option == "sheet" and step in ("moving_points", "unstrained_points", "estimate_focal")


def test_a_failed_fusion_streamed_to_a_file_leaves_the_networks_depth_and_no_scratch(monkeypatch, tmp_path, model, bending):
    np.save(tmp_path / "clip.npy", bending)
    settings = {**NOTHING_GIVEN, "sheet_settings": LOOSE, "device": "cpu"}
    reconstruct_file(tmp_path / "clip.npy", tmp_path / "alone", model, device="cpu", max_side=OPTIONS["max_side"], sheet_stage=False)
    module, calls = step_module("densify"), []
    real = module.densify
    monkeypatch.setattr(module, "densify", lambda *a, **k: calls.append(1) or (real(*a, **k) if len(calls) < 3 else 1 / 0))
    reconstruct_file(tmp_path / "clip.npy", tmp_path / "out", model, **settings)
    with np.load(tmp_path / "out" / "depth.npz") as saved, np.load(tmp_path / "alone" / "depth.npz") as network:
        sheet = json.loads(str(saved["sheet"]))
        np.testing.assert_array_equal(saved["depth"], network["depth"])
    assert not sheet["used"] and "ZeroDivisionError" in sheet["reason"] and len(calls) == 3
    listing = lambda folder: sorted(p.name for p in (tmp_path / folder).rglob("*"))  # noqa: E731
    assert listing("out") == listing("alone")  # no staging or partial file left
    assert not list(tmp_path.rglob("*.sheet")) and not list(tmp_path.rglob("*.partial*"))


# Every option of the stage with nothing given, and what it sets.
STAGE_OPTIONS = [("isometric_template", "joint"), ("isometric_template", "refined"), ("isometric_template", "first"),
                 ("isometric_each_frame", "program"), ("isometric_each_frame", "mirror"), ("isometric_hold", True), ("isometric_scale", 0.0),
                 ("isometric_drop", 0.0), ("isometric_points", 49), ("centre", (30.0, 34.0))]


@pytest.mark.parametrize("name,value", STAGE_OPTIONS)
def test_with_nothing_given_every_option_of_the_stage_reads_through_the_same_gate(model, bending, noise, alone, defaults, name, value):
    for video in ("noise", "bending"):  # the bending sheet at 64×64: its strain picks no focal length sharply, so the gate says no
        frames, default = {"noise": noise, "bending": bending}[video], defaults[video]
        depth, decision = reconstructed(frames, model, **{**NOTHING_GIVEN, name: value})
        assert not default.used and not decision.used, (video, decision.line())
        np.testing.assert_array_equal(depth, alone[video])
        if name not in ("isometric_drop", "isometric_points", "centre"):  # the same points through the same camera: the same verdict
            assert decision.reason == default.reason
    assert default.reason.startswith("no focal length keeps their pairs' lengths")  # the contrast gate, which an option once switched off
    # and where the gate passes (a looser contrast), the option asks for its reading
    if name in ("isometric_template", "isometric_each_frame"):
        read = reconstructed(bending, model, **{**NOTHING_GIVEN, name: value}, sheet_settings=LOOSE).sheet
        assert read.used and read.contrast is not None and (name != "isometric_template" or read.template == value)


def test_every_run_has_a_decision_and_every_skipped_stage_says_why(tmp_path, model, bending):
    depth, decision = reconstructed(bending, model, **NOTHING_GIVEN, sheet_settings=LOOSE)
    assert decision.used and decision.camera == nrdepth.Camera(decision.focal, decision.centre) and decision.camera.focal == decision.focal
    assert isinstance(nrdepth.reconstruct(bending, model, device="cpu", max_side=32, sheet_stage=False), np.ndarray)  # the depth alone unless asked
    for options, says in (({"sheet_stage": False}, "the sheet stage is off"), ({"units": "pixels"}, "units='standard' and temporal off only"),
                          ({"temporal": True}, "units='standard' and temporal off only")):
        skipped = reconstructed(bending, None if "units" in options else model, max_side=32, **options).sheet  # pixels: the shipped model that learnt them
        assert not skipped.used and says in skipped.reason and skipped.camera is None and skipped.frames == len(bending)
        assert skipped.line().startswith(f"sheet: the network's depth alone ({says}") or says in skipped.line()
    # an option that cannot act says so, by name, and the decision says why
    with pytest.warns(UserWarning, match="isometric_points: the sheet stage did not read the video"):
        tiny = nrdepth.reconstruct(bending, model, device="cpu", max_side=32, isometric_points=4, with_decision=True).sheet  # 4 less the drop
    assert not tiny.used and "cannot run here" in tiny.reason
    with pytest.warns(UserWarning, match="centre: the sheet stage did not read the video"):
        nrdepth.reconstruct(bending[:20], model, device="cpu", max_side=32, centre=(30.0, 30.0))
    with pytest.warns(UserWarning, match="isometric_hold: with neither focal nor sheet given"):
        reconstructed_warned = nrdepth.reconstruct(bending, model, device="cpu", **NOTHING_GIVEN, isometric_hold=True)
    assert reconstructed_warned.shape == depth.shape


@pytest.mark.parametrize("shape", [(16, 32, 2000), (16, 2000, 32), (16, 2, 200)])
def test_a_video_of_any_shape_the_network_reads_is_read_with_the_stage_skipped_where_no_pinhole_fits(model, shape):
    video = np.random.default_rng(0).integers(0, 256, shape, dtype=np.uint8)
    for sheet_stage in (True, False):
        depth, decision = reconstructed(video, model, max_side=64, sheet_stage=sheet_stage)
        assert depth.shape == shape and not decision.used


def test_a_benchmarks_setting_and_the_command_lines_give_the_same_bytes(tmp_path, model, bending):
    """The benchmarks run the shipped stage: a setting there is ``--sheet-settings`` here."""
    import importlib.util
    from pathlib import Path

    from nrdepth.cli import main
    from nrdepth.model import save_model

    spec = importlib.util.spec_from_file_location("bench_sheet_stage", Path(__file__).parents[1] / "benchmarks" / "bench_sheet_stage.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    setting = "min_contrast=1:read_smooth=0.5"
    options = bench.job_options(setting, **NOTHING_GIVEN)
    assert options.sheet_settings == SheetSettings(min_contrast=1.0, read_smooth=0.5)
    np.save(tmp_path / "clip.npy", bending)
    save_model(model, tmp_path / "model.safetensors")
    reconstruct_file(tmp_path / "clip.npy", tmp_path / "api", tmp_path / "model.safetensors", options, device="cpu")
    assert main(["reconstruct", str(tmp_path / "clip.npy"), "-o", str(tmp_path / "cli"), "--model", str(tmp_path / "model.safetensors"),
                 "--device", "cpu", "--max-side", "32", "--isometric-points", "36", "--sheet-settings", setting]) == 0
    with np.load(tmp_path / "api" / "depth.npz") as api, np.load(tmp_path / "cli" / "depth.npz") as cli:
        assert json.loads(str(api["sheet"]))["used"] and api["depth"].tobytes() == cli["depth"].tobytes()
    with pytest.raises(ValueError, match="sheet_settings: min_contrast: expected a finite number"):
        SheetSettings.parse("min_contrast=-1")
    with pytest.raises(ValueError, match="sheet_settings: keyframes: expected an integer ≥ 2"):
        SheetSettings(keyframes=1)
    with pytest.raises(ValueError, match="sheet_settings: expected key=value pairs"):
        SheetSettings.parse("min_contrats=1")
    assert SheetSettings.parse(SheetSettings(jump=None, keyframes=12).text()) == SheetSettings(jump=None, keyframes=12)
