"""The CLI writes a complete PNG of the requested size, or nothing; its
generator options reach the clips it writes."""

import json
import math
import struct

import numpy as np
import pytest

from nrdepth.cli import main
from nrdepth.engine.dataset import ClipStore
from nrdepth.engine.generate import window_widths


def png_size(path):
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert data[12:16] == b"IHDR" and data[-8:-4] == b"IEND"
    return struct.unpack(">II", data[16:24])


def test_surfaces_writes_a_png_sheet(tmp_path):
    out = tmp_path / "sheet.png"
    assert main(["surfaces", str(out), "--clips", "2", "--frames", "5", "--grid", "16", "--columns", "3"]) == 0
    # 2 rows and 3 columns of 32-pixel tiles with 4-pixel gutters.
    assert png_size(out) == (3 * 36 + 4, 2 * 36 + 4)
    assert [p.name for p in tmp_path.iterdir()] == ["sheet.png"]


def test_surfaces_refuses_bad_sizes_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "sheet.png"
    assert main(["surfaces", str(out), "--grid", "1"]) == 2
    assert "grid" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


def test_unwritable_destination_is_a_clear_error(tmp_path, capsys):
    out = tmp_path / "missing-dir" / "sheet.png"
    assert main(["surfaces", str(out), "--clips", "1", "--frames", "2", "--grid", "8"]) == 2
    assert "cannot write" in capsys.readouterr().err


def test_pictures_carry_titles_and_a_colour_bar_with_values():
    import numpy as np

    from nrdepth.io.figures import ColourBar, labelled
    from nrdepth.io import colorize_depth

    depth = np.linspace(1.0, 2.0, 60 * 90).reshape(1, 60, 90)
    mosaic = colorize_depth(depth, (1.0, 2.0))[0]
    plain = labelled(mosaic, ["a", "b", "c"], 30)
    out = labelled(mosaic, ["a", "b", "c"], 30, colour_bar=ColourBar(1.0, 2.0, "depth (mm)"), title="a title")
    assert plain.dtype == out.dtype == np.uint8 and plain.shape[0] > 60 and out.shape[0] > plain.shape[0] and out.shape[1] > plain.shape[1] + 60
    # The mosaic is drawn pixel for pixel; titles above it and the bar's ticks beside it are dark text on white.
    h, w = plain.shape[:2]
    np.testing.assert_array_equal(plain[h - 8 - 60 : h - 8, 8 : 8 + 90], mosaic)
    assert (plain[: h - 68] < 80).all(axis=-1).any()
    bar = out[:, 8 + 90 + 10 :]
    assert (bar < 80).all(axis=-1).sum() > 50  # tick labels and the axis label
    ramp = {tuple(c) for c in mosaic.reshape(-1, 3)}
    assert sum(tuple(c) in ramp for c in bar.reshape(-1, 3)) > 200  # the ramp's own colours
    try:
        labelled(np.zeros((4, 4)), [], 4)
    except ValueError as e:
        assert str(e).startswith("image:")
    else:
        raise AssertionError("a grey image was accepted")


def test_help_shows_defaults():
    import contextlib
    import io

    from nrdepth.cli import build_parser

    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer), contextlib.suppress(SystemExit):
        build_parser().parse_args(["reconstruct", "--help"])
    assert "(default: 8)" in buffer.getvalue() and "0.073" in buffer.getvalue()


