"""``attica view``: the attitude, the node and the bus on a local web page (docs/view.md).

One process serves the page (plain JavaScript and Canvas 2D, shipped in this package: no CDN, nothing
fetched) and feeds it from any source the CAN tools read:

- :mod:`attica.view.sources` (a live python-can bus), :mod:`attica.view.playback` (a log played back:
  pause, seek, speed) and :mod:`attica.view.demo` (the simulator or a recording through the C node on a
  bus, ``attica view --demo``);
- :mod:`attica.view.state`: every frame checked and counted by ``attica monitor``'s
  :class:`~attica.can.monitor.Monitor`, the latest output set, DIAG and IMU sample kept and decoded at
  display rate;
- :mod:`attica.view.server`: the page and its WebSocket (the ``websockets`` library), updates at display
  rate, latest wins;
- :mod:`attica.view.foxglove`: the optional Foxglove live bridge (``foxglove-sdk``).

Needs the ``view`` extra (``pip install 'attica[view]'``; the Foxglove bridge ``attica[foxglove]``).
"""

from __future__ import annotations

from attica.view.demo import ImuSource
from attica.view.playback import LogSource
from attica.view.sources import BusSource, Source, SourceError
from attica.view.state import ViewState

__all__ = ["BusSource", "ImuSource", "LogSource", "Source", "SourceError", "ViewServer", "ViewState"]


def __getattr__(name: str) -> object:
    if name == "ViewServer":  # needs the websockets package (the view extra): imported on use
        from attica.view.server import ViewServer

        return ViewServer
    raise AttributeError(name)
