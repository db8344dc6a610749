"""The tree picture: layout, and files that show every node, attribute and relation."""

from __future__ import annotations

import pytest

from depthgram.errors import InputError
from depthgram.scene import parse_sentence
from depthgram.views.tree_plot import draw_tree, tree_layout

SENTENCE = (
    "Bkg[A=307200,c=(319.5,239.5),z=0.0] -> wall#6 o_4[A=97350,c=(112.1,202.1),z=2513.2] "
    "floor#1 o_3[A=69945,c=(395.0,407.6),z=2437.5] { object#2 o_0[A=18614,c=(319.5,357.4),z=2021.4] "
    "{ object#3 o_1[A=267,c=(286.0,291.5),z=2209.0,v=-120.0,ttc=18.4,s=visible] "
    "object#4 o_2..4[A=590,c=(345.0,287.5),z=2309.1] } object#5 o_5[A=3467,c=(433.1,353.1),z=2560.9] } "
    "; 2 left_of 5, 3 left_of 4"
)


def test_layout_leaves_on_slots_parents_centered():
    pos = tree_layout(parse_sentence(SENTENCE))
    # Leaves in depth-first order: wall 6 -> 0, cup 3 -> 1, box 4 -> 2, box 5 -> 3.
    assert pos[6] == (0.0, -1.0)
    assert pos[3] == (1.0, -3.0) and pos[4] == (2.0, -3.0)
    assert pos[2] == (1.5, -2.0)
    assert pos[5] == (3.0, -2.0)
    assert pos[1] == (2.25, -1.0)
    assert pos[0] == (1.125, 0.0)


def test_svg_shows_nodes_attributes_and_relations(tmp_path):
    out = tmp_path / "tree.svg"
    draw_tree(parse_sentence(SENTENCE), out)
    svg = out.read_text()
    # Text is kept as text in the SVG only when fonttype is none; check glyph ids otherwise.
    assert svg.lstrip().startswith("<?xml") and "<svg" in svg
    assert svg.count("stroke-dasharray") >= 2  # the two dashed relation arcs


def test_png_is_written(tmp_path):
    out = tmp_path / "tree.png"
    draw_tree(parse_sentence(SENTENCE), out)
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    width = int.from_bytes(data[16:20], "big")
    assert width >= 400


def test_text_of_nodes_in_svg(tmp_path):
    import matplotlib

    matplotlib.rcParams["svg.fonttype"] = "none"  # keep text as text to read it back
    try:
        out = tmp_path / "tree.svg"
        draw_tree(parse_sentence(SENTENCE), out)
        svg = out.read_text()
    finally:
        matplotlib.rcParams["svg.fonttype"] = "path"
    for s in ["object#3", "o_1", "ttc=18.4", "visible", "o_2..4", "A=590", "left_of", "wall#6", "Bkg"]:
        assert s in svg, s


@pytest.mark.parametrize("name", ["tree.jpg", "missing/tree.png"])
def test_bad_paths(tmp_path, name):
    with pytest.raises(InputError):
        draw_tree(parse_sentence(SENTENCE), tmp_path / name)
