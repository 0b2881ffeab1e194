"""How the figures read: a logarithmic colour scale ticked in the values themselves, contour labels placed
where they have room, allocation paths that stand out on the colour map, legends beside the plot.

Drawing helpers for `packetloss_cvx.plots.figures` (which draws and saves); nothing here computes a cost.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib import patheffects

__all__ = ["LEGEND", "OUTLINE", "PATH_STYLES", "callout_positions", "contour_label_points", "fit_width", "lay_out",
           "log_ticks", "set_log_ticks", "tick_labels", "tick_text"]

#: Allocation paths on a colour map: bright colours with a black outline (visible on viridis' dark purple and
#: its yellow alike), told apart by their dashes and markers too.
PATH_STYLES = (("#ff3b30", (0, (5, 2)), "X"), ("#ff7cf5", (0, (8, 3, 2, 3)), "o"), ("#22e0ff", (0, (2, 1.5)), "s"),
               ("#fff200", "-", "D"))
OUTLINE = (patheffects.withStroke(linewidth=3.4, foreground="k"),)
#: Legends beside the plot, at a size a printed page can read.
LEGEND = {"loc": "outside right center", "fontsize": 8, "frameon": False}


def log_ticks(lo: float, hi: float) -> np.ndarray:
    """Readable colour-bar ticks on [lo, hi] (0 < lo < hi): 1-2-5 per decade; 1..9 when that gives fewer than
    three; powers of ten (every k-th) when there would be more than nine. O(decades).

    >>> log_ticks(2.5, 84.0).tolist(), log_ticks(4.7, 140.0).tolist(), log_ticks(2.0, 3.5).tolist()
    ([5.0, 10.0, 20.0, 50.0], [5.0, 10.0, 20.0, 50.0, 100.0], [2.0, 3.0])
    >>> log_ticks(1e-3, 1e15).tolist()[:3]
    [0.001, 1.0, 1000.0]
    """
    decades = np.arange(np.floor(np.log10(lo)), np.ceil(np.log10(hi)) + 1)

    def within(subs: Sequence[float]) -> np.ndarray:
        ticks = np.array([m * 10.0**d for d in decades for m in subs])
        return ticks[(ticks >= lo * (1 - 1e-9)) & (ticks <= hi * (1 + 1e-9))]

    ticks = within((1.0, 2.0, 5.0))
    if ticks.size < 3:
        ticks = within(range(1, 10))
    if ticks.size > 9:
        ticks = within((1.0,))
        ticks = ticks[::int(np.ceil(ticks.size / 9))]
    return ticks if ticks.size >= 2 else np.array([lo, hi])


def tick_text(value: float, _pos: Any = None) -> str:
    r"""``%g`` for the values read at a glance, 10^k beyond.

    >>> tick_text(20.0), tick_text(0.5), tick_text(1e6), tick_text(3e-5)
    ('20', '0.5', '$10^{6}$', '$3\\times10^{-5}$')
    """
    if 1e-3 <= abs(value) < 1e5:
        return f"{value:g}"
    mantissa, exponent = f"{value:.0e}".split("e")
    return f"$10^{{{int(exponent)}}}$" if mantissa == "1" else f"${mantissa}\\times10^{{{int(exponent)}}}$"


def tick_labels(ticks: Sequence[float]) -> list[str]:
    r"""Labels of a log axis's ticks in one style: ``10^k`` for all when they are powers of ten and some would
    be written so (`tick_text`: beyond 1e-3 to 1e5) or they span three decades, `tick_text` otherwise.
    O(ticks).

    >>> tick_labels([1e4, 1e5, 1e6]), tick_labels([1.0, 10.0, 100.0, 1000.0]), tick_labels([2.0, 5.0, 10.0])
    (['$10^{4}$', '$10^{5}$', '$10^{6}$'], ['$10^{0}$', '$10^{1}$', '$10^{2}$', '$10^{3}$'], ['2', '5', '10'])
    """
    arr = np.asarray(ticks, dtype=float)
    powers = np.log10(arr)
    wide = powers[-1] - powers[0] >= 3 or any("$" in tick_text(v) for v in arr)
    if arr.size >= 2 and np.allclose(powers, np.round(powers), atol=1e-9) and wide:
        return [f"$10^{{{int(round(k))}}}$" for k in powers]
    return [tick_text(v) for v in arr]


def set_log_ticks(target: Any, lo: float, hi: float) -> None:
    """Round ticks on [lo, hi] (`log_ticks`) in one label style (`tick_labels`) on a log axis or a
    colour bar (``target.set_ticks``), without matplotlib's minor labels (``3x10^1``). O(decades).

    >>> from matplotlib.figure import Figure
    >>> ax = Figure().subplots(); ax.set_yscale("log"); set_log_ticks(ax.yaxis, 3.0, 40.0)
    >>> ax.get_yticks().tolist(), [t.get_text() for t in ax.get_yticklabels()]
    ([5.0, 10.0, 20.0], ['5', '10', '20'])
    """
    ticks = log_ticks(lo, hi) if hi > lo else np.array([lo])
    target.set_ticks(ticks, labels=tick_labels(ticks))
    target.minorticks_off()


def contour_label_points(ax: Any, contours: Any, avoid: Sequence[Any] = ()) -> tuple[list[float], list[tuple]]:
    """Where to label each contour level once so that labels neither collide nor sit on another line.

    Levels in turn, each at the vertex of its line (inside the axes, away from their edges) farthest from the
    other levels' lines, from the polylines ``avoid`` (data coordinates, e.g. allocation paths) and from the
    labels already placed (axes fractions; labels count as 0.13 wide and 0.06 tall); a level whose best point
    is crowded is left unlabelled (the legend lists every level). O(levels * vertices^2).
    """
    to_frac = ax.transData + ax.transAxes.inverted()
    lines = [to_frac.transform(path.vertices) if len(path.vertices) else np.empty((0, 2))
             for path in contours.get_paths()]
    dense = [np.vstack([a + t * (b - a) for a, b in zip(pts[:-1], pts[1:], strict=True) for t in np.linspace(0, 1, 25)])
             if len(pts) > 1 else pts for pts in (to_frac.transform(np.reshape(p, (-1, 2))) for p in avoid)]
    obstacles = np.vstack([*dense, np.empty((0, 2))])
    chosen: list[float] = []
    points: list[tuple[float, float]] = []
    placed: list[np.ndarray] = []
    for k, level in enumerate(contours.levels):
        inside = lines[k][np.all((lines[k] > 0.07) & (lines[k] < 0.93), axis=1)]
        if not inside.size:
            continue
        others = np.vstack([lines[j] for j in range(len(lines)) if j != k] + [obstacles])
        room = np.full(len(inside), 1.0)
        if others.size:
            room = np.min(np.linalg.norm(inside[:, None] - others[None], axis=2), axis=1)
        for q in placed:
            room = np.minimum(room, 0.04 * np.maximum(np.abs(inside[:, 0] - q[0]) / 0.13,
                                                      np.abs(inside[:, 1] - q[1]) / 0.06))
        best = int(np.argmax(room))
        if room[best] < 0.035:
            continue
        placed.append(inside[best])
        chosen.append(float(level))
        points.append(tuple(to_frac.inverted().transform(inside[best])))
    return chosen, points


def lay_out(fig: Any) -> None:
    """Run ``fig``'s layout engine and place its fixed-aspect axes, without drawing: afterwards axes positions
    and window extents are those the figure will be drawn with (at its size). O(artists) text measurements."""
    engine = fig.get_layout_engine()
    if engine is not None:
        engine.execute(fig)
    for ax in fig.axes:
        ax.apply_aspect()


def fit_width(fig: Any) -> None:
    """Narrow ``fig`` (a constrained layout) to what it draws: a square map (``set_box_aspect(1)``) in a figure
    wider than it needs is shrunk inside its slot, leaving an empty band beside it; the figure's width is set so
    that the map's slot is square (its height kept, so the map keeps its size). Two layout passes (`lay_out`),
    no drawing. O(artists).
    """
    square = [ax for ax in fig.axes if ax.get_box_aspect() == 1]
    for _ in range(2):                  # the second pass corrects the margins the first width changed
        lay_out(fig)
        slots = [ax.get_position(original=True) for ax in square]
        if not slots:
            return
        excess = min(slot.width * fig.get_figwidth() - slot.height * fig.get_figheight() for slot in slots)
        if abs(excess) < 0.02:
            return
        fig.set_figwidth(fig.get_figwidth() - excess)


def callout_positions(anchors: Sequence[Sequence[float]], sizes: Sequence[Sequence[float]],
                      obstacles: np.ndarray, boxes: Sequence[Sequence[float]] = ()) -> list[tuple | None]:
    """Where to write a label for each anchor (axes fractions), each in turn: the nearest free spot on rings
    around it (radius 0.035 to 0.45, 24 directions) whose box (``sizes``: width, height) stays inside the axes,
    overlaps no box placed before (``boxes``: x0, y0, x1, y1, e.g. contour labels) and covers no point of
    ``obstacles`` (shape (N, 2): paths and markers). None where there is no free spot. The label is joined to its
    anchor by a leader line when it sits away from it. O(anchors * 24 * 30 * (N + boxes)).

    >>> (x, y), = callout_positions([(0.5, 0.5)], [(0.1, 0.05)], np.array([[0.5, 0.5]]))
    >>> abs(x - 0.5) > 0.05 or abs(y - 0.5) > 0.025       # the box (0.1 x 0.05 around it) leaves the anchor free
    True
    """
    placed = [np.asarray(b, dtype=float) for b in boxes]
    pts = np.reshape(np.asarray(obstacles, dtype=float), (-1, 2))
    angles = np.linspace(0.0, 2 * np.pi, 24, endpoint=False)
    out: list[tuple | None] = []
    for (ax_, ay_), (w, h) in zip(anchors, sizes, strict=True):
        found = None
        for radius in np.linspace(0.035, 0.45, 30):
            for angle in angles:
                cx, cy = ax_ + radius * np.cos(angle), ay_ + radius * np.sin(angle)
                box = np.array([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2])
                if box[0] < 0.01 or box[1] < 0.01 or box[2] > 0.99 or box[3] > 0.99:
                    continue
                if any(box[0] < b[2] and b[0] < box[2] and box[1] < b[3] and b[1] < box[3] for b in placed):
                    continue
                pad = 0.008
                if pts.size and np.any((pts[:, 0] > box[0] - pad) & (pts[:, 0] < box[2] + pad)
                                       & (pts[:, 1] > box[1] - pad) & (pts[:, 1] < box[3] + pad)):
                    continue
                found = (round(float(cx), 6), round(float(cy), 6))
                placed.append(box)
                break
            if found is not None:
                break
        out.append(found)
    return out
