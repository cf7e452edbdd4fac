"""The depth network (3D U-Net with atrous context modules) and its parts."""

from .unet import UNet3D, count_parameters

__all__ = ["UNet3D", "count_parameters"]
