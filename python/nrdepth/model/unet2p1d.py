"""A U-Net of factorised (2+1)D convolutions, built for the cost of a CPU:
a grayscale video patch (B, 1, T, H, W) to its depth at half spatial
resolution (B, 1, T, H/2, W/2), as :class:`UNet3D`, at a fraction of its work.

Where :class:`UNet3D` spends its FLOPs, and what this network does instead:

- the output is at half resolution, so after one cheap full-resolution
  convolution (``stem_width`` channels) a stride-2 convolution brings the
  video to H/2 × W/2 before any context module;
- every 3×3×3 kernel is factorised into a spatial 1×3×3 and a temporal
  3×1×1 convolution, each followed by a leaky ReLU ((2+1)D: fewer weights
  and FLOPs, one more non-linearity), inside residual blocks;
- the context module (atrous spatial pyramid pooling, dilations 1, 2, 4) runs
  on the coarsest level, behind a 1×1×1 bottleneck, and its branches are
  spatial only;
- time keeps its full length at every level (16 frames cost little at
  H/8), so no temporal detail is pooled away;
- :class:`UNet2p1DGlobal` (``unet2p1d_global``) adds a temporal context
  module on the coarsest level, so every frame sees the whole clip;
  :class:`UNet2p1DDeep` (``unet2p1d_deep``) adds residual blocks there,
  where the large-scale shape is read, at H/8 × W/8 cost.

Levels (``width`` = w, default 24)::

    stem     1×3×3 conv 1 → stem_width, 3×3 stride 2 conv → w   T, H/2, W/2
    level1   Block(w) × 2                                       T, H/2, W/2
    level2   stride-2 1×3×3 conv w → 2w, Block(2w) × 2          T, H/4, W/4
    level3   stride-2 1×3×3 conv 2w → 4w, Block(4w), context    T, H/8, W/8
    up2      ×2 upsample, 1×1×1 conv 4w → 2w, + level2, Block   T, H/4, W/4
    up1      ×2 upsample, 1×1×1 conv 2w → w,  + level1, Block   T, H/2, W/2
    head     1×1×1 conv w → 1, linear

The input is standardised per clip (zero mean, unit standard deviation over
the patch) inside the network: depth does not depend on exposure, and
reconstruction sees videos of any brightness. H and W must be divisible by 8;
T is free.
"""

from __future__ import annotations

from typing import Any, Dict, Sequence

import torch
from torch import nn

from .parts import NEGATIVE_SLOPE

STD_FLOOR = 1e-3
"""Added to the input's standard deviation before dividing by it (a flat clip stays finite)."""


WRITE_OVER = True
"""Without gradients, sums are written over a layer's new output
(:class:`Block`'s residual, :class:`UpMerge`'s skip): the same bits, no
new activations. False: every sum a new tensor, as with gradients (the
reference ``benchmarks/bench_kernels.py write-over`` times against)."""


def _written_over() -> bool:
    return WRITE_OVER and not torch.is_grad_enabled()


def _plus(fresh: torch.Tensor, other: torch.Tensor) -> torch.Tensor:
    """``other + fresh``, written over ``fresh`` (a layer's new output)
    where no gradient is kept and the two are laid out alike: inference
    then allocates no new activation, whose page faults cost more than
    the sum (a quarter of the CPU's fine pass went to these sums). The
    same bits either way: addition commutes."""
    if not _written_over() or fresh.dtype != other.dtype or fresh.shape != other.shape or fresh.stride() != other.stride():
        return other + fresh
    return fresh.add_(other)


def _act() -> nn.Module:
    return nn.LeakyReLU(NEGATIVE_SLOPE, inplace=True)


def spatial(cin: int, cout: int, stride: int = 1, dilation: int = 1) -> nn.Conv3d:
    """A 1×3×3 convolution (space only)."""
    return nn.Conv3d(cin, cout, (1, 3, 3), stride=(1, stride, stride), padding=(0, dilation, dilation), dilation=(1, dilation, dilation))


def temporal(cin: int, cout: int) -> nn.Conv3d:
    """A 3×1×1 convolution (time only)."""
    return nn.Conv3d(cin, cout, (3, 1, 1), padding=(1, 0, 0))


class Block(nn.Module):
    """Residual (2+1)D block: x + temporal(act(spatial(x))), then act."""

    def __init__(self, width: int) -> None:
        super().__init__()
        self.spatial, self.temporal, self.act = spatial(width, width), temporal(width, width), _act()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.act(_plus(self.temporal(self.act(self.spatial(x))), x))


