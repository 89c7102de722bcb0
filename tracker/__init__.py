"""Core of the articulated-object tracking framework.

Works on numpy arrays and plain dataclasses. Never imports hydra or rerun, and importing it needs no OpenGL context
(the renderer loads pyrender lazily). Conventions (frames, units, shapes) are stated once, in the module that owns
them: `tracker.geometry.rotations` (rotations, rigid transforms) and `tracker.geometry.cameras` (camera frame, pixels).
"""
