"""The recordings' video format, both ways: a view's RGB frames as one AV1 video in MP4 (PyAV's bundled SVT-AV1), a
run's images at a fraction of the bytes of per-frame JPEGs (about 0.3 KB a frame at 320x240 instead of 12), decoded
natively by Rerun's viewer. The run's recording writes it (`VideoEncoder`); the readers of recordings take it back
(`decode`, `eval.recordings`).

Every frame of the run is encoded in order, its presentation time its frame index; `decode` gives them back.
"""

from __future__ import annotations

import io
import os

import av
import numpy as np

CODEC = "libsvtav1"
FRAME_RATE = 30  # of the file only: Rerun shows each frame at its own index on the ``frame`` timeline
# BT.709, limited range, stated in the stream and used both ways: RGB -> YUV 4:2:0 -> RGB loses ~1.3 levels on
# average (mismatched matrices lose 2 and shift dark colours).
COLORSPACE, COLOR_RANGE = 1, 1
# SVT-AV1 prints 24 lines of configuration for every encoder it opens; errors only, unless the user set SVT_LOG.
SVT_LOG_ERRORS = "1"


class VideoEncoder:
    """Encodes ``(h, w, 3)`` uint8 RGB frames one by one; `finish` gives the MP4 file's bytes."""

    def __init__(self, width: int, height: int, quality: int) -> None:
        if width % 2 or height % 2:
            raise ValueError(f"video frames need even sides, got {width}x{height}")
        os.environ.setdefault("SVT_LOG", SVT_LOG_ERRORS)  # read by the encoder when it opens
        self._buffer = io.BytesIO()
        self._container = av.open(self._buffer, "w", format="mp4")
        # preset 12: the fastest (0.8 ms a 320x240 frame); crf: constant quality, lower is better (0-63).
        self._stream = self._container.add_stream(CODEC, rate=FRAME_RATE, options={"preset": "12", "crf": str(quality)})
        self._stream.width, self._stream.height, self._stream.pix_fmt = width, height, "yuv420p"
        self._stream.codec_context.colorspace, self._stream.codec_context.color_range = COLORSPACE, COLOR_RANGE
        self.frames = 0

    def add(self, rgb: np.ndarray) -> None:
        frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(rgb), format="rgb24").reformat(
            format="yuv420p", dst_colorspace=COLORSPACE, dst_color_range=COLOR_RANGE
        )
        frame.pts = self.frames
        self._container.mux(self._stream.encode(frame))
        self.frames += 1

    def finish(self) -> bytes:
        self._container.mux(self._stream.encode())
        self._container.close()
        return self._buffer.getvalue()


def decode(video: bytes) -> list[np.ndarray]:
    """Every frame of an MP4 file's first video stream, in presentation order, as ``(h, w, 3)`` uint8 RGB."""
    with av.open(io.BytesIO(video)) as container:
        frames = sorted(container.decode(video=0), key=lambda frame: frame.pts)
        return [
            frame.reformat(format="rgb24", src_colorspace=COLORSPACE, src_color_range=COLOR_RANGE).to_ndarray()
            for frame in frames
        ]
