"""The CLI writes a complete PNG of the requested size, or nothing; its
generator options reach the clips it writes."""

import json
import struct

import numpy as np

from nrdepth.cli import main
from nrdepth.dataset import ClipStore
from nrdepth.generate import window_widths


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


def test_pictures_carry_readable_labels():
    import numpy as np

    from nrdepth.labels import text, titled, with_colour_bar

    mask = text("ab 1", scale=2)
    assert mask.shape == (14, 4 * 12) and mask.any()
    assert not np.array_equal(text("a"), text("b")) and not text(" ").any()
    picture = np.full((40, 60, 3), 128, np.uint8)
    out = with_colour_bar(titled(picture, ["x", "y"], 30), "far", "near")
    assert out.shape[0] == 40 + 22 and out.shape[1] > 60
    assert (out[:22] == 0).any()  # the titles are drawn in black on the white band
    # A title wider than its column wraps inside it instead of running into the next.
    wrapped = titled(np.full((40, 90, 3), 128, np.uint8), ["ground truth", "", "nrdepth (gbr-aligned)"], 30)
    band = wrapped[: wrapped.shape[0] - 40] == 0
    assert wrapped.shape[0] > 62 and band[:, :30].any() and band[:, 60:].any() and not band[:, 30:60].any()


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
    from nrdepth.evaluate import evaluate
    from nrdepth.model import DEFAULT_MODEL

    assert main(["evaluate", str(DEFAULT_MODEL), "--clips", "2", "--device", "cpu", "--readings", "4", "-o", str(tmp_path)]) == 0
    assert "4 readings averaged" in capsys.readouterr().out
    written = json.loads((tmp_path / "summary.json").read_text())
    assert written["readings"] == 4
    assert written["mae_sn_frame"] == evaluate(DEFAULT_MODEL, clips=2, device="cpu", readings=4)["mae_sn_frame"]
    assert written["mae_sn_frame"] != evaluate(DEFAULT_MODEL, clips=2, device="cpu")["mae_sn_frame"]
