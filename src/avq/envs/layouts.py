"""Maze layouts: the presets, parsing and validation, and shortest-path distances.

A layout is a list of equally long strings: ``#`` wall, ``.`` free, ``S`` start,
``G`` goal. Coordinates are ``(x, y)`` with ``x`` the column and ``y`` the row,
both from 0 at the top-left corner (docs/explanation/paper.md#the-maze).
"""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypeAlias

import numpy as np

__all__ = [
    "MAPS",
    "Layout",
    "LayoutSpec",
    "parse_layout",
    "load_layout",
    "layout_text",
    "layout_image",
    "COLOURS",
    "check_start",
    "random_layout",
    "refine_layout",
]

#: Colours of the maze renderings (RGB).
COLOURS = {
    "wall": (40, 40, 40),
    "free": (235, 235, 235),
    "goal": (60, 170, 75),
    "start": (160, 190, 230),
    "robot": (200, 50, 50),
}

#: Preset layouts. ``lau2002`` reconstructs the paper's maze (docs/explanation/paper.md#the-maze).
MAPS: dict[str, list[str]] = {
    "lau2002": [
        "##############",
        "#S...........#",
        "#............#",
        "#..#######...#",
        "#........#...#",
        "#........#.#.#",
        "#..#.....#.#.#",
        "#..#.....#.#G#",
        "#..#.....###.#",
        "#..#.........#",
        "#..#.........#",
        "##############",
    ],
    "open5": [
        "S....",
        ".....",
        ".....",
        ".....",
        "....G",
    ],
    "corridor": [
        "#######",
        "#S...G#",
        "#######",
    ],
}

LayoutSpec: TypeAlias = str | os.PathLike | Sequence[str]

_ALLOWED = set("#.SG")

# Action index -> (dx, dy): North, East, South, West (y grows downwards).
MOVES = np.array([[0, -1], [1, 0], [0, 1], [-1, 0]], dtype=np.int64)


@dataclass(frozen=True)
class Layout:
    """A parsed, validated maze layout.

    Attributes:
        name: Preset name, file path, or ``"<custom>"``.
        rows: The layout's rows as given.
        walls: Boolean array ``(height, width)``, True on a wall.
        start: The ``S`` position ``(x, y)``, or None when the layout has none.
        goal: The ``G`` position ``(x, y)``.
        distances: Shortest-path steps to the goal ``(height, width)``; -1 on walls.
    """

    name: str
    rows: tuple[str, ...]
    walls: np.ndarray
    start: tuple[int, int] | None
    goal: tuple[int, int]
    distances: np.ndarray = field(repr=False)

    @property
    def height(self) -> int:
        return self.walls.shape[0]

    @property
    def width(self) -> int:
        return self.walls.shape[1]

    @property
    def n_states(self) -> int:
        """Number of free positions, goal included."""
        return int((~self.walls).sum())

    def free_positions(self, include_goal: bool = False) -> np.ndarray:
        """Free positions as an ``(k, 2)`` int array of ``(x, y)``, row-major order."""
        ys, xs = np.nonzero(~self.walls)
        pos = np.stack([xs, ys], axis=1).astype(np.int64)
        if not include_goal:
            pos = pos[~((pos[:, 0] == self.goal[0]) & (pos[:, 1] == self.goal[1]))]
        return pos

    def is_free(self, x: int, y: int) -> bool:
        return 0 <= x < self.width and 0 <= y < self.height and not self.walls[y, x]


def _bfs(walls: np.ndarray, goal: tuple[int, int]) -> np.ndarray:
    h, w = walls.shape
    dist = np.full((h, w), -1, dtype=np.int64)
    gx, gy = goal
    dist[gy, gx] = 0
    queue = deque([(gx, gy)])
    while queue:
        x, y = queue.popleft()
        for dx, dy in MOVES:
            nx, ny = x + int(dx), y + int(dy)
            if 0 <= nx < w and 0 <= ny < h and not walls[ny, nx] and dist[ny, nx] < 0:
                dist[ny, nx] = dist[y, x] + 1
                queue.append((nx, ny))
    return dist


