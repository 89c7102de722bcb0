"""Named numerical tolerances, each with its reason. Import these; do not write bare epsilons elsewhere."""

# |cos| or |sin| below this is snapped to exactly 0 in the superquadric signed powers, so the pole rings and the
# omega = -pi / pi seam of a DSQ mesh coincide bit for bit (cos(pi/2) is 6e-17 in float64, not 0).
TRIG_SNAP = 1e-12

# Orthonormality of a rotation matrix built by us (products of a few float64 rotations drift by ~1e-15).
ROTATION_ORTHONORMAL = 1e-9

# A point must be at least this far in front of a camera (metres, camera z) to be projected.
MIN_DEPTH_M = 1e-6

# A model sample is visible in a view when the z-buffer at its pixel shows its own part no more than this far in
# front of it (metres). Rounding the sample to a pixel centre and the render mesh's flat facets shift depth by up
# to ~1 cm at grazing angles on our 320x240 views; the far side of the thinnest arm part is 7 cm behind its front.
VISIBILITY_DEPTH_M = 0.02
