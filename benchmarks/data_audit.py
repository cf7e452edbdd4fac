"""Which training clips teach the network nothing? Held-out clips (the seed
``nrdepth evaluate`` uses) scored per clip and grouped by what the generator
drew for them: texture family, surface intensity (the relief's amplitude),
the lights' component along image-up (through which shading shows the
relief's sign, ``flip_anatomy.py``), the lights' mean elevation (how frontal
they are), pixel noise, specular weight, number of lights. For each group:
clips, the model's MAE-SN per frame, the flat plane's, their ratio (below 1:
the model reads shape there; near 1: the frames show it nothing it can use),
and the share of clips whose relief sign flips.

    python benchmarks/data_audit.py [--clips 256] [--model PATH]
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

import nrdepth
from flip_anatomy import up_component
from nrdepth.evaluate import TEST_SEED
from nrdepth.model import DEFAULT_MODEL, load_model, predict_depth


def elevation(lights: list) -> float:
    """Intensity-weighted mean elevation of a clip's lights in degrees (90:
    along the optical axis, frontal)."""
    z = [light["vector"][2] / np.linalg.norm(light["vector"]) for light in lights]
    return float(np.degrees(np.arcsin(np.clip(np.average(z, weights=[light["intensity"] for light in lights]), -1, 1))))


def quartile_groups(values: np.ndarray, fmt: str) -> list:
    """(label, mask) for the four quartiles of ``values``."""
    edges = np.quantile(values, [0, 0.25, 0.5, 0.75, 1])
    groups = []
    for k in range(4):
        mask = (values >= edges[k]) & ((values < edges[k + 1]) if k < 3 else (values <= edges[k + 1]))
        groups.append((f"{fmt.format(edges[k])}–{fmt.format(edges[k + 1])}", mask))
    return groups


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--clips", type=int, default=256)
    parser.add_argument("--model", default=str(DEFAULT_MODEL))
    args = parser.parse_args()
    clips = nrdepth.generate_clips(args.clips, seed=TEST_SEED)
    truth = torch.nn.functional.avg_pool2d(torch.from_numpy(clips.depth).float(), 2).numpy()
    pred = predict_depth(load_model(args.model, device="cpu"), clips.video)
    model = np.array([nrdepth.mae_sn(p, g, "frame") for p, g in zip(pred, truth)])
    flat = np.array([nrdepth.flat_baseline(g, "frame") for g in truth])
    flips = np.array([nrdepth.sign_rates(p, g)["flip"] for p, g in zip(pred, truth)])
    params = clips.params
    lights = [p["lights"] for p in params]
    factors = {
        "texture family": [(f, np.array([p["texture"]["family"] == f for p in params])) for f in sorted({p["texture"]["family"] for p in params})],
        "surface intensity": quartile_groups(np.array([p["surface"]["intensity"] for p in params]), "{:.3f}"),
        "lights' image-up component": quartile_groups(np.array([up_component(lt) for lt in lights]), "{:.2f}"),
        "lights' elevation, degrees": quartile_groups(np.array([elevation(lt) for lt in lights]), "{:.0f}"),
        "pixel noise std": quartile_groups(np.array([p["noise_std"] for p in params]), "{:.3f}"),
        "specular weight": quartile_groups(np.array([p["material"]["specular"] for p in params]), "{:.2f}"),
        "lights": [(str(n), np.array([len(lt) == n for lt in lights])) for n in sorted({len(lt) for lt in lights})],
    }
    print(f"{args.clips} held-out clips (seed {TEST_SEED}), model {args.model}: MAE-SN per frame {model.mean():.4f}, "
          f"flat plane {flat.mean():.4f}, ratio {model.mean() / flat.mean():.3f}, flips in {100 * flips.mean():.1f} % of clips")
    print(f"{'group':34s}{'clips':>6s}{'model':>9s}{'plane':>9s}{'ratio':>8s}{'flips %':>9s}")
    for factor, groups in factors.items():
        print(factor)
        for label, mask in groups:
            if mask.any():
                print(f"  {label:32s}{mask.sum():>6d}{model[mask].mean():>9.4f}{flat[mask].mean():>9.4f}"
                      f"{model[mask].mean() / flat[mask].mean():>8.3f}{100 * flips[mask].mean():>9.1f}")


if __name__ == "__main__":
    main()
