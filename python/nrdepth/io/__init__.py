"""Input and output: videos read in (:mod:`.decode`), the depth's colours
(:mod:`.colours`), the files of a depth video (:mod:`.writers`), a
reconstruction's folder written all or nothing (:mod:`.folder`), its 3-D
page (:mod:`.viewer`) and labelled pictures (:mod:`.figures`)."""

from .colours import colorize_depth, colormap, depth_range
from .decode import IMAGE_SUFFIXES, Video, VideoSource, iter_npz_frames, npz_header, open_video, read_left_half, read_video, select, to_gray
from .folder import ReconstructionWriter, check_complete, check_output_folder, save_reconstruction
from .viewer import ViewerFrames, view, write_page
from .writers import PLY_RELIEF, Mp4Writer, write_depth_png16, write_mp4, write_ply

__all__ = [
    "colorize_depth", "colormap", "depth_range",
    "IMAGE_SUFFIXES", "Video", "VideoSource", "iter_npz_frames", "npz_header", "open_video", "read_left_half", "read_video", "select", "to_gray",
    "ReconstructionWriter", "check_complete", "check_output_folder", "save_reconstruction",
    "ViewerFrames", "view", "write_page",
    "PLY_RELIEF", "Mp4Writer", "write_depth_png16", "write_mp4", "write_ply",
]
