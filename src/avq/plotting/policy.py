"""The picture of what an agent learned on a task with a ``Box`` observation space: its greedy action over two
chosen dimensions, its cells' borders and centres (:func:`plot_policy`; the data is
:func:`avq.plotting.policy_map`), and the same for a saved model or run directory
(:func:`plot_model`, which ``avq plot`` calls)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from avq.agents.base import BaseAgent
from avq.plotting._figure import pyplot, save_figure
from avq.plotting.policy_data import PolicyMap, dimension_names, policy_map

__all__ = ["plot_policy", "plot_model", "policy_figure", "border_segments", "ACTION_COLOURS"]

#: Okabe & Ito's colour-blind-safe palette (without its black, which the borders and centres use).
ACTION_COLOURS = ("#E69F00", "#56B4E9", "#009E73", "#F0E442", "#0072B2", "#D55E00", "#CC79A7")


def _edges(centres: np.ndarray) -> np.ndarray:
    """The pixels' edges from their (evenly spaced) centres."""
    step = centres[1] - centres[0]
    return np.concatenate([centres - step / 2, [centres[-1] + step / 2]])


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """The ``(start, stop)`` of each run of True in a 1-D mask."""
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    change = np.flatnonzero(np.diff(padded))
    return list(zip(change[0::2].tolist(), change[1::2].tolist()))


def border_segments(cells: np.ndarray, xs: np.ndarray, ys: np.ndarray) -> list[tuple[tuple[float, float], ...]]:
    """The borders between pixels of different cells, as line segments in data units (a straight run of pixel
    edges is one segment). ``cells`` is ``(ny, nx)`` over the pixel centres ``xs``, ``ys``."""
    xe, ye = _edges(xs), _edges(ys)
    segments: list[tuple[tuple[float, float], ...]] = []
    across = cells[:, 1:] != cells[:, :-1]  # (ny, nx - 1): a border at x edge i + 1
    for i in range(across.shape[1]):
        segments += [((xe[i + 1], ye[a]), (xe[i + 1], ye[b])) for a, b in _runs(across[:, i])]
    up = cells[1:, :] != cells[:-1, :]  # (ny - 1, nx): a border at y edge j + 1
    for j in range(up.shape[0]):
        segments += [((xe[a], ye[j + 1]), (xe[b], ye[j + 1])) for a, b in _runs(up[j])]
    return segments


def _action_colours(n: int, plt) -> list:
    if n <= len(ACTION_COLOURS):
        return list(ACTION_COLOURS[:n])
    return [plt.get_cmap("cividis")(k / max(n - 1, 1)) for k in range(n)]


