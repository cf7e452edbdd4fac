"""The main job's options and camera: one definition that the API and the
command line share, checked once, and errors that name what the user set."""

import argparse
import dataclasses
import inspect
import math

import numpy as np
import pytest

import nrdepth
from nrdepth.cli import build_parser, main
from nrdepth.reconstruct.options import add_flags, flag_of, options_from_flags

# Every flag of `nrdepth reconstruct` set away from its default, and the options it must give.
FLAGS = [
    (["--roi", "1,2,30,40"], {"roi": (1, 2, 30, 40)}),
    (["--frames", "2:10:2"], {"frames": slice(2, 10, 2)}),
    (["--max-side", "0"], {"max_side": None}),
    (["--max-side", "96"], {"max_side": 96}),
    (["--mask", "mask.png"], {"mask": "mask.png"}),
    (["--device", "cpu"], {"device": "cpu"}),
    (["--precision", "float32"], {"precision": "float32"}),
    (["--batch-size", "3"], {"batch_size": 3}),
    (["--fine", "patches"], {"fine": "patches"}),
    (["--units", "pixels"], {"units": "pixels"}),
    (["--alignment", "coarse"], {"alignment": "coarse"}),
    (["--coarse-weight", "0.01"], {"coarse_weight": 0.01}),
    (["--temporal-weight", "0"], {"temporal_weight": 0.0}),
    (["--window", "triangle"], {"window": "triangle"}),
    (["--temporal-align"], {"temporal": True}),
    (["--no-sheet"], {"sheet_stage": False}),
    (["--focal", "500,510", "--centre", "10,20", "--sheet", "0,0,8,8", "--isometric-scale", "0.1", "--isometric-template", "refined",
      "--isometric-each-frame", "mirror", "--isometric-drop", "0.3", "--isometric-points", "900", "--isometric-hold"],
     {"focal": (500.0, 510.0), "centre": (10.0, 20.0), "sheet": (0, 0, 8, 8), "isometric_scale": 0.1, "isometric_template": "refined",
      "isometric_each_frame": "mirror", "isometric_drop": 0.3, "isometric_points": 900, "isometric_hold": True}),
    (["--sheet-settings", "min_contrast=1.5:jump=none"], {"sheet_settings": nrdepth.SheetSettings(min_contrast=1.5, jump=None)}),
    (["--flip", "--png16", "--ply", "--ply-relief", "0.1", "--no-viewer", "--overwrite"],
     {"flip": True, "png16": True, "ply": True, "ply_relief": 0.1, "viewer": False, "overwrite": True}),
]


def parsed(flags: list) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_flags(parser)
    return parser.parse_args(flags)


@pytest.mark.parametrize("flags, expected", FLAGS, ids=[f[0][0] for f in FLAGS])
def test_each_flag_sets_its_option_and_nothing_else(flags, expected):
    options = options_from_flags(parsed(flags))
    assert options.changed() == expected


def test_every_option_but_the_tile_has_a_flag_and_the_flags_cover_them():
    names = {f.name for f in dataclasses.fields(nrdepth.ReconstructOptions)}
    flagged = set().union(*(expected for _, expected in FLAGS))
    assert names - flagged == {"tile"}  # a tuning knob of the API, no flag
    defaults = options_from_flags(parsed([]))
    assert defaults.changed() == {}


def test_reconstruct_and_reconstruct_file_share_one_options_definition():
    a = set(inspect.signature(nrdepth.reconstruct).parameters)
    b = set(inspect.signature(nrdepth.reconstruct_file).parameters)
    assert len(a & b) <= 12, sorted(a & b)
    assert {"options", "settings"} <= a & b


def test_an_unknown_option_is_named():
    with pytest.raises(TypeError, match="^foci: not an option of the main job"):
        nrdepth.reconstruct(np.zeros((4, 32, 32), np.uint8), foci=500.0)
    with pytest.raises(TypeError, match="^options: expected nrdepth.ReconstructOptions"):
        nrdepth.reconstruct(np.zeros((4, 32, 32), np.uint8), options={"roi": (0, 0, 8, 8)})


@pytest.mark.parametrize("settings, option", [
    ({"focal": "100"}, "focal"),
    ({"focal": True}, "focal"),
    ({"focal": -5.0}, "focal"),
    ({"focal": (1.0, 2.0, 3.0)}, "focal"),
    ({"focal": 100.0, "centre": ("a", 1)}, "centre"),
    ({"centre": (1.0, 1.0), "sheet_stage": False}, "sheet_stage"),  # the centre shapes the sheet's depth: it needs the sheet stage
    ({"sheet_stage": "no"}, "sheet_stage"),
    ({"sheet_stage": False, "focal": 100.0}, "sheet_stage"),
    ({"focal": 100.0, "isometric_drop": 1.0}, "isometric_drop"),
    ({"focal": 100.0, "isometric_scale": float("nan")}, "isometric_scale"),
    ({"focal": 100.0, "isometric_points": 2.5}, "isometric_points"),
    ({"focal": 100.0, "isometric_hold": "yes"}, "isometric_hold"),
    ({"focal": 100.0, "isometric_each_frame": "best"}, "isometric_each_frame"),
    ({"isometric_each_frame": "program", "units": "pixels"}, "isometric_each_frame"),
    ({"roi": (0, 0, 8.5, 8)}, "roi"),
    ({"max_side": 4}, "max_side"),
    ({"tile": (8, 36, 64)}, "tile"),
    ({"batch_size": 0}, "batch_size"),
    ({"coarse_weight": 0.0}, "coarse_weight"),
    ({"mask": np.ones((8, 8), np.uint8)}, "mask"),
    ({"mask": np.ones((8, 8), bool), "alignment": "coarse"}, "mask"),
    ({"ply_relief": float("inf")}, "ply_relief"),
])
def test_a_bad_option_names_itself(settings, option):
    with pytest.raises((ValueError, TypeError)) as caught:
        nrdepth.ReconstructOptions(**settings)
    assert caught.value.option == option and str(caught.value).startswith(f"{option}: ")


