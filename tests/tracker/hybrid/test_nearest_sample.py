"""The hybrid's nearest sample (the feed's target) against every distance measured (brute force)."""

import numpy as np

from tracker.hybrid.tracker import NearestSample
from tracker.models.body_skeleton import POSE_SIZE


def brute_force(poses: np.ndarray, pose: np.ndarray) -> int:
    return int(np.argmin(((poses[:, 3:] - pose[3:]) ** 2).sum(axis=1)))  # of equal distances, the first


def test_the_nearest_sample_is_the_brute_force_ones():
    """Samples spread over a few directions (as postures are), and queries near them, far and among them; equal
    samples (a dictionary's mirrored copies can repeat a posture) give the first."""
    rng = np.random.default_rng(3)
    spread = rng.normal(size=(6, POSE_SIZE - 3)) * np.linspace(1.0, 0.2, 6)[:, None]
    poses = np.zeros((3000, POSE_SIZE))
    poses[:, 3:] = rng.normal(size=(3000, 6)) @ spread + rng.normal(0, 0.05, (3000, POSE_SIZE - 3))
    poses[2500:2600] = poses[100:200]  # repeats, later than their first
    poses[:, :3] = rng.normal(size=(3000, 3))  # the roots' positions are not compared
    search = NearestSample(poses)
    queries = [poses[k] + rng.normal(0, scale, POSE_SIZE) for k in range(0, 3000, 97) for scale in (0.0, 0.01, 0.3)]
    queries += [rng.normal(0, 3.0, POSE_SIZE) for _ in range(20)]
    for query in queries:
        assert search(query) == brute_force(poses, query)
    assert search(poses[2550]) == 150


def test_one_sample():
    poses = np.random.default_rng(4).normal(size=(1, POSE_SIZE))
    assert NearestSample(poses)(np.zeros(POSE_SIZE)) == 0
