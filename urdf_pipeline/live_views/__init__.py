"""Live views: one config drives a live view of a robot, from a control loop (`LiveView.push`) or from a robot's
stream (a Foxglove WebSocket server, an MCAP file being written), with the checks a run makes.

The names below are the package's public surface; other packages import them from here, never from its modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..package import lazy_surface

if TYPE_CHECKING:  # the package's public surface, the one list (lazy_surface reads it)
    from .foxglove_feed import FoxgloveFeed
    from .joint_state import JOINT_STATE, Feed, JointStateDecoder, JointStateSample
    from .live_run import Latencies, LiveOptions, LiveSummary, live_command, live_recording, open_feed
    from .live_view import LiveView, TimeKind
    from .mcap_follow import McapFollowFeed

if not TYPE_CHECKING:  # the names above, imported when first used
    __all__, __getattr__ = lazy_surface(__name__, __file__)
