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
    path = Path(path)
    buf = io.BytesIO()
    fig.savefig(buf, format=path.suffix.lstrip(".") or "png", dpi=dpi, bbox_inches="tight")
    atomic_write_bytes(path, buf.getvalue())
    return path
