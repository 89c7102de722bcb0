"""Which tracker tracks which model, from how many camera views: one table (`FITS`), checked before every run
(`experiments.checks`: a combination not in it fails with one line) and shown in the README
(`python -m experiments.options`).

A tracker that is not in the table (a plugin's, until it calls `allow`) tracks any model from any rig. A fit
may name the rig to use when the composed one has too few or too many views (``model=body_mesh`` picks the
one-camera ``rig=body_side``; ``tracker=abis`` on the body then takes ``rig=body_multi``): the command line picks
it unless it names a rig itself (`experiments.validate.with_picked_rig`).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Fit:
    """A tracker on a model: the camera views it uses (fewest, most) and the rig option it takes when the
    composed rig has another number of views (None: it asks for one)."""

    views: tuple[int, int]
    rig: str | None = None

    def allows(self, views: int) -> bool:
        return self.views[0] <= views <= self.views[1]

    @property
    def says(self) -> str:
        low, high = self.views
        return f"{low} camera view{'s' * (high > 1)}" if low == high else f"{low} to {high} camera views"


# tracker -> model -> fit
FITS: dict[str, dict[str, Fit]] = {
    "render_only": {"dsq_arm": Fit((1, 4)), "body_mesh": Fit((1, 4))},
    "abis": {"dsq_arm": Fit((1, 4))},  # paper 1: 3 orthogonal views
    "tbf": {"body_mesh": Fit((1, 4)), "dsq_arm": Fit((1, 4))},  # paper 2: one camera; more: the views multiplied
}


def allow(tracker: str, model: str, fit: Fit) -> None:
    """Add a row: ``tracker`` tracks ``model`` as ``fit`` says (a plugin's tracker states its fits this way)."""
    FITS.setdefault(tracker, {})[model] = fit


def fit_of(tracker: str, model: str) -> Fit | None:
    """How ``tracker`` tracks ``model`` (None: the tracker is not in the table, any goes). Raises ``ValueError``
    with one line when it does not track that model."""
    if tracker not in FITS:
        return None
    fits = FITS[tracker]
    if model not in fits:
        raise ValueError(f"tracker={tracker} does not track model={model}: allowed model={'|'.join(fits)}")
    return fits[model]
