"""BVH motion files (Biovision hierarchy), as the CMU clips of the data directory's ``mocap/`` use them.

`read_bvh` parses the hierarchy (joint names, parents, offsets, channel order) and the motion block into one
``(frames, channels)`` float64 array; `BvhClip.global_rotations` and `BvhClip.root_positions` turn a frame range
into world rotations and root positions in the file's own frame and units (the CMU clips: Y up, facing +Z at the
T-pose of frame 0, 1 unit = 1/0.45 inch). Rotation channels are degrees, applied in the order listed, each about
the joint's parent-frame axis composed intrinsically: ``Zrotation Yrotation Xrotation`` means
``R = Rz(z) @ Ry(y) @ Rx(x)``. End sites carry no channels and are dropped.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tracker.data import data_path


class BvhError(ValueError):
    """A BVH file that cannot be read: the message names the file and what is wrong."""


_AXES = {"X": 0, "Y": 1, "Z": 2}


@dataclass(frozen=True, eq=False)
class BvhClip:
    """One BVH file. ``channels[j]`` lists joint j's channel names in file order; ``motion[:, columns[j]]`` are
    their values (positions in file units, rotations in degrees)."""

    path: Path
    names: tuple[str, ...]
    parents: np.ndarray  # (J,) index of the parent joint, -1 for the root
    offsets: np.ndarray  # (J, 3) joint position in the parent's frame at zero rotation
    channels: tuple[tuple[str, ...], ...]
    columns: tuple[np.ndarray, ...]
    frame_time: float  # seconds
    motion: np.ndarray  # (frames, channel count)

    @property
    def frames(self) -> int:
        return len(self.motion)

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise BvhError(f"{self.path}: no joint {name!r}; joints are {', '.join(self.names)}") from None

    def local_rotations(self, frames: np.ndarray | slice = slice(None)) -> np.ndarray:
        """``(n, J, 3, 3)`` each joint's rotation relative to its parent at ``frames``."""
        motion = self.motion[frames]
        rotations = np.broadcast_to(np.eye(3), (len(motion), len(self.names), 3, 3)).copy()
        for joint, (names, columns) in enumerate(zip(self.channels, self.columns, strict=True)):
            for name, column in zip(names, columns, strict=True):
                if name.endswith("rotation"):
                    rotations[:, joint] = rotations[:, joint] @ axis_rotations(_AXES[name[0]], motion[:, column])
        return rotations

    def global_rotations(self, frames: np.ndarray | slice = slice(None)) -> np.ndarray:
        """``(n, J, 3, 3)`` each joint's rotation in the file's world frame at ``frames``."""
        local = self.local_rotations(frames)
        world = np.empty_like(local)
        for joint, parent in enumerate(self.parents):  # parents come before children in a BVH file
            world[:, joint] = local[:, joint] if parent < 0 else world[:, parent] @ local[:, joint]
        return world

    def root_positions(self, frames: np.ndarray | slice = slice(None)) -> np.ndarray:
        """``(n, 3)`` the root joint's position (file units) at ``frames``: its offset plus its position channels."""
        motion = self.motion[frames]
        position = np.broadcast_to(self.offsets[0], (len(motion), 3)).copy()
        for name, column in zip(self.channels[0], self.columns[0], strict=True):
            if name.endswith("position"):
                position[:, _AXES[name[0]]] += motion[:, column]
        return position

    def joint_positions(self, frames: np.ndarray | slice = slice(None)) -> np.ndarray:
        """``(n, J, 3)`` every joint's world position (file units) at ``frames``, by forward kinematics."""
        world = self.global_rotations(frames)
        positions = np.empty((len(world), len(self.names), 3))
        positions[:, 0] = self.root_positions(frames)
        for joint, parent in enumerate(self.parents[1:], start=1):
            positions[:, joint] = positions[:, parent] + world[:, parent] @ self.offsets[joint]
        return positions


