"""The partition of a maze as it learns, animated: a GIF of the views a ``PartitionRecorder`` kept."""

from __future__ import annotations

import io
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from avq._io import atomic_write_bytes
from avq.figure_data import PartitionView
from avq.plotting._figure import pyplot
from avq.plotting.partition import cell_arrows, cell_borders, cell_image, cell_palette, draw_arrows, maze_axes

__all__ = ["animate_partition"]


def _colour_ids(views: Sequence[PartitionView]) -> list[np.ndarray]:
    """A colour number per cell and frame that follows a cell from frame to frame.

    A cell keeps its colour while its codebook vector is the mutual nearest of a vector of the
    frame before (merges renumber the cells, so the index alone would repaint half the maze);
    any other cell takes the next unused number. Without a codebook the cell index is the colour.
    """
    ids: list[np.ndarray] = []
    prev_vectors, prev_ids, next_id = None, None, 0
    for view in views:
        if view.vectors is None:
            ids.append(np.arange(view.n_cells))
            continue
        vec = view.vectors
        new = np.full(len(vec), -1)
        if prev_vectors is not None and prev_ids is not None and len(prev_vectors) and len(vec):
            d = ((vec[:, None, :] - prev_vectors[None, :, :]) ** 2).sum(axis=2)
            nearest_old, nearest_new = d.argmin(axis=1), d.argmin(axis=0)
            mutual = nearest_new[nearest_old] == np.arange(len(vec))
            new[mutual] = prev_ids[nearest_old[mutual]]
        for k in np.flatnonzero(new < 0):
            new[k] = next_id
            next_id += 1
        ids.append(new)
        prev_vectors, prev_ids = vec, new
    return ids


def _palette_image(frame, lut: np.ndarray | None = None):
    """An RGB(A) frame (an ``(h, w, 3)`` or ``(h, w, 4)`` uint8 array, or a Pillow image) as a palette image
    for the GIF: its 255 most frequent colours, exactly, and every other colour as the nearest of those
    (with a frame of flat cells, most pixels keep their colour; about twice as fast as Pillow's median cut,
    which shifts more of them). Alpha is ignored. The 256th entry is left free: Pillow makes it transparent,
    for the pixels that a frame leaves as they were.

    ``lut``: a ``(2**24,)`` uint8 scratch table that maps each colour of the frame to its entry (pass the
    same one for every frame of an animation: only the colours a frame has are written and read).
    """
    from PIL import Image

    pixels = np.ascontiguousarray(frame)
    if pixels.shape[2] == 3:  # (as RGBA, whose four bytes read as one little-endian number)
        pixels = np.concatenate([pixels, np.full((*pixels.shape[:2], 1), 255, np.uint8)], axis=2)
    counts = Image.frombuffer("RGBA", pixels.shape[1::-1], pixels, "raw", "RGBA", 0, 1).getcolors(1 << 16)
    if counts is None:  # (far more colours than a partition has)
        return Image.fromarray(pixels[..., :3]).convert("P", palette=Image.Palette.ADAPTIVE)
    found = np.array([c for _, c in counts], dtype=np.int64).reshape(-1, 4)[:, :3]
    # (the same colour under another alpha counts once, as in the RGB frame)
    key, at = np.unique((found[:, 0] << 16) | (found[:, 1] << 8) | found[:, 2], return_inverse=True)
    n = np.bincount(at, weights=np.fromiter((c for c, _ in counts), np.float64, len(counts)))
    colours = np.stack([key >> 16, (key >> 8) & 255, key & 255], axis=1)
    order = np.lexsort((key, -n))  # the most frequent first (then by colour)
    kept, others = order[:255], order[255:]
    palette = colours[kept]
    entry = np.empty(len(colours), dtype=np.uint8)  # each colour's palette entry: itself, or its nearest
    entry[kept] = np.arange(len(kept))
    if len(others):
        near, pal = colours[others].astype(np.int32), palette.astype(np.int32)  # (int32: half the memory of int64)
        d = (near[:, None, 0] - pal[None, :, 0]) ** 2
        d += (near[:, None, 1] - pal[None, :, 1]) ** 2
        d += (near[:, None, 2] - pal[None, :, 2]) ** 2
        entry[others] = d.argmin(axis=1)  # (squared distance in RGB; the first entry on a tie)
    if lut is None:
        lut = np.empty(1 << 24, dtype=np.uint8)
    lut[colours[:, 0] | (colours[:, 1] << 8) | (colours[:, 2] << 16)] = entry
    image = Image.fromarray(lut[pixels.view("<u4")[..., 0] & 0xFFFFFF], "P")
    image.putpalette(palette.astype(np.uint8).ravel().tolist())
    return image


