"""The built-in components: importing this module registers every one of them (`tracker.registry`).

A user's components register the same way in their own module (``plugins=[my.module]`` imports it for a run).
"""

from tracker import protocol  # noqa: F401  (render_only)
from tracker.abis import tracker as abis_tracker  # noqa: F401
from tracker.evaluation import arm, body  # noqa: F401  (each model's evaluation)
from tracker.geometry import rigs  # noqa: F401
from tracker.hybrid import tracker as hybrid_tracker  # noqa: F401
from tracker.models import dsq_arm, makehuman  # noqa: F401
from tracker.motion import arm_sweep, mocap, scenes  # noqa: F401
from tracker.tbf import costs, motion  # noqa: F401
from tracker.tbf import tracker as tbf_tracker  # noqa: F401
