"""What every figure shares: Matplotlib with the Agg backend (imported only here, on first use), and saving a
figure atomically."""

from __future__ import annotations

import io
import os
from pathlib import Path

from avq._io import atomic_write_bytes

__all__ = ["pyplot", "save_figure"]


def pyplot():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path: str | os.PathLike, dpi: int = 150) -> Path:
    """Write ``fig`` into ``path`` (its suffix picks the format) at ``dpi``, cropped to what is drawn
    (``bbox_inches="tight"``), atomically.

    A PNG of a figure on an Agg canvas that is laid out already (by ``tight_layout``, or not at all) is
    drawn once (see :func:`_png`); the figure is then left without a layout engine.
    """
    path = Path(path)
    data = _png(fig, dpi) if path.suffix.lower() in (".png", "") else None
    if data is None:
        buf = io.BytesIO()
        fig.savefig(buf, format=path.suffix.lstrip(".") or "png", dpi=dpi, bbox_inches="tight")
        data = buf.getvalue()
    atomic_write_bytes(path, data)
    return path


def _png(fig, dpi: int) -> bytes | None:
    """The PNG that ``savefig(format="png", dpi=dpi, bbox_inches="tight")`` writes, in about two thirds of
    its time; None for a figure this does not apply to (one with a layout engine that still lays it out,
    or not on a plain Agg canvas, as pyplot's figures are here).

    ``savefig`` goes over the figure twice for a tight crop: once without drawing, to place what is placed
    as it draws, then once drawing. After a ``tight_layout`` everything is placed, so the crop is worked
    out here, as ``savefig`` does it (at the file's resolution, with its padding), and handed to it; it
    then skips its first pass when the figure has no layout engine. The pixels are the same. An opaque
    figure is written as RGB, without the alpha channel that it does not use (smaller, and faster to
    compress); its metadata are those Matplotlib writes.
    """
    import matplotlib as mpl
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.layout_engine import PlaceHolderLayoutEngine
    from PIL import Image, PngImagePlugin

    if type(fig.canvas) is not FigureCanvasAgg:  # (a window's canvas would follow the change of dpi below)
        return None
    if fig.get_layout_engine() is not None:
        if not isinstance(fig.get_layout_engine(), PlaceHolderLayoutEngine):  # (one that lays out as it draws)
            return None
        fig.set_layout_engine(None)  # (the place holder that tight_layout leaves does nothing)
        if fig.get_layout_engine() is not None:  # (rcParams["figure.autolayout"] puts one back)
            return None
    shown_dpi = fig.dpi
    try:
        fig.dpi = dpi
        bbox = fig.get_tightbbox(fig.canvas.get_renderer()).padded(mpl.rcParams["savefig.pad_inches"])
    finally:
        fig.dpi = shown_dpi
    buf = io.BytesIO()
    fig.savefig(buf, format="rgba", dpi=dpi, bbox_inches=bbox)
    width, height = int(bbox.width * dpi), int(bbox.height * dpi)  # (the size of Agg's canvas for it)
    rgba = np.frombuffer(buf.getbuffer(), dtype=np.uint8)
    if rgba.size != width * height * 4:
        return None
    image = Image.frombuffer("RGBA", (width, height), rgba, "raw", "RGBA", 0, 1)
    if rgba[3::4].min() == 255:
        image = image.convert("RGB")
    info = PngImagePlugin.PngInfo()
    info.add_text("Software", f"Matplotlib version{mpl.__version__}, https://matplotlib.org/")
    out = io.BytesIO()
    image.save(out, format="png", pnginfo=info, dpi=(dpi, dpi))
    return out.getvalue()