def test_the_command_line_names_the_flag_the_user_set(tmp_path, capsys):
    np.save(tmp_path / "clip.npy", np.zeros((4, 32, 32), np.uint8))
    for flags, flag in [(["--focal", "0"], "--focal"), (["--max-side", "4"], "--max-side"), (["--temporal-align", "--focal", "9"], "--focal"),
                        (["--sheet", "40,40,9,9", "--focal", "9"], "--sheet"), (["--ply-relief", "-1"], "--ply-relief")]:
        assert main(["reconstruct", str(tmp_path / "clip.npy"), "-o", str(tmp_path / "out"), "--quiet", *flags]) == 2
        message = capsys.readouterr().err.strip()
        assert message.startswith(f"nrdepth reconstruct: error: {flag}: "), message
        assert not (tmp_path / "out").exists()
    assert flag_of("viewer") == "--no-viewer" and flag_of("temporal") == "--temporal-align" and flag_of("out") == "--out"


def test_the_help_shows_every_flag_once():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices["reconstruct"]
    flags = [s for a in sub._actions for s in a.option_strings if s.startswith("--")]
    assert len(flags) == len(set(flags))
    assert {"--focal", "--no-viewer", "--temporal-align", "--max-side", "--roi"} <= set(flags)


def test_a_sheet_without_a_focal_length_is_seen_through_the_guessed_pinhole():
    from nrdepth.camera import GUESSED_VIEW

    for frame in ((480, 640), (1920, 1080)):  # landscape and portrait: the view is across the longer side
        guessed = nrdepth.Camera.guessed(frame)
        assert math.isclose(2 * math.degrees(math.atan(max(frame) / 2 / guessed.focal[0])), GUESSED_VIEW) and guessed.focal[0] == guessed.focal[1]
        assert guessed.centre == ((frame[1] - 1) / 2, (frame[0] - 1) / 2)
        assert nrdepth.ReconstructOptions(sheet=(0, 0, 8, 8)).sheet_camera(frame) == guessed
    assert nrdepth.ReconstructOptions(sheet=(0, 0, 8, 8), centre=(10, 20)).sheet_camera((480, 640)).centre == (10.0, 20.0)
    default = nrdepth.ReconstructOptions()
    assert default.sheet_mode and not default.sheet_given and default.sheet_camera((480, 640)) == nrdepth.Camera.guessed((480, 640))
    for off in ({"sheet_stage": False}, {"units": "pixels"}, {"temporal": True}):  # no stage where its shape could not join the depth
        assert not nrdepth.ReconstructOptions(**off).sheet_mode
    assert np.allclose(nrdepth.Camera.guessed((256, 256), view=90).focal, 128.0)  # 90° across: the focal length half the side
    with pytest.raises(ValueError, match="^view: expected degrees"):
        nrdepth.Camera.guessed((480, 640), view=180)


def test_a_camera_is_checked_once_and_passed_as_itself():
    K = np.array([[528.0, 0.0, 319.5], [0.0, 530.0, 239.5], [0.0, 0.0, 1.0]])
    camera = nrdepth.Camera.from_matrix(K)
    assert camera == nrdepth.Camera((528.0, 530.0), (319.5, 239.5))
    assert nrdepth.Camera(500).focal == (500.0, 500.0) and nrdepth.Camera(500).principal_point((480, 640)) == (319.5, 239.5)
    options = nrdepth.ReconstructOptions(focal=camera)
    assert (options.focal, options.centre, options.sheet_camera((480, 640))) == ((528.0, 530.0), (319.5, 239.5), camera)
    # A point seen at its pixel is on its ray: x = f X / Z + c.
    X = np.array([[0.3, -0.2, 2.0]])
    xy = np.stack([528.0 * X[:, 0] / X[:, 2] + 319.5, 530.0 * X[:, 1] / X[:, 2] + 239.5], axis=-1)
    np.testing.assert_allclose(camera.rays(xy) * X[:, 2:], X)
    for bad in (np.eye(4), [[528, 1, 319], [0, 530, 239], [0, 0, 1]], [[528, 0, 319], [0, 530, 239], [0, 0, 2]]):
        with pytest.raises(ValueError, match="^K: "):
            nrdepth.Camera.from_matrix(bad)