def animate_partition(
    views: Sequence[PartitionView],
    env,
    path: str | os.PathLike,
    title: str | None = None,
    fps: int = 8,
    dpi: int = 90,
) -> Path:
    """An animated GIF of the partition as it learns: one frame per view (of a :class:`PartitionRecorder`).

    Each frame: the cells' colours and borders, each cell's greedy action on its own square, the
    codebook vectors, and the trial (episode) number and the number of cells. A cell keeps its
    colour from frame to frame while its vector stays. Each frame is drawn by Matplotlib (Agg) and
    written with Pillow, in its own palette of its 255 most frequent colours.
    """
    if not views:
        raise ValueError("no views to animate: record at least one episode")
    plt = pyplot()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    layout = env.unwrapped.layout
    h, w = layout.height, layout.width
    palette = cell_palette(plt)
    ids = _colour_ids(views)
    # Drawn on its own Agg canvas (no pyplot figure to close), at the GIF's resolution.
    fig = Figure(figsize=(max(4.0, w * 0.45), max(3.5, h * 0.45) + 0.5), dpi=dpi)
    canvas = FigureCanvasAgg(fig)
    ax = fig.subplots()
    cells, borders, goal = maze_axes(
        ax,
        layout,
        cell_image(layout, views[0], palette[ids[0] % len(palette)]),
        cell_borders(layout, views[0]),
        fontsize=None,
    )
    (dots,) = ax.plot([], [], "o", color="k", ms=2.5, ls="none", zorder=4)

    def heading(view: PartitionView) -> str:
        what = f"trial {view.episode}: {view.n_cells} cell{'s' if view.n_cells != 1 else ''}"
        return f"{title}\n{what}" if title else what

    # y=1.0 is where Matplotlib places it over axes without ticks; given, it is not worked out again for
    # every frame (which measures the hidden tick labels).
    text = ax.set_title(heading(views[0]), fontsize=11, y=1.0)
    # Room for a two-line title; no layout engine, which would lay the figure out again for every frame.
    fig.subplots_adjust(left=0.02, right=0.98, bottom=0.02, top=1 - 0.55 / fig.get_figheight())
    # What changes from frame to frame is drawn over a copy of the rest (Matplotlib's blitting), in the
    # order a whole drawing takes (by zorder; the arrows are made anew for each frame).
    for artist in (cells, borders, text, goal, dots):
        artist.set_animated(True)
    canvas.draw()
    background = canvas.copy_from_bbox(fig.bbox)
    lut = np.empty(1 << 24, dtype=np.uint8)  # (see _palette_image)
    frames = []
    arrows = None
    for view, colour_ids in zip(views, ids):
        cells.set_facecolor(cell_image(layout, view, palette[colour_ids % len(palette)]).reshape(-1, 4))
        borders.set_segments(cell_borders(layout, view))
        if view.vectors is not None:
            dots.set_data(view.vectors[:, 0], view.vectors[:, 1])
        if arrows is not None:
            arrows.remove()
        _, anchors, directions = cell_arrows(view)
        arrows = draw_arrows(ax, anchors, directions, length=0.45, width=0.09)
        text.set_text(heading(view))
        canvas.restore_region(background)
        for artist in (cells, borders, arrows, text, goal, dots):
            ax.draw_artist(artist)
        frames.append(_palette_image(np.asarray(canvas.buffer_rgba()), lut))
    gif = io.BytesIO()
    frames[0].save(gif, format="GIF", save_all=True, append_images=frames[1:], duration=int(1000 / fps), loop=0)
    out = Path(path)
    atomic_write_bytes(out, gif.getvalue())
    return out
