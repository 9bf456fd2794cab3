"""LinuxCNC's ``streamer`` component as precontour feeds it: one float pin per axis, and a
FIFO deep enough to ride through pauses of the program that feeds it (``halstreamer``). Used
by the halstreamer writer (:mod:`precontour.toolpath.writers`) and the configuration's
``stream.hal`` (:mod:`.config`), which must agree."""

from __future__ import annotations

import math

__all__ = ["STREAMER_FLOAT", "STREAMER_BUFFER_SECONDS", "streamer_depth"]

#: streamer's config letter for one float pin.
STREAMER_FLOAT = "f"
#: Seconds of samples the streamer FIFO holds, to ride through pauses of the feeding program.
STREAMER_BUFFER_SECONDS = 2.0


def streamer_depth(ts: float) -> int:
    """FIFO depth (samples) that holds :data:`STREAMER_BUFFER_SECONDS` of commands."""
    return int(math.ceil(STREAMER_BUFFER_SECONDS / ts))
