"""The real videos nrdepth is scored on, and how each is scored: one place
for the benchmarks, the experiments and training's ``--real``.

- ``phisft_R1``: a real cloth, 50 frames with per-frame depth ground truth.
  :func:`phisft_crop` is the 108×108 crop (:data:`CROP`) of the 4×4-binned
  frames that the benchmarks score; :func:`phisft_at_bin` the same region
  at another binning.
- ``kinect_paper``: a real bending sheet of paper, 191 frames of 640×480,
  sparse 3-D ground truth (``gt_mdh.npz``): :func:`kinect_video`,
  :func:`kinect_truth`, :func:`kinect_camera`, scored in mm by
  :func:`kinect_score` on the points inside a region.

The data sets live in the repository's ``../shared/data/real``; set
``NRDEPTH_DATA`` to another folder that holds ``phisft_R1/`` and
``kinect_paper/``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Dict, Tuple

import numpy as np

from ..io import read_video
from .metrics import gbr_align, sparse_baselines, sparse_mae, sparse_sign_rate


def _default_data() -> Path:
    """``NRDEPTH_DATA``, else ``../shared/data/real`` beside the repository: found from the package's own
    files (an editable install) or from the working folder (the repository's root, as the scripts run)."""
    if "NRDEPTH_DATA" in os.environ:
        return Path(os.environ["NRDEPTH_DATA"])
    candidates = [Path(__file__).resolve().parents[4] / "shared" / "data" / "real", Path.cwd().resolve().parent / "shared" / "data" / "real"]
    return next((c for c in candidates if c.is_dir()), candidates[-1])


DATA = _default_data()
"""The folder of the real videos (``NRDEPTH_DATA``, or ``../shared/data/real`` beside the repository)."""


def data_folder(name: str) -> Path:
    """The folder of the real video ``name`` under :data:`DATA`; FileNotFoundError naming ``NRDEPTH_DATA`` if it is missing."""
    folder = DATA / name
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder}: no such data set; set NRDEPTH_DATA to the folder that holds {name}/")
    return folder


CROP = (110, 218, 106, 214)
"""The crop of ``phisft_R1`` scored of the 4×4-binned grid: TOP, BOTTOM, LEFT, RIGHT."""
FOCAL, CENTRE = (971.522, 944.575), (962.134, 554.778)
"""The full frames' intrinsics (pixels; the data set's README)."""


def crop_at_bin(b: int) -> tuple:
    """:data:`CROP`'s region on the full frames binned b×b: TOP, BOTTOM, LEFT, RIGHT."""
    return tuple(round(c * 4 / b) for c in CROP)


