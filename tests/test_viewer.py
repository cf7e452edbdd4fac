"""The 3-D viewer page (``nrdepth.io.viewer``): its data round trip, decimation
and size, the files that write it, and the page itself in a real headless
Chromium, offline: its script runs without errors, the canvas shows both
the surface and the background, and moving the time slider changes the
picture. A page broken on purpose is caught by the same checks."""

from __future__ import annotations

import base64
import os
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

import nrdepth
import nrdepth.model
from nrdepth.io.viewer import SAMPLES, ViewerFrames, view


def clip(size=96, seed=3):
    c = nrdepth.generate_clips(1, seed=seed, config=nrdepth.GeneratorConfig(size=size))
    return c.video[0], c.depth[0]


def test_the_pages_depth_decodes_to_the_block_means_within_its_quantisation():
    depth = np.random.default_rng(0).standard_normal((5, 70, 300)).astype(np.float32)
    frames = ViewerFrames(depth.shape, side=100)
    frames.add(depth[:2])
    frames.add(depth[2:])
    data = frames.payload("d")
    assert frames.step == 3 and (data["rows"], data["cols"]) == (24, 100) and data["grey"] is None
    heights = np.frombuffer(base64.b64decode(data["z"]), "<i2").reshape(5, 24, 100) * data["zscale"] + data["zoffset"]
    means = depth[:, :69, :].reshape(5, 23, 3, 100, 3).mean(axis=(2, 4))
    shown = np.concatenate(frames.depth)
    expected = -(means - shown.mean()) / shown.std()
    np.testing.assert_allclose(heights[:, :23], expected, atol=data["zscale"])


def test_long_videos_keep_every_kth_frame_and_say_so():
    frames = ViewerFrames((300, 1080, 1920))
    assert frames.mesh == (72, 128) and frames.keep == 1  # 300 × 72 × 128 = 2.8 M vertex-frames
    long = ViewerFrames((3000, 1080, 1920))
    assert long.keep == 10 and 3000 // long.keep * 72 * 128 <= SAMPLES
    long.add(np.zeros((25, 1080, 1920), np.float32))
    assert [len(d) for d in long.depth] == [3] and "every 10th of the 3000 frames" in long.note()


def test_view_refuses_bad_input_by_name(tmp_path):
    with pytest.raises(ValueError, match="^depth:"):
        view(np.zeros((4, 8), np.float32), path=tmp_path / "v.html")
    with pytest.raises(ValueError, match="^video:"):
        view(np.zeros((4, 8, 8), np.float32), np.zeros((4, 8, 9), np.uint8), path=tmp_path / "v.html")
    with pytest.raises(ValueError, match="^depth:.*no depth.npz"):
        view(tmp_path)



