"""Is the plane's motion in the network's features, beyond what it outputs?

MAE-SN from the first frame charges how each frame's plane (tilt and mean
depth) moves over a clip, and the shipped network reads only part of that
motion (README, "The shipped model"). This probe asks whether more of it
is there to be read: the network is frozen, and a small head is trained on
fresh clips to add a plane a_t + b_t·x + c_t·y to each frame of its depth
(scaled by the clip's depth std, so scale-free). The head sees, per frame,
each level's features and the standardised input and output pooled three
ways (mean, and moments along x and along y over the frame: a tilt's
first-order traces), mixed over the clip by dilated temporal convolutions
(±14 frames); its last layer starts at zero, so it starts as the network.
It trains on the clip term of the campaign's loss (`aligned_clip_signed`
on the observable target), the only term a per-frame plane changes.

Scores: the training run's validation clips every ``--every`` steps, and
at the end the 128 held-out clips of ``nrdepth evaluate``, with and
without the head, paired over the clips (mean difference ± standard
error).

    python benchmarks/plane_head_probe.py [--model default] [--steps 4000] [--lr 1e-3] [--control]

``--control`` is the positive control: the head also sees the true depth's
(the observable target's) moments, so it can learn the planes, and the
probe shows how much a head of this size, trained this long, recovers
when the information is there.
"""

from __future__ import annotations

import argparse
import time
from typing import Optional

import numpy as np
import torch
from torch import nn

import nrdepth
from nrdepth.evaluate import TEST_SEED
from nrdepth.losses import aligned_clip_signed_loss
from nrdepth.metrics import mae_sn
from nrdepth.model import DEFAULT_MODEL, UNet2p1D, load_model
from nrdepth.train import VALIDATION_SEED_OFFSET, OnlineBatches, evaluate_depth


def moments(f: torch.Tensor) -> torch.Tensor:
    """(B, C, T, H, W) → (B, 3C, T): the mean over each frame and its first moments along x and y."""
    h, w = f.shape[-2:]
    ys, xs = torch.meshgrid(torch.linspace(-1, 1, h), torch.linspace(-1, 1, w), indexing="ij")
    return torch.cat([f.mean((-2, -1)), (f * xs).mean((-2, -1)), (f * ys).mean((-2, -1))], 1)


def features(net: nn.Module, video: torch.Tensor, truth: Optional[torch.Tensor] = None) -> tuple:
    """The frozen network's depth (B, T, H/2, W/2) and the head's input (B, C, T);
    with ``truth`` (B, T, H/2, W/2), its moments too (the control)."""
    flat = video.flatten(1)
    x = (video - flat.mean(1).view(-1, 1, 1, 1, 1)) / (flat.std(1).view(-1, 1, 1, 1, 1) + 1e-3)
    l1 = net.level1(net.stem(x))
    l2 = net.level2(l1)
    l3 = net.level3(l2)
    depth = net.head(net.up1(net.up2(l3, l2), l1))[:, 0]
    d = (depth - depth.mean((1, 2, 3), keepdim=True)) / (depth.std((1, 2, 3), keepdim=True) + 1e-6)
    parts = [moments(l1), moments(l2), moments(l3), moments(x), moments(d.unsqueeze(1))]
    if truth is not None:
        parts.append(moments(((truth - truth.mean((1, 2, 3), keepdim=True)) / (truth.std((1, 2, 3), keepdim=True) + 1e-6)).unsqueeze(1)))
    return depth, torch.cat(parts, 1)


class PlaneHead(nn.Module):
    def __init__(self, channels: int, width: int = 64) -> None:
        super().__init__()
        act = lambda: nn.LeakyReLU(0.1)  # noqa: E731
        self.body = nn.Sequential(nn.Conv1d(channels, width, 1), act(),
                                  *[m for d in (1, 2, 4) for m in (nn.Conv1d(width, width, 3, padding=d, dilation=d), act())])
        self.out = nn.Conv1d(width, 3, 1)
        nn.init.zeros_(self.out.weight)
        nn.init.zeros_(self.out.bias)

    def forward(self, depth: torch.Tensor, feats: torch.Tensor) -> torch.Tensor:
        a, b, c = self.out(self.body(feats))[..., None, None].unbind(1)  # each (B, T, 1, 1)
        h, w = depth.shape[-2:]
        ys, xs = torch.meshgrid(torch.linspace(-1, 1, h), torch.linspace(-1, 1, w), indexing="ij")
        return depth + depth.std((1, 2, 3), keepdim=True) * (a + b * xs + c * ys)


