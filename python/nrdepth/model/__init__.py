"""The depth networks and their I/O: the paper's 3D U-Net (:class:`UNet3D`),
a factorised (2+1)D U-Net built for a CPU's budget (:class:`UNet2p1D`,
and :class:`UNet2p1DGlobal`, which sees the whole clip in time), models
by name, on disk and at work (:mod:`nrdepth.model.io`), and weight
averages of models of one lineage (:mod:`nrdepth.model.average`)."""

from .average import average_models
from .io import ARCHITECTURES, DEFAULT_MODEL, SCALED_MODEL, architecture_name, build_model, load_model, predict_depth, resolve_device, save_model
from .unet import UNet3D, count_parameters
from .unet2p1d import UNet2p1D, UNet2p1DDeep, UNet2p1DGlobal

__all__ = [
    "ARCHITECTURES",
    "DEFAULT_MODEL",
    "SCALED_MODEL",
    "UNet2p1D",
    "UNet2p1DDeep",
    "UNet2p1DGlobal",
    "UNet3D",
    "architecture_name",
    "average_models",
    "build_model",
    "count_parameters",
    "load_model",
    "predict_depth",
    "resolve_device",
    "save_model",
]