class SpatialContext(nn.Module):
    """ASPP behind a bottleneck: 1×1×1 to ``width // 2``, parallel 1×3×3
    convolutions at the given dilations, concatenated, fused by a 1×1×1
    convolution back to ``width`` and added to the input."""

    def __init__(self, width: int, rates: Sequence[int]) -> None:
        super().__init__()
        inner = max(width // 2, 1)
        self.reduce = nn.Sequential(nn.Conv3d(width, inner, 1), _act())
        self.branches = nn.ModuleList(nn.Sequential(spatial(inner, inner, dilation=r), _act()) for r in rates)
        self.fuse = nn.Conv3d(inner * len(rates), width, 1)
        self.act = _act()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        reduced = self.reduce(x)
        return self.act(_plus(self.fuse(torch.cat([branch(reduced) for branch in self.branches], dim=1)), x))


class TemporalContext(nn.Module):
    """The whole clip in time at the coarsest level: a 1×1×1 bottleneck to
    ``width // 2``, parallel 3×1×1 convolutions at the given temporal
    dilations, concatenated and fused by a 1×1×1 convolution that is added
    to the input. The fusion starts at zero, so the module starts as the
    identity (a network without it warm-starts one with it unchanged)."""

    ZERO_START = "fuse"
    """The child whose zero weights make the module the identity (:mod:`nrdepth.model.average`)."""

    def __init__(self, width: int, rates: Sequence[int]) -> None:
        super().__init__()
        inner = max(width // 2, 1)
        self.reduce = nn.Sequential(nn.Conv3d(width, inner, 1), _act())
        self.branches = nn.ModuleList(
            nn.Sequential(nn.Conv3d(inner, inner, (3, 1, 1), padding=(r, 0, 0), dilation=(r, 1, 1)), _act()) for r in rates)
        self.fuse = nn.Conv3d(inner * len(rates), width, 1)
        nn.init.zeros_(self.fuse.weight)
        nn.init.zeros_(self.fuse.bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        reduced = self.reduce(x)
        return _plus(self.fuse(torch.cat([branch(reduced) for branch in self.branches], dim=1)), x)


class IdentityStartBlock(nn.Module):
    """Residual (2+1)D block without the closing activation, whose temporal
    convolution starts at zero: x + temporal(act(spatial(x))) is the
    identity at initialisation, so a network that gains it warm-starts
    from one without it unchanged."""

    ZERO_START = "temporal"
    """The child whose zero weights make the block the identity (:mod:`nrdepth.model.average`)."""

    def __init__(self, width: int) -> None:
        super().__init__()
        self.spatial, self.temporal, self.act = spatial(width, width), temporal(width, width), _act()
        nn.init.zeros_(self.temporal.weight)
        nn.init.zeros_(self.temporal.bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return _plus(self.temporal(self.act(self.spatial(x))), x)


class UpMerge(nn.Module):
    """Spatial ×2 upsampling (nearest), a 1×1×1 convolution to the skip's
    width, added to the skip connection, then a block. The convolution runs
    before the upsampling, which it commutes with (a pointwise map of
    replicated voxels): the same output, at a quarter of its work and half
    the upsampled tensor (the tiled fine pass: 193 → 172 bytes of
    activations per input voxel). Where no gradient is kept, the
    projection is added to the skip in its own memory, each voxel to the
    2 × 2 it stands for, the skip being used nowhere after: the same bits,
    and no upsampled tensor at all."""

    def __init__(self, cin: int, cout: int) -> None:
        super().__init__()
        self.project, self.block = nn.Conv3d(cin, cout, 1), Block(cout)

    def forward(self, x: torch.Tensor, skip: torch.Tensor) -> torch.Tensor:
        x = self.project(x)
        n, c, t, h, w = skip.shape
        if (_written_over() and x.dtype == skip.dtype and x.shape == (n, c, t, h // 2, w // 2) and h % 2 == w % 2 == 0
                and (skip.is_contiguous() or skip.is_contiguous(memory_format=torch.channels_last_3d))):
            skip.view(n, c, t, h // 2, 2, w // 2, 2).add_(x[:, :, :, :, None, :, None])
            return self.block(skip)
        return self.block(_plus(nn.functional.interpolate(x, size=skip.shape[2:], mode="nearest"), skip))


def _check_rates(name: str, rates: Sequence[int]) -> tuple:
    rates = tuple(rates)
    if not rates or any(isinstance(r, bool) or not isinstance(r, int) or r < 1 for r in rates):
        raise ValueError(f"{name}: expected positive ints, got {rates!r}")
    return rates


class UNet2p1D(nn.Module):
    def __init__(self, width: int = 24, stem_width: int = 8, rates: Sequence[int] = (1, 2, 4)) -> None:
        super().__init__()
        for name, value in (("width", width), ("stem_width", stem_width)):
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name}: expected a positive int, got {value!r}")
        rates = _check_rates("rates", rates)
        self.config: Dict[str, Any] = {"width": width, "stem_width": stem_width, "rates": list(rates)}
        w = width
        self.stem = nn.Sequential(spatial(1, stem_width), _act(), spatial(stem_width, w, stride=2), _act())
        self.level1 = nn.Sequential(Block(w), Block(w))
        self.level2 = nn.Sequential(spatial(w, 2 * w, stride=2), _act(), Block(2 * w), Block(2 * w))
        self.level3 = nn.Sequential(spatial(2 * w, 4 * w, stride=2), _act(), Block(4 * w), SpatialContext(4 * w, rates))
        self.up2 = UpMerge(4 * w, 2 * w)
        self.up1 = UpMerge(2 * w, w)
        self.head = nn.Conv3d(w, 1, 1)

    def forward(self, video: torch.Tensor) -> torch.Tensor:
        if video.dim() != 5 or video.shape[1] != 1:
            raise ValueError(f"video: expected (B, 1, T, H, W), got {tuple(video.shape)}")
        h, w = video.shape[3:]
        if h % 8 or w % 8:
            raise ValueError(f"video: expected H and W divisible by 8, got H={h}, W={w}")
        flat = video.flatten(1)
        mean, std = flat.mean(1), flat.std(1)
        return self.forward_standardised((video - mean.view(-1, 1, 1, 1, 1)) / (std.view(-1, 1, 1, 1, 1) + STD_FLOOR))

    def forward_standardised(self, x: torch.Tensor) -> torch.Tensor:
        """The network after its input standardisation, given ``x`` already
        standardised (by a statistic of the caller's choice: the tiled fine
        pass of ``nrdepth.reconstruct`` uses one for the whole video, so a
        tile's output does not depend on which tile it was cut in)."""
        l1 = self.level1(self.stem(x))
        l2 = self.level2(l1)
        l3 = self.level3(l2)
        return self.head(self.up1(self.up2(l3, l2), l1))


class UNet2p1DGlobal(UNet2p1D):
    """:class:`UNet2p1D` whose coarsest level also sees the whole clip in
    time (:class:`TemporalContext` after the spatial context, dilations
    ``temporal_rates``). The plain network's seven 3-tap temporal
    convolutions give each output frame ±7 frames: beyond the clip-wide
    standardisation of the input, frame 15 of a 16-frame clip never sees
    frame 0, so the plane's motion between them (what MAE-SN from the first
    frame charges) can only be read twice, independently. The module adds
    39,456 parameters (394,953 in all at the default width)."""

    def __init__(self, width: int = 24, stem_width: int = 8, rates: Sequence[int] = (1, 2, 4), temporal_rates: Sequence[int] = (2, 4, 8)) -> None:
        super().__init__(width, stem_width, rates)
        temporal_rates = _check_rates("temporal_rates", temporal_rates)
        self.config["temporal_rates"] = list(temporal_rates)
        self.level3.append(TemporalContext(4 * width, temporal_rates))


class UNet2p1DDeep(UNet2p1D):
    """:class:`UNet2p1D` with ``coarse_blocks`` more residual blocks on the
    coarsest level, after the spatial context (:class:`IdentityStartBlock`:
    the network starts as the plain one, so it warm-starts from its
    weights). Capacity where the clip's large-scale shape and the plane's
    motion are read, at an eighth of the resolution: at the default width
    each block adds 110,784 parameters and 0.23 GFLOP a 64×64×16 patch (the
    plain network's whole forward pass: 2.06)."""

    def __init__(self, width: int = 24, stem_width: int = 8, rates: Sequence[int] = (1, 2, 4), coarse_blocks: int = 4) -> None:
        super().__init__(width, stem_width, rates)
        if isinstance(coarse_blocks, bool) or not isinstance(coarse_blocks, int) or coarse_blocks < 1:
            raise ValueError(f"coarse_blocks: expected a positive int, got {coarse_blocks!r}")
        self.config["coarse_blocks"] = coarse_blocks
        for _ in range(coarse_blocks):
            self.level3.append(IdentityStartBlock(4 * width))