def parse_layout(rows: Sequence[str], name: str = "<custom>") -> Layout:
    """Validate a list of strings and return a :class:`Layout`.

    Raises:
        ValueError: naming the problem and where it is (row, column).
    """
    if isinstance(rows, str):
        rows = rows.splitlines()
    rows = [r.rstrip("\r\n") for r in rows]
    while rows and not rows[-1].strip():
        rows.pop()
    while rows and not rows[0].strip():
        rows.pop(0)
    if not rows or not any(r for r in rows):
        raise ValueError(f"layout {name}: the layout is empty; give rows of '#', '.', 'S', 'G'")
    width = len(rows[0])
    for y, row in enumerate(rows):
        if len(row) != width:
            raise ValueError(
                f"layout {name}: row {y} has {len(row)} characters but row 0 has {width}; "
                "all rows must have the same length"
            )
        for x, ch in enumerate(row):
            if ch not in _ALLOWED:
                raise ValueError(
                    f"layout {name}: unknown character {ch!r} at x={x}, y={y}; "
                    "use '#' wall, '.' free, 'S' start, 'G' goal"
                )
    cells = np.array([list(r) for r in rows])
    walls = cells == "#"
    goals = [(int(x), int(y)) for y, x in zip(*np.nonzero(cells == "G"))]
    starts = [(int(x), int(y)) for y, x in zip(*np.nonzero(cells == "S"))]
    if not goals:
        raise ValueError(f"layout {name}: no goal; mark exactly one position with 'G'")
    if len(goals) > 1:
        raise ValueError(f"layout {name}: {len(goals)} goals at {goals}; mark exactly one 'G'")
    if len(starts) > 1:
        raise ValueError(f"layout {name}: {len(starts)} starts at {starts}; mark at most one 'S'")
    goal = goals[0]
    if int((~walls).sum()) < 2:
        raise ValueError(f"layout {name}: the goal is the only free position; add free positions to start from")
    dist = _bfs(walls, goal)
    cut_off = [(int(x), int(y)) for y, x in zip(*np.nonzero((~walls) & (dist < 0)))]
    if cut_off:
        shown = ", ".join(f"({x}, {y})" for x, y in cut_off[:5])
        more = f" and {len(cut_off) - 5} more" if len(cut_off) > 5 else ""
        raise ValueError(
            f"layout {name}: free positions cannot reach the goal: {shown}{more}; wall them off or open a path"
        )
    return Layout(
        name=name,
        rows=tuple(rows),
        walls=walls,
        start=starts[0] if starts else None,
        goal=goal,
        distances=dist,
    )


def load_layout(layout: LayoutSpec) -> Layout:
    """Resolve a preset name, a file path, a multi-line string or a list of rows."""
    if isinstance(layout, Layout):
        return layout
    if isinstance(layout, (str, os.PathLike)):
        text = os.fspath(layout)
        if text in MAPS:
            return parse_layout(MAPS[text], name=text)
        if "\n" in text:
            return parse_layout(text.splitlines())
        path = Path(text)
        if path.is_file():
            try:
                content = path.read_text(encoding="utf-8")
            except (OSError, UnicodeDecodeError) as exc:
                raise ValueError(f"layout {text}: cannot read the file ({exc})") from None
            return parse_layout(content.splitlines(), name=text)
        raise ValueError(f"layout {text!r} is neither a preset ({', '.join(sorted(MAPS))}) nor a readable file")
    try:
        rows = [str(r) for r in layout]
    except TypeError:
        raise ValueError(
            f"layout must be a preset name, a file path or a list of strings, not {type(layout).__name__}"
        ) from None
    return parse_layout(rows)


def layout_text(layout: Layout, robot: tuple[int, int]) -> str:
    """The layout as text with the robot's square marked ``R`` (and ``S`` shown as free)."""
    grid = [list(r.replace("S", ".")) for r in layout.rows]
    x, y = robot
    grid[y][x] = "R"
    return "\n".join("".join(r) for r in grid) + "\n"


def layout_image(layout: Layout, scale: int) -> np.ndarray:
    """The layout as an RGB image, ``scale`` pixels a square: walls dark, free light, goal green."""
    img = np.empty((layout.height, layout.width, 3), dtype=np.uint8)
    img[:] = COLOURS["free"]
    img[layout.walls] = COLOURS["wall"]
    gx, gy = layout.goal
    img[gy, gx] = COLOURS["goal"]
    return np.repeat(np.repeat(img, scale, axis=0), scale, axis=1)


