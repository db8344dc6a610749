"""A picture of the scene's parse tree, as the paper's Fig. 6.

Nodes are boxes with their attributes (kind, id, depth-label terminal, area, center, depth,
and v_radial / ttc / status when known); solid edges are the vertical links (support),
dashed arcs the horizontal relations between siblings. Drawn on a matplotlib Figure with an Agg
canvas: pyplot and the user's backend are left untouched.
"""

from __future__ import annotations

from pathlib import Path

from depthgram.errors import InputError
from depthgram.scene.tree import Node, SceneTree

__all__ = ["draw_tree", "tree_layout"]

_SUFFIXES = (".png", ".svg")


def tree_layout(tree: SceneTree) -> dict[int, tuple[float, float]]:
    """Position of each node id: leaves on successive x slots, parents centered over children.

    Returns
    -------
    dict of int to (float, float)
        (x, y) in layout units; y is minus the node's level (root at 0).
    """
    pos: dict[int, tuple[float, float]] = {}
    next_slot = [0.0]

    def place(n: Node, level: int) -> float:
        if not n.children:
            x = next_slot[0]
            next_slot[0] += 1.0
        else:
            xs = [place(c, level + 1) for c in n.children]
            x = (xs[0] + xs[-1]) / 2.0
        pos[n.id] = (x, -float(level))
        return x

    place(tree.root, 0)
    return pos


def _text(n: Node) -> str:
    if n.kind == "Bkg":
        return f"Bkg\nA={n.area}\nc=({n.center_xy[0]:.0f},{n.center_xy[1]:.0f})"
    term = f"o_{n.depth_label}"
    if n.parts:
        run = n.parts == tuple(range(n.depth_label, n.depth_label + len(n.parts))) and len(n.parts) > 1
        term += f"..{n.parts[-1]}" if run else "(" + ",".join(map(str, n.parts)) + ")"
    cx, cy = n.center_xy
    lines = [f"{n.kind}#{n.id}  {term}", f"A={n.area}  z={n.depth:.0f} mm", f"c=({cx:.1f},{cy:.1f})"]
    dyn = []
    if n.v_radial is not None:
        dyn.append(f"v={n.v_radial:.0f}")
    if n.ttc is not None:
        dyn.append(f"ttc={n.ttc:.1f}")
    if n.status is not None:
        dyn.append(n.status)
    if dyn:
        lines.append("  ".join(dyn))
    return "\n".join(lines)


_COLORS = {
    "Bkg": "#dddddd",
    "floor": "#d9c7a7",
    "wall": "#b9c9d9",
    "ceiling": "#d0d0e8",
    "compound": "#e8d0a8",
    "part": "#f0e0c0",
}


def draw_tree(tree: SceneTree, path: str | Path) -> None:
    """Draw the parse tree to a PNG or SVG file (chosen by the suffix).

    Parameters
    ----------
    tree : SceneTree
        The tree to draw.
    path : str or Path
        Output file; its suffix must be ``.png`` or ``.svg``. The folder must exist.

    Raises
    ------
    InputError
        For another suffix or a missing folder.
    """
    out = Path(path)
    if out.suffix.lower() not in _SUFFIXES:
        raise InputError(f"{out}: the tree picture must be .png or .svg, got suffix {out.suffix!r}")
    if not out.parent.is_dir():
        raise InputError(f"{out}: folder {out.parent} does not exist")

    # a Figure with its own Agg canvas, not pyplot: the user's backend is left alone
    from depthgram._optional import needs_extra

    with needs_extra("report", "drawing the tree"):
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
        from matplotlib.patches import FancyArrowPatch

    pos = tree_layout(tree)
    nodes = [tree.root, *tree.nodes()]
    width = max(x for x, _ in pos.values()) + 1.0
    levels = -min(y for _, y in pos.values()) + 1.0
    fig = Figure(figsize=(max(4.0, 2.3 * width), max(2.5, 1.6 * levels)))
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    ax.set_xlim(-0.6, width - 0.4)
    ax.set_ylim(-levels + 0.45, 0.55)
    ax.axis("off")

    parent = tree.parent_of()
    for n in nodes:
        if n.id in parent:
            (x0, y0), (x1, y1) = pos[parent[n.id]], pos[n.id]
            ax.plot([x0, x1], [y0 - 0.18, y1 + 0.18], color="#444444", lw=1.2, zorder=1)
    for r in tree.relations:
        if r.a not in pos or r.b not in pos:
            continue
        (xa, ya), (xb, yb) = pos[r.a], pos[r.b]
        arc = FancyArrowPatch(
            (xa, ya - 0.2),
            (xb, yb - 0.2),
            connectionstyle="arc3,rad=0.35",
            arrowstyle="-|>",
            mutation_scale=10,
            linestyle="--",
            color="#aa3333",
            lw=1.0,
            zorder=2,
        )
        ax.add_patch(arc)
        ax.text(
            (xa + xb) / 2,
            (ya + yb) / 2 - 0.2 - 0.18 * abs(xb - xa) * 0.35 - 0.05,
            r.relation,
            ha="center",
            va="top",
            fontsize=7,
            color="#aa3333",
            zorder=4,
        )
    for n in nodes:
        x, y = pos[n.id]
        ax.text(
            x,
            y,
            _text(n),
            ha="center",
            va="center",
            fontsize=7,
            family="monospace",
            zorder=3,
            bbox={"boxstyle": "round,pad=0.35", "fc": _COLORS.get(n.kind, "#ffffff"), "ec": "#333333"},
        )
    ax.set_title("Scene parse tree (solid: supports, dashed: relations)", fontsize=9)
    fig.tight_layout()
    fig.savefig(out, format=out.suffix.lower()[1:], dpi=110)
