"""Building blocks of the 3D U-Net: convolution + leaky ReLU, and the context
module with atrous spatial pyramid pooling (parallel dilated 3×3×3
convolutions, concatenated, fused by a 3×3×3 convolution)."""

from __future__ import annotations

from typing import Sequence

import torch
from torch import nn

NEGATIVE_SLOPE = 0.1


class ConvAct(nn.Sequential):
    """3×3×3 convolution (optionally dilated) followed by a leaky ReLU."""

    def __init__(self, cin: int, cout: int, dilation: int = 1) -> None:
        super().__init__(nn.Conv3d(cin, cout, 3, padding=dilation, dilation=dilation), nn.LeakyReLU(NEGATIVE_SLOPE, inplace=True))


class Context(nn.Module):
    """ASPP context module: one ConvAct per dilation rate in parallel, their
    outputs concatenated and fused by a ConvAct to ``cout`` channels."""

    def __init__(self, cin: int, cout: int, rates: Sequence[int]) -> None:
        super().__init__()
        self.branches = nn.ModuleList(ConvAct(cin, cout, r) for r in rates)
        self.fuse = ConvAct(cout * len(rates), cout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.fuse(torch.cat([branch(x) for branch in self.branches], dim=1))


class Up(nn.Module):
    """Trilinear ×2 upsampling (time and space), concatenation with the skip
    connection, then a context module."""

    def __init__(self, cin: int, cskip: int, cout: int, rates: Sequence[int]) -> None:
        super().__init__()
        self.context = Context(cin + cskip, cout, rates)

    def forward(self, x: torch.Tensor, skip: torch.Tensor) -> torch.Tensor:
        x = nn.functional.interpolate(x, size=skip.shape[2:], mode="trilinear", align_corners=False)
        return self.context(torch.cat([x, skip], dim=1))