def phisft_at_bin(b: int) -> tuple:
    """``phisft_R1`` on the full frames box-averaged b×b, cut to the region
    of :data:`CROP`: gray uint8 (50, S, S) and ground-truth Z float32 (metres,
    NaN where no point falls), with S = 108·4/b."""
    root = data_folder("phisft_R1")
    top, bottom, left, right = crop_at_bin(b)
    if b == 4:
        data = np.load(root / "derived_q4.npz")
        return data["gray"][:, top:bottom, left:right], data["depth"][:, top:bottom, left:right]
    full = read_video(root / "rgbs").frames.astype(np.float64)
    t, h, w = full.shape
    gray = np.rint(full[:, : h // b * b, : w // b * b].reshape(t, h // b, b, w // b, b).mean(axis=(2, 4))).astype(np.uint8)
    clouds = np.load(root / "gt_pointclouds.npz")
    depth = np.full(gray.shape, np.nan, np.float32)
    for i in range(t):
        p = clouds["points"][clouds["offsets"][i] : clouds["offsets"][i + 1]].astype(np.float64)
        u, v = ((f * p[:, k] / p[:, 2] + c + 0.5) / b - 0.5 for k, f, c in zip((0, 1), FOCAL, CENTRE))
        iu, iv = np.rint(u).astype(int), np.rint(v).astype(int)
        inside = (iu >= 0) & (iu < w // b) & (iv >= 0) & (iv < h // b)
        far_first = np.argsort(-p[inside, 2], kind="stable")  # the nearest point is written last
        depth[i, iv[inside][far_first], iu[inside][far_first]] = p[inside, 2][far_first]
    return gray[:, top:bottom, left:right], depth[:, top:bottom, left:right]


def phisft_crop() -> Tuple[np.ndarray, np.ndarray]:
    """``phisft_R1``'s scored crop (:data:`CROP` of ``derived_q4.npz``, the
    frames box-averaged 4×4): gray uint8 (50, 108, 108) and its depth
    (metres, NaN where the Kinect has none)."""
    return phisft_at_bin(4)


PHISFT_BORDER = 10
"""``phisft_R1``'s border region: the cloth's pixels within this many pixels
(on the 4×4-binned grid) of the black background. In :data:`CROP` they are
the hem and the left edge, a quarter of the scored pixels, and they carry
most of what separates checkpoints on this video (docs/campaign.md)."""


def phisft_regions(gray: np.ndarray, truth: np.ndarray) -> dict:
    """The scored pixels (finite ``truth``) of ``phisft_R1`` frames ``gray``
    (T, H, W) split into ``"border"`` (within :data:`PHISFT_BORDER` pixels of
    the background, gray 0) and ``"inside"``: bool (T, H, W) each."""
    from scipy.ndimage import distance_transform_edt

    scored = np.isfinite(truth)
    near = np.stack([distance_transform_edt(frame > 0) <= PHISFT_BORDER for frame in gray])
    return {"border": scored & near, "inside": scored & ~near}


def scaled_error(aligned: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """MAE-SN's error map of a depth already aligned to ``truth`` (T, H, W):
    the absolute error divided by each frame's truth's standard deviation
    over its finite pixels; NaN where the truth is."""
    spread = np.array([frame[np.isfinite(frame)].std() for frame in truth])[:, None, None]
    return np.abs(aligned - truth) / spread


def region_errors(depth: np.ndarray, truth: np.ndarray, regions: dict) -> dict:
    """MAE-SN per frame split by region: each frame of ``depth`` GBR-aligned
    over all its scored pixels as :func:`~nrdepth.scores.metrics.mae_sn` does, its
    :func:`scaled_error` averaged over each region's pixels (the regions'
    pixel-weighted mean is close to, not equal to, MAE-SN's mean of frame
    means)."""
    error = scaled_error(gbr_align(depth, truth, "frame", mask=np.isfinite(truth)), truth)
    return {name: float(error[region].mean()) for name, region in regions.items()}


KINECT_ROI = (64, 24, 528, 416)
"""x, y, width, height of the whole sheet in kinect_paper's 640×480 frames."""


def kinect_video() -> np.ndarray:
    """``kinect_paper``'s frames: gray uint8 (191, 480, 640)."""
    return read_video(data_folder("kinect_paper")).frames


def kinect_camera() -> Tuple[Tuple[float, float], Tuple[float, float]]:
    """The Kinect's focal lengths (f_x, f_y) and principal point (c_x, c_y), pixels (``gt_mdh.npz``'s K)."""
    K = np.load(data_folder("kinect_paper") / "gt_mdh.npz")["K"].astype(np.float64)
    return (float(K[0, 0]), float(K[1, 1])), (float(K[0, 2]), float(K[1, 2]))


def kinect_truth() -> Dict[str, np.ndarray]:
    """``gt_mdh.npz``: ``frames`` (23,) 0-based indices of the frames with
    ground truth, ``uv`` (23, 2, 301) pixel positions, ``z`` (23, 301) depth in mm."""
    gt = np.load(data_folder("kinect_paper") / "gt_mdh.npz")
    return {"frames": gt["file_index"].astype(int) - 1, "uv": gt["uv"].astype(np.float64), "z": gt["P"][:, 2].astype(np.float64)}


def kinect_score(depth: np.ndarray, truth: dict, roi: tuple = KINECT_ROI, signs: bool = False) -> float:
    """MAE in mm of a depth video of the ``roi`` (x, y, w, h) of every frame
    on the sparse ground truth's points inside it (``nrdepth.scores.metrics.sparse_mae``),
    or with ``signs`` the share of frames whose relief sign is right."""
    x, y, w, h = roi
    uv = truth["uv"] - np.array([x, y], np.float64)[None, :, None]
    inside = (uv[:, 0] >= 0) & (uv[:, 0] <= w - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= h - 1)
    return (sparse_sign_rate if signs else sparse_mae)(depth[truth["frames"]], uv, truth["z"], mask=inside)


def kinect_references(truth: dict, roi: tuple) -> dict:
    """Plane, fixed bowl and oracle quadratic on the points inside ``roi``."""
    x, y, w, h = roi
    u, v = truth["uv"][:, 0] - x, truth["uv"][:, 1] - y
    return sparse_baselines(truth["uv"], truth["z"], mask=(u >= 0) & (u <= w - 1) & (v >= 0) & (v <= h - 1))


KINECT_INNER = (200, 96, 320, 272)
"""x, y, width, height of a crop inside the sheet (the printed part in frame 0; the crop ``bench_table3.py`` scores)."""
