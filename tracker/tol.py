"""Named numerical tolerances, each with its reason. Import these; do not write bare epsilons elsewhere."""

# |cos| or |sin| below this is snapped to exactly 0 in the superquadric signed powers, so the pole rings and the
# omega = -pi / pi seam of a DSQ mesh coincide bit for bit (cos(pi/2) is 6e-17 in float64, not 0).
TRIG_SNAP = 1e-12

# A point must be at least this far in front of a camera (metres, camera z) to be projected.
MIN_DEPTH_M = 1e-6

# A model sample is visible in a view when the z-buffer at its pixel shows its own part no more than this far in
# front of it (metres). Rounding the sample to a pixel centre and the render mesh's flat facets shift depth by up
# to ~1 cm at grazing angles on our 320x240 views; the far side of the thinnest arm part is 7 cm behind its front.
VISIBILITY_DEPTH_M = 0.02

# Added to keep a logarithm finite (log 0 is -inf) or to break a sign's tie at 0: far below any probability or
# quantity that matters, far above float64's smallest normal number (2.2e-308).
TINY = 1e-300

# Frame 0's prior is cut to 0 below this fraction of its peak (a Gaussian's tails: about 7.4 sigma).
NEGLIGIBLE_PRIOR = 1e-12

# A length (or norm, or angle in radians) below this counts as zero: float64 noise on quantities of order 1 is
# ~1e-16, and the smallest real ones here (sub-micrometre, micro-radian) are far above it.
ZERO_LENGTH = 1e-12

# Rotation conversions switch to their series expansions below these angles (radians): the exact formulas divide
# by sin(angle) or angle**2, which lose all precision there (the series' next terms are ~angle**4, negligible).
SERIES_ANGLE_RAD = 1e-8  # exponential map: 1 - a^2/6, 1/2 - a^2/24
LOG_MAP_ANGLE_RAD = 1e-6  # logarithm map near 0 (first order) and near pi (axis from the symmetric part)

# A count computed from a float product this close below a whole number is that number (0.1 * 30 = 2.9999...).
COUNT_ROUNDING = 1e-9

# A recording writes a mesh that moved as a rigid transform of its last vertices when no vertex lands farther than
# this from where it is (metres): below the positions' own float32 rounding (~1e-7 m at 2 m from the origin).
RIGID_MESH_M = 1e-7
