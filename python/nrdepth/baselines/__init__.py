"""The baselines nrdepth is compared with: NRSfM (CSF2, KSTA; :mod:`.nrsfm`)
on point tracks (:mod:`.tracks`: true tracks of a generated clip, or
followed by optical flow, and their depths spread over the frame)."""