def check_start(layout: Layout, start: str) -> None:
    """A maze's ``start`` argument: ``"random"``, or ``"fixed"`` when the layout has an ``S``."""
    if start not in ("random", "fixed"):
        raise ValueError(f"start must be 'random' or 'fixed', not {start!r}")
    if start == "fixed" and layout.start is None:
        raise ValueError(
            f"layout {layout.name}: start='fixed' needs an 'S' in the layout; add one or use start='random'"
        )


def random_layout(
    width: int, height: int, wall_density: float = 0.25, seed: int | None = 0, max_segment: int | None = None
) -> list[str]:
    """A random maze of ``width`` x ``height`` squares (border included), seeded and reproducible.

    Wall segments of random length (1 to ``max_segment`` squares, default a
    quarter of the larger side) and direction are dropped at random places inside
    the border. A segment is kept only if the free squares stay connected, so
    every free square has a path to the goal. Segments are added until
    ``wall_density`` of the inner squares are walls, or until many tries in a row
    fail (then the density reached is a little below the target). The goal is a
    random free square. Returns the rows (``#`` wall, ``.`` free, ``G`` goal), ready
    for ``gymnasium.make("avq/GridMaze-v0", layout=...)`` or RobotMaze.
    """
    from scipy.ndimage import label

    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 3:
            raise ValueError(f"{name} must be an integer >= 3 (the border takes two squares), not {value!r}")
    if isinstance(wall_density, bool) or not isinstance(wall_density, (int, float)) or not 0.0 <= wall_density <= 0.6:
        raise ValueError(f"wall_density must be a number in [0, 0.6], not {wall_density!r}")
    rng = np.random.default_rng(seed)
    inner_w, inner_h = int(width) - 2, int(height) - 2
    longest = int(max_segment) if max_segment is not None else max(1, max(inner_w, inner_h) // 4)
    if longest < 1:
        raise ValueError(f"max_segment must be >= 1, not {max_segment!r}")
    inner = np.zeros((inner_h, inner_w), dtype=bool)
    target = int(round(wall_density * inner.size))
    count, failures = 0, 0
    while count < target and failures < 200:
        length = int(rng.integers(1, longest + 1))
        y, x = int(rng.integers(inner_h)), int(rng.integers(inner_w))
        trial = inner.copy()
        if rng.random() < 0.5:
            trial[y, x : x + length] = True
        else:
            trial[y : y + length, x] = True
        added = int(trial.sum()) - count
        if added == 0 or count + added > inner.size - 2 or label(~trial)[1] != 1:
            failures += 1
            continue
        inner, count, failures = trial, count + added, 0
    walls = np.ones((int(height), int(width)), dtype=bool)
    walls[1:-1, 1:-1] = inner
    free = np.argwhere(~walls)
    gy, gx = (int(v) for v in free[int(rng.integers(len(free)))])
    rows = ["".join("#" if walls[y, x] else "." for x in range(int(width))) for y in range(int(height))]
    rows[gy] = rows[gy][:gx] + "G" + rows[gy][gx + 1 :]
    return rows


def refine_layout(layout: LayoutSpec, k: int) -> list[str]:
    """``layout`` at ``k`` times its resolution: every square becomes a block of ``k`` x ``k`` squares.

    The same maze, finer: walls become blocks of walls and free squares blocks of free squares, so
    a shortest path is up to ``k`` times as long (a little less where it cuts corners inside blocks)
    and a table needs ``k**2`` times the rows, while the maze's structure (and a good partition of
    it) is unchanged. The goal ``G`` and the start ``S``
    become one square each, the one at the centre of their block (``k // 2`` from its top-left corner);
    the rest of their block is free. ``k = 1`` gives the layout back. Returns the rows, ready for
    ``gymnasium.make("avq/GridMaze-v0", layout=...)`` (raise ``max_episode_steps`` with ``k``).
    """
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1:
        raise ValueError(f"k must be an integer >= 1 (the refinement factor), not {k!r}")
    base = load_layout(layout)
    k = int(k)
    walls = np.kron(base.walls, np.ones((k, k), dtype=bool))
    rows = [["#" if w else "." for w in row] for row in walls]
    for mark, at in (("G", base.goal), ("S", base.start)):
        if at is not None:
            rows[at[1] * k + k // 2][at[0] * k + k // 2] = mark
    return ["".join(row) for row in rows]