def axis_rotations(axis: int, degrees: np.ndarray) -> np.ndarray:
    """``(n, 3, 3)`` rotations by ``degrees`` about the x (0), y (1) or z (2) axis."""
    angle = np.radians(np.asarray(degrees, dtype=np.float64))
    c, s = np.cos(angle), np.sin(angle)
    rotations = np.zeros((len(angle), 3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    rotations[:, axis, axis] = 1.0
    rotations[:, i, i], rotations[:, i, j], rotations[:, j, i], rotations[:, j, j] = c, -s, s, c
    return rotations


CLIPS_KEPT = 32  # parsed clips a process keeps: checks before a run and the run itself read the same files


def read_bvh(path: str | Path) -> BvhClip:
    """Parse a BVH file (a data path: `tracker.data.data_path`); any problem raises `BvhError` naming the file and
    what is wrong. A file read before, unchanged since (its size and modification time), is not parsed again: the
    same clip, its arrays read-only."""
    path = data_path(path)
    try:
        stat = path.stat()
    except OSError as error:
        raise _unreadable(path, error) from None
    return _parsed(path, stat.st_size, stat.st_mtime_ns)


def _unreadable(path: Path, error: OSError) -> BvhError:
    return BvhError(f"cannot read BVH file {path}: {error.strerror or error}")


@functools.lru_cache(maxsize=CLIPS_KEPT)
def _parsed(path: Path, size: int, modified_ns: int) -> BvhClip:
    """The clip in ``path`` as it is with that ``size`` and ``modified_ns`` (the cache's key only)."""
    try:
        text = path.read_text()
    except OSError as error:
        raise _unreadable(path, error) from None
    except UnicodeDecodeError:
        raise BvhError(f"{path} is not a BVH file (not text)") from None
    head, _, body = text.partition("MOTION")
    if not body:
        raise BvhError(f"{path} is not a BVH file: no MOTION section")
    names, parents, offsets, channels = _parse_hierarchy(path, head.split())
    bounds = np.cumsum([0] + [len(c) for c in channels])
    columns = tuple(np.arange(start, end) for start, end in zip(bounds[:-1], bounds[1:], strict=True))
    frames, frame_time, motion = _parse_motion(path, body, int(bounds[-1]))
    if frames != len(motion):
        raise BvhError(f"{path}: header says {frames} frames, the file holds {len(motion)} (truncated?)")
    parents, offsets = np.array(parents), np.array(offsets, dtype=np.float64)
    for array in (parents, offsets, motion, *columns):
        array.flags.writeable = False  # shared by every reader of the file
    return BvhClip(path, tuple(names), parents, offsets, tuple(channels), columns, frame_time, motion)


class _Tokens:
    """The HIERARCHY section's tokens, taken in order."""

    def __init__(self, path: Path, tokens: list[str]) -> None:
        self.path, self.tokens, self.position = path, tokens, 0

    def __bool__(self) -> bool:
        return self.position < len(self.tokens)

    def take(self, count: int = 1) -> list[str]:
        if self.position + count > len(self.tokens):
            raise BvhError(f"{self.path}: the HIERARCHY section ends early")
        values = self.tokens[self.position : self.position + count]
        self.position += count
        return values


_CHANNEL_NAMES = {f"{axis}{kind}" for axis in "XYZ" for kind in ("position", "rotation")}


def _parse_hierarchy(path: Path, tokens: list[str]):
    names: list[str] = []
    parents: list[int] = []
    offsets: list[list[float]] = []
    channels: list[tuple[str, ...]] = []
    stack: list[int | None] = []  # the open blocks: joint index, or None for an end site
    pending: int | None = None
    if not tokens or tokens[0] != "HIERARCHY":
        raise BvhError(f"{path} is not a BVH file: it does not start with HIERARCHY")
    stream = _Tokens(path, tokens[1:])
    while stream:
        token = stream.take()[0]
        if token in ("ROOT", "JOINT"):
            if token == "ROOT" and names:
                raise BvhError(f"{path}: more than one ROOT")
            parents.append(next((joint for joint in reversed(stack) if joint is not None), -1))
            names.append(stream.take()[0])
            offsets.append([0.0, 0.0, 0.0])
            channels.append(())
            pending = len(names) - 1
        elif token == "End":
            stream.take()  # "Site"
            pending = None
        elif token == "{":
            stack.append(pending)
        elif token == "}":
            if not stack:
                raise BvhError(f"{path}: unbalanced braces in HIERARCHY")
            stack.pop()
        elif token == "OFFSET":
            values = _floats(path, stream.take(3), "OFFSET")
            if stack and stack[-1] is not None:
                offsets[stack[-1]] = values
        elif token == "CHANNELS":
            names_ = tuple(stream.take(_int(path, stream.take()[0], "CHANNELS count")))
            if set(names_) - _CHANNEL_NAMES or not stack or stack[-1] is None:
                raise BvhError(f"{path}: bad CHANNELS {' '.join(names_)}")
            channels[stack[-1]] = names_
        else:
            raise BvhError(f"{path}: unexpected {token!r} in HIERARCHY")
    if not names or stack:
        raise BvhError(f"{path}: the HIERARCHY section is incomplete")
    return names, parents, offsets, channels


def _parse_motion(path: Path, body: str, width: int) -> tuple[int, float, np.ndarray]:
    lines = body.strip().splitlines()
    if len(lines) < 2 or not lines[0].startswith("Frames:") or not lines[1].startswith("Frame Time:"):
        raise BvhError(f"{path}: the MOTION section must start with 'Frames:' and 'Frame Time:'")
    frames = _int(path, lines[0].split(":", 1)[1].strip(), "Frames")
    frame_time = _floats(path, [lines[1].split(":", 1)[1].strip()], "Frame Time")[0]
    if not (frame_time > 0 and math.isfinite(frame_time)):
        raise BvhError(f"{path}: Frame Time must be a positive number, got {frame_time}")
    motion = _number_table(lines[2:], width)
    if motion is None:  # not a table of numbers `width` wide: say what is wrong
        motion = _checked_table(path, lines[2:], width, frames)
    if not np.isfinite(motion).all():
        raise BvhError(f"{path}: the MOTION section holds NaN or infinite values")
    return frames, frame_time, motion


def _number_table(lines: list[str], width: int) -> np.ndarray | None:
    """The lines' whitespace-separated numbers as ``(rows, width)`` (blank lines skipped), parsed by NumPy's reader
    (correctly rounded, as Python's ``float``); None when they are not such a table."""
    if not lines:  # (NumPy's reader would warn)
        return None
    try:
        table = np.loadtxt(lines, dtype=np.float64, comments=None, ndmin=2)
    except ValueError:
        return None
    return table if table.shape[1:] == (width,) and len(table) else None


def _checked_table(path: Path, lines: list[str], width: int, frames: int) -> np.ndarray:
    """The MOTION lines' numbers, or `BvhError` saying what is wrong with them."""
    rows = [line.split() for line in lines if line.strip()]
    if len(rows) > 1 and len(rows[-1]) < width and all(len(row) == width for row in rows[:-1]):
        raise BvhError(
            f"{path}: the file ends inside frame {len(rows) - 1} ({len(rows[-1])} of {width} values; "
            f"the header says {frames} frames): truncated?"
        )
    lengths = sorted({len(row) for row in rows})
    if any(length != width for length in lengths):
        raise BvhError(f"{path}: every MOTION line must hold {width} values, found lines of {lengths}")
    try:
        return np.array(rows, dtype=np.float64).reshape(len(rows), width)
    except ValueError:
        raise BvhError(f"{path}: a MOTION line holds something that is not a number") from None


def _floats(path: Path, values: list[str], what: str) -> list[float]:
    try:
        return [float(value) for value in values]
    except ValueError:
        raise BvhError(f"{path}: {what} must be numbers, got {' '.join(values)}") from None


def _int(path: Path, value: str, what: str) -> int:
    try:
        return int(value)
    except ValueError:
        raise BvhError(f"{path}: {what} must be an integer, got {value!r}") from None