def test_generate_passes_the_window_width_to_the_generator(tmp_path, capsys):
    """--window-width reaches the clips (their windows are that wide) and a
    bad range is refused naming the field."""
    out = tmp_path / "zoomed"
    assert main(["generate", str(out), "--clips", "2", "--window-width", "0.5,0.5", "--quiet"]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["config"]["window_width"] == [0.5, 0.5]
    written = ClipStore(out)
    assert np.allclose(window_widths([written[i][2] for i in range(len(written))]), 0.5)
    assert main(["generate", str(tmp_path / "bad"), "--clips", "2", "--window-width", "0,3"]) != 0
    assert "config.window_width" in capsys.readouterr().err and not (tmp_path / "bad").exists()


def test_evaluate_passes_the_readings_to_the_scores(tmp_path, capsys):
    from nrdepth.learning.evaluate import evaluate
    from nrdepth.model import DEFAULT_MODEL

    assert main(["evaluate", str(DEFAULT_MODEL), "--clips", "2", "--device", "cpu", "--readings", "4", "-o", str(tmp_path)]) == 0
    assert "4 readings averaged" in capsys.readouterr().out
    written = json.loads((tmp_path / "summary.json").read_text())
    assert written["readings"] == 4
    assert written["mae_sn_frame"] == evaluate(DEFAULT_MODEL, clips=2, device="cpu", readings=4)["mae_sn_frame"]
    assert written["mae_sn_frame"] != evaluate(DEFAULT_MODEL, clips=2, device="cpu")["mae_sn_frame"]


def test_train_defaults_to_the_recommended_recipe_and_the_paper_is_one_flag_away(tmp_path, capsys):
    from nrdepth.learning import PAPER, RECOMMENDED

    tiny = ["--epochs", "1", "--steps", "1", "--batch-size", "1", "--validation-clips", "1", "--workers", "0", "--device", "cpu",
            "--base", "4", "--frames", "4", "--quiet"]
    for name, flags, recipe in (("ours", [], RECOMMENDED), ("paper", ["--paper"], PAPER), ("mixed", ["--paper", "--loss", "aligned"], {**PAPER, "loss": "aligned"})):
        assert main(["train", str(tmp_path / name), *flags, *tiny]) == 0
        config = json.loads((tmp_path / name / "config.json").read_text())
        assert {k: config[k] for k in recipe} == recipe, name
    assert RECOMMENDED["arch"] != PAPER["arch"] and RECOMMENDED["loss"] != PAPER["loss"]


def test_train_learns_from_backdrop_clips_with_a_signed_loss_and_refuses_others(tmp_path, capsys):
    tiny = ["--epochs", "1", "--steps", "1", "--batch-size", "2", "--validation-clips", "2", "--workers", "0", "--device", "cpu",
            "--base", "4", "--frames", "4", "--quiet", "--backdrops", "1"]
    assert main(["train", str(tmp_path / "ours"), *tiny, "--backdrop-brightness", "0,0.1", "--camera-fov", "30,60", "--crop-share", "0.5,1", "--perspective", "0.5"]) == 0
    config = json.loads((tmp_path / "ours" / "config.json").read_text())
    assert config["generator"]["backdrop_probability"] == 1.0
    assert config["generator"]["backdrop_brightness"] == [0.0, 0.1]
    assert config["generator"]["camera_fov"] == pytest.approx([math.radians(30), math.radians(60)])
    assert config["generator"]["crop_share"] == [0.5, 1.0]
    assert config["generator"]["camera_probability"] == 0.5
    metrics = (tmp_path / "ours" / "metrics.csv").read_text().splitlines()
    header, row = metrics[0].split(","), metrics[-1].split(",")
    assert all(np.isfinite(float(row[header.index(k)])) for k in ("train_loss", "val_mae_sn_frame", "val_mae_sn_flat_frame"))
    assert main(["train", str(tmp_path / "paper"), *tiny, "--paper"]) != 0
    assert "backdrop clips have no depth off the sheet" in capsys.readouterr().err
    assert main(["train", str(tmp_path / "bright"), *tiny, "--backdrop-brightness", "0,2"]) != 0
    assert "backdrop_brightness" in capsys.readouterr().err
    assert main(["train", str(tmp_path / "wide"), *tiny, "--camera-fov", "0,170"]) != 0
    assert "camera_fov" in capsys.readouterr().err


def test_keep_freed_memory_reuses_a_large_freed_buffer():
    """The ``nrdepth`` command's heap keeps what it frees: a 64 MB buffer
    allocated again after it was freed is not faulted in again (glibc; a
    process of its own for each, since the setting is the process's)."""
    import subprocess
    import sys

    code = (
        "import resource, sys\n"
        "import numpy as np\n"
        "from nrdepth.memory import keep_freed_memory\n"
        "kept = keep_freed_memory() if sys.argv[1] == 'keep' else None\n"
        "a = np.ones(64 << 20, np.uint8); del a\n"
        "before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt\n"
        "for _ in range(5):\n"
        "    a = np.ones(64 << 20, np.uint8); del a\n"
        "print(kept, resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)\n"
    )
    faults = {}
    for how in ("keep", "default"):
        kept, count = subprocess.run([sys.executable, "-c", code, how], check=True, capture_output=True, text=True).stdout.split()
        if how == "keep" and kept != "True":
            pytest.skip("not glibc: the heap is left as it is")
        faults[how] = int(count)
    assert faults["keep"] * 10 < faults["default"], faults
