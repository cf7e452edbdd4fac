"""The 3D U-Net of the paper: a grayscale video patch (B, 1, T, H, W) to its
depth video at half spatial resolution (B, 1, T, H/2, W/2).

Stages (``base`` = width of the first stage, default 16):

    stem     ConvAct 1 → base                        T,   H,   W
    enc1     Context(base,  rates 1, 2, 3)           T,   H,   W
    enc2     Context(2base, rates 1, 2, 3)  pool 1×2×2  T,   H/2, W/2
    enc3     Context(4base, rates 1, 2)     pool 2×2×2  T/2, H/4, W/4
    bottom   Context(8base, rates 1, 2)     pool 2×2×2  T/4, H/8, W/8
    up3      Up(8base + 4base → 4base, rates 1, 2)      T/2, H/4, W/4
    up2      Up(4base + 2base → 2base, rates 1, 2, 3)   T,   H/2, W/2
    head     1×1×1 convolution 2base → 1, linear

3×3×3 kernels throughout, leaky ReLU everywhere but the linear head. T must
be divisible by 4 and H, W by 8. Default parameter count: see
``count_parameters(UNet3D())`` (tested).
"""

from __future__ import annotations

from typing import Any, Dict

import torch
from torch import nn

from .parts import Context, ConvAct, Up


class UNet3D(nn.Module):
    def __init__(self, base: int = 16) -> None:
        super().__init__()
        if not isinstance(base, int) or base < 1:
            raise ValueError(f"base: expected a positive int, got {base!r}")
        self.config: Dict[str, Any] = {"base": base}
        b = base
        self.stem = ConvAct(1, b)
        self.enc1 = Context(b, b, (1, 2, 3))
        self.enc2 = Context(b, 2 * b, (1, 2, 3))
        self.enc3 = Context(2 * b, 4 * b, (1, 2))
        self.bottom = Context(4 * b, 8 * b, (1, 2))
        self.up3 = Up(8 * b, 4 * b, 4 * b, (1, 2))
        self.up2 = Up(4 * b, 2 * b, 2 * b, (1, 2, 3))
        self.head = nn.Conv3d(2 * b, 1, 1)

    def forward(self, video: torch.Tensor) -> torch.Tensor:
        if video.dim() != 5 or video.shape[1] != 1:
            raise ValueError(f"video: expected (B, 1, T, H, W), got {tuple(video.shape)}")
        t, h, w = video.shape[2:]
        if t % 4 or h % 8 or w % 8:
            raise ValueError(f"video: expected T divisible by 4 and H, W by 8, got T={t}, H={h}, W={w}")
        pool = nn.functional.max_pool3d
        e1 = self.enc1(self.stem(video))
        e2 = self.enc2(pool(e1, (1, 2, 2)))
        e3 = self.enc3(pool(e2, 2))
        bottom = self.bottom(pool(e3, 2))
        return self.head(self.up2(self.up3(bottom, e3), e2))


def count_parameters(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())
