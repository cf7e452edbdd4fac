"""Weight averages of models (nrdepth.model.average_models, nrdepth average)."""

import json

import pytest
import torch

from nrdepth.cli import main
from nrdepth.model import UNet2p1D, UNet2p1DDeep, UNet2p1DGlobal, average_models, load_model, save_model


def small(cls=UNet2p1D, seed=0, **config):
    torch.manual_seed(seed)
    model = cls(width=4, stem_width=2, **config).eval()
    for name, p in model.named_parameters():
        if name.endswith("temporal.weight") or ".fuse." in name:  # the zero-start layers too, so that they matter
            torch.nn.init.normal_(p, std=0.2)
    return model


def depth(model, seed=1):
    video = torch.rand((2, 1, 16, 32, 32), generator=torch.Generator().manual_seed(seed))
    with torch.inference_mode():
        return model(video)


def test_an_average_is_the_weighted_mean_of_the_weights():
    a, b = small(seed=0), small(seed=1)
    mixed = average_models([a, b], [3, 1]).state_dict()
    for key, value in a.state_dict().items():
        torch.testing.assert_close(mixed[key], 0.75 * value + 0.25 * b.state_dict()[key], rtol=1e-6, atol=1e-7)
    assert torch.equal(depth(average_models([a, b], [1, 0])), depth(a))
    halves = average_models([a, b]).state_dict()
    torch.testing.assert_close(halves["head.weight"], (a.head.weight + b.head.weight) / 2)
    assert not torch.allclose(depth(average_models([a, b])), depth(a), atol=1e-3)


def test_a_smaller_architecture_enters_as_the_same_function():
    """``unet2p1d`` beside ``unet2p1d_deep``: with all the weight on either
    the average computes that model; in between, the added blocks keep the
    deep model's spatial convolutions and take its share of their temporal
    ones (the plain model holds zero there), whatever the order."""
    plain, deep = small(seed=0), small(UNet2p1DDeep, seed=1, coarse_blocks=2)
    assert type(average_models([plain, deep], [1, 0])) is UNet2p1DDeep
    torch.testing.assert_close(depth(average_models([plain, deep], [1, 0])), depth(plain), rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(depth(average_models([plain, deep], [0, 1])), depth(deep), rtol=1e-5, atol=1e-6)
    mixed = average_models([deep, plain], [1, 3]).state_dict()
    theirs, mine = deep.state_dict(), plain.state_dict()
    for key, value in theirs.items():
        if key in mine:
            want = 0.25 * value + 0.75 * mine[key]
        elif ".temporal." in key:
            want = 0.25 * value
        else:
            want = value
        torch.testing.assert_close(mixed[key], want, rtol=1e-6, atol=1e-7, msg=key)
    assert torch.allclose(mixed["level3.4.spatial.weight"], theirs["level3.4.spatial.weight"])


def test_averages_refuse_models_of_other_lineages_and_bad_weights():
    plain = small()
    with pytest.raises(ValueError, match=r"^models\[1\]: its weights are not those"):
        average_models([plain, UNet2p1D(width=8, stem_width=2)])
    with pytest.raises(ValueError, match=r"^models\[1\]: it does not compute the same function"):
        average_models([plain, small(seed=1, rates=(1, 3, 5))])  # the same shapes, other dilations
    with pytest.raises(ValueError, match=r"^models\[1\]: its weights are not those"):
        average_models([small(UNet2p1DGlobal), small(UNet2p1DDeep, coarse_blocks=1)])
    scaled = small(seed=1)
    scaled.depth_units = "window"
    with pytest.raises(ValueError, match="^models: expected one depth_units"):
        average_models([plain, scaled])
    with pytest.raises(ValueError, match=r"^models\[1\]: .*not found"):
        average_models([plain, "no-such-model.safetensors"])
    with pytest.raises(TypeError, match=r"^models\[1\]"):
        average_models([plain, 3])
    for bad in ([plain], plain, "model.safetensors"):
        with pytest.raises(ValueError, match="^models:"):
            average_models(bad)
    for bad in ([1], [1, -1], [0, 0], [1, float("nan")], [True, 1], "12"):
        with pytest.raises(ValueError, match="^weights:"):
            average_models([plain, small(seed=1)], bad)


def test_cli_average_writes_the_model_and_its_recipe(tmp_path, capsys):
    a, b = tmp_path / "a.safetensors", tmp_path / "b" / "model.safetensors"
    b.parent.mkdir()
    save_model(small(seed=0), a)
    save_model(small(UNet2p1DDeep, seed=1, coarse_blocks=1), b)
    assert main(["average", str(tmp_path / "soup"), str(a), str(b.parent), "--weights", "3,1"]) == 0
    assert "0.75 × " in capsys.readouterr().out
    written = load_model(tmp_path / "soup")
    want = average_models([a, b.parent], [0.75, 0.25])
    assert all(torch.equal(v, want.state_dict()[k]) for k, v in written.state_dict().items())
    meta = json.loads((tmp_path / "soup" / "model.json").read_text())
    assert meta["architecture"] == "unet2p1d_deep" and meta["average"] == {"models": [str(a), str(b.parent)], "weights": [0.75, 0.25]}
    before = (tmp_path / "soup" / "model.safetensors").read_bytes()
    assert main(["average", str(tmp_path / "soup"), str(a), str(b.parent)]) == 2
    assert "exists; --overwrite" in capsys.readouterr().err
    assert (tmp_path / "soup" / "model.safetensors").read_bytes() == before
    assert main(["average", str(tmp_path / "soup"), str(a), str(b.parent), "--overwrite"]) == 0
    assert (tmp_path / "soup" / "model.safetensors").read_bytes() != before
