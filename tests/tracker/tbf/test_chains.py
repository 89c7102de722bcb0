import numpy as np

from tracker.tbf.chains import BestChain


def naive_best_chain(joints, frames, step_m):
    """Viterbi's forward pass written out: every chain's score, link by link, in Python loops."""
    aligned = joints - joints[:, :1]
    scores = {}
    estimates = []
    for candidates, log_likelihood in frames:
        new = {}
        for c, own in zip(candidates, log_likelihood, strict=True):
            links = [
                score - ((aligned[last] - aligned[c]) ** 2).sum(axis=1).mean() / (2 * step_m**2)
                for last, score in scores.items()
            ]
            new[int(c)] = own + (max(links) if links else 0.0)
        scores = new
        estimates.append(max(scores, key=lambda c: (scores[c], -c)))
    return estimates


def test_the_best_chain_is_viterbis_forward_pass_written_out():
    rng = np.random.default_rng(3)
    joints = rng.normal(0.0, 0.3, (40, 6, 3))
    frames = [(rng.choice(40, size=size, replace=False), rng.normal(0.0, 3.0, size)) for size in (5, 7, 1, 6, 9, 4, 8)]
    chain = BestChain(joints, step_m=0.2)
    assert [chain.step(*frame) for frame in frames] == naive_best_chain(joints, frames, 0.2)
    assert chain.scores.max() == 0.0 and len(chain.scores) == len(frames[-1][0])


def test_a_chain_keeps_its_pose_against_one_frames_doubt_and_follows_a_lasting_change():
    """Two poses 0.5 m apart (a pose and its flip, say): the other one a little more likely for a frame does not move
    the chain; much more likely for good, it does."""
    joints = np.zeros((2, 4, 3))
    joints[1, 1:, 0] = 0.5  # every joint but the root 0.5 m along x: mean squared distance 0.1875 m^2
    both = np.array([0, 1])
    chain = BestChain(joints, step_m=0.08)
    assert chain.step(both, np.array([0.0, -5.0])) == 0
    assert [chain.step(both, np.array([-1.0, 0.0])) for _ in range(3)] == [0, 0, 0]
    link = 0.1875 / (2 * 0.08**2)  # 14.6 nats: the cost of the jump
    assert [chain.step(both, np.array([-2 * link, 0.0])) for _ in range(2)] == [1, 1]


def test_around_the_best_are_the_candidates_within_the_radius_weighted_by_their_chains_probability():
    rng = np.random.default_rng(8)
    joints = rng.normal(0.0, 0.2, (30, 5, 3))
    chain = BestChain(joints, step_m=0.1)
    for candidates in (np.arange(0, 12), np.arange(6, 30)):
        chain.step(candidates, rng.normal(0.0, 2.0, len(candidates)))
    best = chain.candidates[np.argmax(chain.scores)]
    aligned = joints - joints[:, :1]
    rms = {int(c): np.sqrt(((aligned[c] - aligned[best]) ** 2).sum(axis=1).mean()) for c in chain.candidates}
    radius = float(np.median(list(rms.values())))
    near, weights = chain.around_best(radius)
    assert sorted(near.tolist()) == sorted(c for c, d in rms.items() if d <= radius) and best in near
    score = dict(zip(chain.candidates.tolist(), chain.scores, strict=True))
    np.testing.assert_allclose(weights, [np.exp(score[c]) for c in near.tolist()], rtol=1e-12)
    assert weights[near.tolist().index(best)] == 1.0
