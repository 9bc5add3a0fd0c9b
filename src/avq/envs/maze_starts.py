"""Where an episode of a maze starts: the one rule of both mazes (``GridMaze``, ``RobotMaze``).

``reset(options={"start": (x, y)})`` starts at that position, checked by the maze; otherwise the maze's
``start`` argument says: ``"fixed"``, at the layout's ``S``; ``"random"``, at a random start position drawn
from the maze's ``np_random`` (a free non-goal square; for ``RobotMaze`` one where its disc fits).
"""

from __future__ import annotations

from typing import Any

__all__ = ["MazeStarts"]


class MazeStarts:
    """The start rule of a maze. The maze sets ``_start_mode`` (checked by
    :func:`avq.envs.layouts.check_start`) and ``dynamics`` (whose ``fixed_start`` is the layout's ``S`` in the
    maze's coordinates, or None), and says how a start given in ``options`` is checked (``_checked_start``)
    and how a random one is drawn (``_random_start``)."""

    _start_mode: str
    dynamics: Any

    @property
    def start(self) -> str:
        """``"random"`` or ``"fixed"`` (read-only: the frozen :attr:`dynamics` hold it)."""
        return self._start_mode

    def _start_position(self, options: dict[str, Any] | None) -> tuple[Any, Any]:
        """Where the episode that ``reset(options=options)`` begins starts (after ``super().reset``, so that a
        random start is drawn from the newly seeded ``np_random``)."""
        start = None if options is None else options.get("start")
        if start is not None:
            return self._checked_start(start)
        if self.start == "fixed":
            return self.dynamics.fixed_start
        return self._random_start()

    def _checked_start(self, start: Any) -> tuple[Any, Any]:
        raise NotImplementedError

    def _random_start(self) -> tuple[Any, Any]:
        raise NotImplementedError