def read(net: nn.Module, clips: "nrdepth.Clips", control: bool) -> tuple:
    v = torch.from_numpy(clips.video).float().div(255).unsqueeze(1)
    truth = half(np.stack([nrdepth.observable_depth(d, p) for d, p in zip(clips.depth, clips.params)])) if control else None
    with torch.no_grad():
        parts = [features(net, v[i : i + 8], None if truth is None else truth[i : i + 8]) for i in range(0, len(v), 8)]
        # features() repeats the network's forward pass to reach its levels: it must give the network's depth.
        torch.testing.assert_close(parts[0][0], net(v[:8])[:, 0])
    return torch.cat([p[0] for p in parts]), torch.cat([p[1] for p in parts])


def half(depth: np.ndarray) -> torch.Tensor:
    return torch.nn.functional.avg_pool2d(torch.from_numpy(depth).float(), 2)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", default="default", help="a unet2p1d-family model.safetensors ('default': the shipped one)")
    parser.add_argument("--steps", type=int, default=4000, help="training steps of 8 fresh clips")
    parser.add_argument("--lr", type=float, default=1e-3)
    parser.add_argument("--every", type=int, default=250, help="validation every so many steps")
    parser.add_argument("--seed", type=int, default=11, help="the training clips' generator seed")
    parser.add_argument("--control", action="store_true",
                        help="the positive control: the head also sees the true (observable) depth's moments, so it can learn the planes")
    args = parser.parse_args()
    torch.manual_seed(0)
    net = load_model(DEFAULT_MODEL if args.model == "default" else args.model, device="cpu").eval()
    if not isinstance(net, UNet2p1D):
        parser.error(f"--model: expected a unet2p1d-family model (its levels are what the head reads), got {type(net).__name__}")
    net.requires_grad_(False)
    config = nrdepth.GeneratorConfig()
    val = nrdepth.generate_clips(64, seed=VALIDATION_SEED_OFFSET, config=config)  # the campaign's validation clips (seed 0)
    val_truth = half(val.depth).numpy()
    val_depth, val_feats = read(net, val, args.control)
    head = PlaneHead(val_feats.shape[1])
    start = evaluate_depth(val_depth.numpy(), val_truth)
    print(f"validation without the head: per frame {start['frame']:.4f}, from the 1st frame {start['first']:.4f}", flush=True)
    data = OnlineBatches(config, seed=args.seed, batch_size=8, target="observable")
    optimiser = torch.optim.Adam(head.parameters(), lr=args.lr)
    began, losses = time.perf_counter(), []
    for step in range(args.steps):
        video, target = data[step]
        with torch.no_grad():
            depth, feats = features(net, video, target if args.control else None)
        loss = aligned_clip_signed_loss(head(depth, feats), target)
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        losses.append(loss.item())
        if (step + 1) % args.every == 0:
            with torch.no_grad():
                s = evaluate_depth(head(val_depth, val_feats).numpy(), val_truth)
            print(f"{8 * (step + 1):7d} clips, {time.perf_counter() - began:5.0f} s: clip loss {np.mean(losses[-args.every:]):.4f}, "
                  f"validation from the 1st frame {s['first']:.4f} (per frame {s['frame']:.4f})", flush=True)
    test = nrdepth.generate_clips(128, seed=TEST_SEED, config=config)
    truth = half(test.depth).numpy()
    depth, feats = read(net, test, args.control)
    with torch.no_grad():
        with_head = head(depth, feats).numpy()
    for name, alignment in (("per frame", "frame"), ("from the 1st frame", "first")):
        a = np.array([mae_sn(p, g, alignment) for p, g in zip(depth.numpy(), truth)])
        b = np.array([mae_sn(p, g, alignment) for p, g in zip(with_head, truth)])
        d = b - a
        print(f"held-out ({len(a)} clips) {name}: without the head {a.mean():.4f}, with it {b.mean():.4f}, "
              f"paired {d.mean():+.4f} ± {d.std(ddof=1) / np.sqrt(len(d)):.4f}")


if __name__ == "__main__":
    main()
