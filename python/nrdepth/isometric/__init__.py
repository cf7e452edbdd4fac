"""The large-scale shape of an inextensible sheet (paper, cloth) from its
video, and its fusion with the network's depth.

A network reads a frame's relief but little of its large-scale bend
(docs/campaign.md); a sheet that bends without stretching gives that bend
away through perspective. Three steps:

- :func:`track_grid`: points spread evenly over ``mask`` in the first frame,
  moved (:func:`track_points`) from each frame to the next by OpenCV's Farneback dense optical flow
  (sampled bilinearly at each point), forward and backward. No point is lost to a fast or
  blurred frame: the flow of its neighbourhood carries it, where a sparse
  tracker would lose it; one that leaves the frame is lost from there on
  (NaN). The share ``drop`` of the points whose two flows disagree most
  over the video is left out: points where the motion breaks (near a
  border), which the flow drags. With ``hold``, each step of the flow is
  checked against the first frame: every point is found again by its look
  there, through a smooth warp of the sheet fitted to the points held in
  the frame before (:mod:`~nrdepth.isometric.hold`), so that the flow's
  drift does not add up, and a point not found again is NaN in that
  frame, not dragged.
- :func:`mdh_depths`: the depth of every point in every frame by the
  maximum-depth heuristic of inextensible NRSfM (Chhatkuli, Pizarro,
  Collins and Bartoli, TPAMI 2018): maximise the sum of the depths subject
  to ``‖Z_i r_i − Z_j r_j‖ ≤ D_ij`` in every frame for each pair of
  neighbours in view (``r``: the point's ray, ``(x − c_x)/f_x, (y − c_y)/f_y, 1``),
  with the pairs' template distances ``D_ij`` shared by all frames and
  ``Σ D_ij`` fixed to the number of pairs (the video fixes no scale). The
  sheet is pulled as far from the camera as its inextensible threads allow,
  which makes them taut: the true shape when the video shows it bent in
  enough ways (a short or barely bending clip leaves the distances loose
  and reads as a taut dome). A second-order cone program, solved by Clarabel over
  ``keyframes`` frames spread over the video; every other frame is then
  solved alone with those ``D_ij`` fixed, in parallel threads. The program
  only bounds each pair's distance, and with the ``D_ij`` free it favours a
  dome: it lengthens the pairs in the middle of the sheet and shortens those
  at its edge. ``template="refined"`` then asks each pair's distance to
  equal ``D_ij`` in every keyframe (isometry as an equality): a
  least-squares refinement of the keyframes' depths and the ``D_ij``,
  started from the program's answer (docs/reconstruction.md).
- the main job's sheet stage (:mod:`nrdepth.reconstruct.sheet`) runs both
  with its settings, spreads the depths over each frame and fuses them:
  :func:`fuse` keeps the network's relief and takes the shape above a
  length scale from the isometric depth.

Where the points are not cut to the sheet, :func:`moving_points` and
:func:`unstrained_points` (:mod:`~nrdepth.isometric.found`) keep the
sheet's: those that move, and those whose pairs keep their lengths
without stepping far in depth; and
:func:`estimate_focal` says how sharply their strain picks a focal length.

Frames and units: pixel coordinates (column x, row y, pixel centres at
integers); depth is distance along the optical axis, growing away from the
camera, in units of the mean template distance between neighbouring points
(the scale is free: a video fixes none). Needs a perspective camera of known
intrinsics.
"""

from .focal import FocalEstimate, estimate_focal
from .found import moving_points, unstrained_points
from .fuse import fuse
from .mirror import SHAPE_KEPT, keep_lengths, mirror_depths, mirror_or_not, shape_kept
from .mdh import EACH_FRAME, TEMPLATES, NotSolved, TooFewPoints, keyframe_indices, mdh_depths, neighbour_pairs, pair_strain, template_strain
from .points import BORDER, DROP, FLOWS, bridge_gaps, frames_of, held_share, inside, least_disagreeing, PLACES, point_held_shares, start_grid, start_texture, track_grid, track_points

__all__ = ["track_grid", "bridge_gaps", "start_grid", "start_texture", "PLACES", "track_points", "least_disagreeing", "inside", "held_share", "point_held_shares", "neighbour_pairs", "mdh_depths", "pair_strain", "template_strain", "keyframe_indices", "estimate_focal", "FocalEstimate", "moving_points", "unstrained_points", "fuse", "mirror_depths", "keep_lengths", "mirror_or_not", "shape_kept", "SHAPE_KEPT",
           "frames_of", "TooFewPoints", "NotSolved", "TEMPLATES", "EACH_FRAME", "DROP", "BORDER", "FLOWS"]