def _damaged_folder(folder: Path, damage: str) -> None:
    """A reconstruction folder whose depth.npz is damaged as named."""
    import zipfile

    folder.mkdir()
    npz = folder / "depth.npz"
    depth = np.random.default_rng(0).random((6, 8, 10)).astype(np.float32)
    if damage == "random bytes":
        npz.write_bytes(np.random.default_rng(1).bytes(4096))
    elif damage == "cut in half":
        np.savez(npz, depth=depth)
        npz.write_bytes(npz.read_bytes()[: npz.stat().st_size // 2])
    elif damage == "no depth":
        np.savez(npz, range=np.array([0.0, 1.0], np.float32))
    elif damage == "integer depth":
        np.savez(npz, depth=(depth * 100).astype(np.int16))
    elif damage == "one frame plane":
        np.savez(npz, depth=depth[0])
    elif damage == "frames missing":  # a header that promises more frames than the member holds
        with zipfile.ZipFile(npz, "w") as archive, archive.open("depth.npy", "w") as member:
            np.lib.format.write_array_header_2_0(member, {"descr": "<f4", "fortran_order": False, "shape": (12, 8, 10)})
            member.write(depth.tobytes())


DAMAGE = {
    "random bytes": "not a readable .npz archive",
    "cut in half": "not a readable .npz archive",
    "no depth": "holds no array 'depth' \\(it holds range\\)",
    "integer depth": "holds depth of int16 \\(6, 8, 10\\); expected a float depth video",
    "one frame plane": "holds depth of float32 \\(8, 10\\); expected a float depth video",
    "frames missing": "is cut short: its data ends in frame 6 of the 12 its header gives",
}


@pytest.mark.parametrize("damage", list(DAMAGE))
def test_view_names_a_damaged_depth_npz_and_the_cli_exits_2(tmp_path, damage, capsys):
    from nrdepth.cli import main

    folder = tmp_path / "out"
    _damaged_folder(folder, damage)
    with pytest.raises(ValueError, match=f"^depth: {folder / 'depth.npz'}.*{DAMAGE[damage]}"):
        view(folder)
    capsys.readouterr()
    assert main(["view", str(folder)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"nrdepth view: error: depth: {folder / 'depth.npz'}"), err
    assert sorted(p.name for p in folder.iterdir()) == ["depth.npz"]  # no page, no temporary file

def test_view_refuses_files_that_disagree_or_infinite_depth_naming_the_file_and_leaves_no_partial_page(tmp_path):
    import torch

    torch.manual_seed(0)
    video, _ = clip(size=64)
    np.save(tmp_path / "clip.npy", video)
    out = nrdepth.reconstruct_file(tmp_path / "clip.npy", tmp_path / "out", nrdepth.model.UNet3D(base=2), device="cpu", max_side=32)
    with np.load(out / "depth.npz") as saved:
        arrays = dict(saved)
        assert "sheet" in arrays and "sheet:" in (out / "viewer.html").read_text()  # the stage's decision is on the page
    listing = sorted(p.name for p in out.iterdir())
    for frames in (len(video) + 24, len(video) - 4):  # more and fewer frames of depth than the side-by-side video has
        depth = np.resize(arrays["depth"], (frames, *arrays["depth"].shape[1:]))
        np.savez(out / "depth.npz", **{**arrays, "depth": depth})
        with pytest.raises(ValueError, match=f"^video: {out / 'side_by_side.mp4'} holds (more|fewer) frames than the {frames} of "):
            view(out)
    infinite = arrays["depth"].copy()
    infinite[3, 2, 2] = np.inf
    np.savez(out / "depth.npz", **{**arrays, "depth": infinite})
    with pytest.raises(ValueError, match=f"^depth: {out / 'depth.npz'}: frame 3 holds infinite depth"):
        view(out)
    with pytest.raises(ValueError, match="^depth: expected a float depth video .*finite"):
        view(infinite, path=tmp_path / "v.html")
    np.savez(out / "depth.npz", **arrays)
    (out / "viewer.html").unlink()
    (out / "viewer.html").mkdir()
    with pytest.raises(ValueError, match="^path: .*viewer.html is a folder"):
        view(out)
    assert sorted(p.name for p in out.iterdir()) == listing and not list(tmp_path.glob("**/*.partial-*"))


def test_a_reconstruction_folder_gets_its_viewer_and_view_rewrites_it(tmp_path):
    import torch

    torch.manual_seed(0)
    video, _ = clip(size=64)
    np.save(tmp_path / "clip.npy", video)
    out = nrdepth.reconstruct_file(tmp_path / "clip.npy", tmp_path / "out", nrdepth.model.UNet3D(base=2), device="cpu")
    first = (out / "viewer.html").read_text()
    assert "nrdepth-view" in first and "Plotly" in first
    (out / "viewer.html").unlink()
    assert view(out) == out / "viewer.html" and (out / "viewer.html").stat().st_size > 4_000_000  # plotly.js is inside
    nrdepth.reconstruct_file(tmp_path / "clip.npy", tmp_path / "bare", nrdepth.model.UNet3D(base=2), device="cpu", viewer=False)
    assert not (tmp_path / "bare" / "viewer.html").exists()


# The page in a browser.

CHROMIUM, DRIVER = shutil.which("chromium"), shutil.which("chromedriver")


@pytest.fixture(scope="module")
def browser():
    if CHROMIUM is None or DRIVER is None:
        if os.environ.get("CI"):
            pytest.fail("CI must have chromium and chromedriver (.ci/run installs Debian's packages)")
        pytest.skip("chromium and chromedriver are not installed (apt-get install chromium chromium-driver)")
    from selenium import webdriver
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service

    options = Options()
    options.binary_location = CHROMIUM
    # Offline: no name resolves. WebGL without a GPU: SwiftShader.
    for flag in ("--headless=new", "--no-sandbox", "--window-size=1280,800", "--host-resolver-rules=MAP * ~NOTFOUND",
                 "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--disable-dev-shm-usage"):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(DRIVER), options=options)
    yield driver
    driver.quit()


def screenshot(driver) -> np.ndarray:
    import cv2

    rect = driver.execute_script("return document.getElementById('nrdepth-view').getBoundingClientRect().toJSON()")
    image = cv2.imdecode(np.frombuffer(driver.get_screenshot_as_png(), np.uint8), cv2.IMREAD_COLOR)
    scale = image.shape[1] / driver.execute_script("return window.innerWidth")
    top, left = int(rect["top"] * scale) + 60, int(rect["left"] * scale)  # below the titles
    return image[top : int(rect["bottom"] * scale), left : int(rect["right"] * scale)]


def page_problems(driver, page: Path) -> list:
    """What is wrong with a viewer page in the browser: errors in its
    console, a blank canvas, a time slider that changes nothing."""
    driver.get_log("browser")  # drop what earlier pages left
    driver.get(page.resolve().as_uri())
    problems = []
    deadline = time.time() + 30
    while not driver.execute_script("return !!(window.nrdepthViewer && document.querySelector('#nrdepth-view canvas'))"):
        if time.time() > deadline:
            return [f"console: {e['message']}" for e in driver.get_log("browser")] + ["no plot after 30 s"]
        time.sleep(0.2)
    time.sleep(1.0)
    before = screenshot(driver)
    background = (before.min(axis=2) > 245).mean()
    if not 0.05 < background < 0.95:
        problems.append(f"blank: {background:.0%} of the plot is background")
    driver.execute_script("const s = document.getElementById('nrdepth-time'); s.value = s.max; s.dispatchEvent(new Event('input'));")
    time.sleep(1.5)
    after = screenshot(driver)
    if np.abs(after.astype(int) - before.astype(int)).mean() < 0.5:
        problems.append("the time slider changes nothing")
    problems += [f"console: {e['message']}" for e in driver.get_log("browser") if e["level"] in ("SEVERE", "ERROR")]
    return problems


def test_the_viewer_page_runs_offline_draws_the_surface_and_scrubs(tmp_path, browser):
    video, depth = clip()
    page = view(depth, video, tmp_path / "viewer.html", fps=10)
    assert page_problems(browser, page) == []


def test_a_broken_or_blank_page_is_caught(tmp_path, browser):
    video, depth = clip()
    page = view(depth, video, tmp_path / "viewer.html", fps=10)
    broken = tmp_path / "broken.html"
    broken.write_text(page.read_text().replace("Plotly.restyle(div, update", "Plotly.restyle(undefinedVariable, update"))
    assert any(p.startswith("console:") for p in page_problems(browser, broken))
    blank = tmp_path / "blank.html"
    blank.write_text(page.read_text().replace("</head>", "<style>#nrdepth-view canvas { visibility: hidden }</style></head>", 1))
    assert any(p.startswith("blank") for p in page_problems(browser, blank))


def test_the_demo_page_shows_truth_and_reconstruction_under_one_slider(tmp_path, browser):
    from nrdepth.demo import demo_page

    video, truth = clip(size=64)
    result = {"video": video, "truth": truth, "depth": truth + 0.1 * np.random.default_rng(0).standard_normal(truth.shape).astype(np.float32)}
    page = demo_page(result, tmp_path / "demo.html")
    assert page_problems(browser, page) == []
    assert browser.execute_script("return document.querySelectorAll('#nrdepth-view canvas').length") >= 1
    assert browser.execute_script("return document.getElementById('nrdepth-view').data.length") == 2


def test_depth_off_the_surface_leaves_a_hole_in_the_page(tmp_path, browser):
    video, depth = clip()
    background = []
    for name, shown in (("whole", depth), ("holed", np.where(np.arange(depth.shape[2]) < depth.shape[2] // 2, np.nan, depth).astype(np.float32))):
        assert page_problems(browser, view(shown, video, tmp_path / f"{name}.html", fps=10)) == [], name
        background.append((screenshot(browser).min(axis=2) > 245).mean())
    assert (1 - background[1]) < 0.7 * (1 - background[0]), background  # half the surface gone, the scene's scale kept: the page's white shows through
