"""Truth motion: procedural generators (and, for the body, motion capture)."""