def policy_figure(agent: BaseAgent, view: PolicyMap, title: str | None = None):
    """The figure of :func:`plot_policy` for a computed ``view`` (a Matplotlib ``Figure``; the caller closes it)."""
    plt = pyplot()
    from matplotlib.collections import LineCollection
    from matplotlib.colors import ListedColormap, to_rgba
    from matplotlib.patches import Patch

    fonts = {"font.size": 9, "axes.titlesize": 9.5, "axes.labelsize": 10, "legend.fontsize": 8.5}
    with plt.rc_context(fonts):
        fig, ax = plt.subplots(figsize=(5.2, 4.6))
        extent = (*_edges(view.xs)[[0, -1]], *_edges(view.ys)[[0, -1]])
        handles = []
        if view.action_names:
            k = len(view.action_names)
            colours = [(*(0.45 + 0.55 * np.array(to_rgba(c)[:3])), 1.0) for c in _action_colours(k, plt)]  # lighter
            ax.imshow(
                view.actions,
                origin="lower",
                extent=extent,
                aspect="auto",
                interpolation="nearest",
                cmap=ListedColormap(colours),
                vmin=-0.5,
                vmax=k - 0.5,
            )
            present = set(np.unique(view.actions).tolist())
            handles = [
                Patch(facecolor=colours[a], edgecolor="0.3", label=name + ("" if a in present else " (nowhere here)"))
                for a, name in enumerate(view.action_names)
            ]
        else:
            image = ax.imshow(
                view.actions, origin="lower", extent=extent, aspect="auto", interpolation="nearest", cmap="cividis"
            )
            fig.colorbar(image, ax=ax, label=view.action_label)
        if view.cells is not None:
            ax.add_collection(LineCollection(border_segments(view.cells, view.xs, view.ys), colors="k", linewidths=0.6))
            handles.append(plt.Line2D([], [], color="k", lw=0.8, label="cell border"))
        if view.centres is not None and len(view.centres):
            ax.plot(view.centres[:, 0], view.centres[:, 1], "o", ms=2.6, color="k", mec="white", mew=0.4, ls="none")
            label = (
                "cell centre (projected)"
                if view.projected
                else "centre of a cell in the slice (projected)"
                if view.at
                else "cell centre"
            )
            handles.append(plt.Line2D([], [], marker="o", ms=4, color="k", mec="white", ls="none", label=label))
        ax.set_xlim(extent[0], extent[1])
        ax.set_ylim(extent[2], extent[3])
        ax.set_xlabel(view.names[0])
        ax.set_ylabel(view.names[1])
        n_cells = int(agent.n_cells)
        head = title or f"{type(agent).__name__}: {n_cells} {agent.size_unit}, greedy action"
        sub = _slice_text(view, dimension_names(agent))
        ax.set_title(f"{head}\n({sub})" if sub else head)
        if handles:
            ncol = min(3, len(handles))
            ax.legend(
                handles=[
                    handles[r * ncol + c]
                    for c in range(ncol)
                    for r in range(-(-len(handles) // ncol))
                    if r * ncol + c < len(handles)
                ],  # row by row: the actions first
                loc="upper center",
                bbox_to_anchor=(0.5, -0.13),
                ncol=ncol,
                frameon=False,
                handlelength=1.4,
            )
        fig.tight_layout()
    return fig


def _slice_text(view: PolicyMap, names: list[str]) -> str:
    if view.projected:
        return "cell centres projected onto the plane; a point takes the action of the nearest projected centre"
    if not view.at:
        return ""
    return "slice at " + ", ".join(f"{names[d]} = {v:.3g}" for d, v in view.at.items())


def plot_policy(
    agent: BaseAgent,
    path: str | os.PathLike,
    dims: tuple[int, int] | str = (0, 1),
    at: Mapping[int, float] | str | None = None,
    project: bool = False,
    resolution: int = 400,
    bounds: Mapping[int, tuple[float, float]] | str | None = None,
    title: str | None = None,
) -> Path:
    """Draw the agent's greedy action over two dimensions of its observations, with its cells' borders and centres.

    Each pixel is coloured by the greedy action there (a legend names the actions; a colour bar for
    continuous actions), the borders between cells are drawn where the cells cut the plane, and the cells'
    centres are marked. The other dimensions are sliced (``at``, by default the middle of their range) or,
    with ``project``, the cells' centres projected: see :func:`avq.plotting.policy_map`, whose
    arguments these are. The axes are named after the task's dimensions where known (MountainCar,
    CartPole, Acrobot, ...), else ``x0, x1, ...``.

    Args:
        path: File to write; its suffix picks the format (``.png``, or ``.pdf`` and ``.svg`` as vectors,
            the pixels then embedded as an image).
        title: First line of the title (default: the agent's class and its cells).

    Returns:
        ``path``.
    """
    view = policy_map(agent, dims=dims, at=at, project=project, resolution=resolution, bounds=bounds)
    fig = policy_figure(agent, view, title=title)
    out = save_figure(fig, path, dpi=300)
    pyplot().close(fig)
    return out


def plot_model(
    model: str | os.PathLike,
    out: str | os.PathLike | None = None,
    dims: tuple[int, int] | str = (0, 1),
    at: Mapping[int, float] | str | None = None,
    project: bool = False,
    resolution: int = 400,
    bounds: Mapping[int, tuple[float, float]] | str | None = None,
    env: str | None = None,
) -> Path:
    """:func:`plot_policy` of a saved agent: a run directory of ``avq train`` (its ``model.zip``) or a model
    file of ``agent.save``. ``out`` defaults to ``policy_D0-D1.png`` (``policy_D0-D1_projected.png``) in the
    run directory, or beside the model file with the file's name in front. ``env``: the environment to load
    it with instead of its own, as :func:`avq.runs.load_run`'s."""
    from avq.plotting.policy_data import parse_dims
    from avq.runs import load_run

    if not os.path.exists(model):
        raise ValueError(
            f"no such model file or run directory: {model}; give a directory written by 'avq train' or a "
            "model file written by agent.save"
        )
    agent, name = load_run(model, env)
    d0, d1 = parse_dims(dims) if isinstance(dims, str) else dims
    if out is None:
        stem = f"policy_{d0}-{d1}{'_projected' if project else ''}.png"
        base = Path(model)
        out = base / stem if base.is_dir() else base.with_name(f"{base.stem}_{stem}")
    spec = agent.env.spec
    title = (
        f"{name} on {spec.id if spec else 'its task'}: {agent.n_cells} {agent.size_unit}, episode {agent.num_episodes}"
    )
    return plot_policy(
        agent, out, dims=(d0, d1), at=at, project=project, resolution=resolution, bounds=bounds, title=title
    )
