"""Paper 1's Analysis-by-Image-Synthesis tracker: visibility, correspondences, per-part fitting."""
