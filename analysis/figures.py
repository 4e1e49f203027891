"""Figures drawn headless: matplotlib's pyplot on the Agg backend, and figures written as PNGs.

matplotlib is imported on first use, so that a module that plots costs no import until
it draws (``minimaxplan --help`` stays fast).
"""

from __future__ import annotations

import pathlib
from collections.abc import Callable
from typing import Any

__all__ = ["pyplot", "save_png", "draw_png"]


def pyplot() -> Any:
    """``matplotlib.pyplot``, with the non-interactive Agg backend selected.

    Returns
    -------
    module
        ``matplotlib.pyplot``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_png(fig: Any, path: str | pathlib.Path, *, dpi: int = 110) -> pathlib.Path:
    """Write ``fig`` to ``path`` as a PNG and close it (also when writing fails).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure, laid out.
    path : str or pathlib.Path
        The image file.
    dpi : int
        Resolution, dots per inch.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    out = pathlib.Path(path)
    try:
        fig.savefig(out, dpi=dpi)
    finally:
        pyplot().close(fig)
    return out


def draw_png(
    draw: Callable[[Any], object], path: str | pathlib.Path, *, figsize: tuple[float, float], dpi: int = 110
) -> pathlib.Path:
    """Draw on the one axes of a new figure, lay it out and write it with `save_png`.

    The figure is closed when done, also when drawing or writing fails.

    Parameters
    ----------
    draw : callable
        ``draw(ax)`` draws on the figure's `matplotlib.axes.Axes`.
    path, dpi
        As for `save_png`.
    figsize : tuple of float
        The figure's (width, height), inches.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=figsize)
    try:
        draw(ax)
        fig.tight_layout()
    except BaseException:
        plt.close(fig)
        raise
    return save_png(fig, path, dpi=dpi)
