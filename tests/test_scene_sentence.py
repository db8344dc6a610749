"""Sentences of the scene grammar: round trips, hand-written examples, located errors."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from depthgram.errors import InputError
from depthgram.scene import (
    RELATIONS,
    Node,
    Relation,
    SceneTree,
    SentenceError,
    parse_sentence,
    parse_sentences,
    round_tree,
    to_sentence,
)

EXAMPLE = (
    "Bkg[A=307200,c=(319.5,239.5),z=0.0] -> floor#1 o_4..6[A=52000,c=(320.0,400.2),z=2100.0] "
    "{ object#2 o_2[A=9000,c=(300.1,250.0),z=1500.0] "
    "{ object#3 o_1[A=300,c=(290.0,180.5),z=1420.0,v=-120.0mm/s,ttc=11.8s,s=visible] } } "
    "wall#4 o_3(3,5,6)[A=8000,c=(20.0,200.0),z=1800.0] ; 2 left_of 4, 3 occludes 2"
)


def test_example_reads_as_written():
    t = parse_sentence(EXAMPLE)
    assert t.root.kind == "Bkg" and t.root.id == 0 and t.root.area == 307200
    assert t.parent_of() == {1: 0, 2: 1, 3: 2, 4: 0}
    floor, wall = t.root.children
    assert (floor.kind, floor.depth_label, floor.parts) == ("floor", 4, (4, 5, 6))
    assert (wall.depth_label, wall.parts) == (3, (3, 5, 6))
    cup = floor.children[0].children[0]
    assert (cup.area, cup.center_xy, cup.depth) == (300, (290.0, 180.5), 1420.0)
    assert (cup.v_radial, cup.ttc, cup.status) == (-120.0, 11.8, "visible")
    assert t.relations == (Relation(2, "left_of", 4), Relation(3, "occludes", 2))
    assert to_sentence(t) == EXAMPLE


def test_precision_rounds_and_empty_scene():
    n = Node(1, "object", 2, 1234.567, 10, (1.25, 2.75), v_radial=-0.04, ttc=math.inf)
    t = SceneTree(Node(0, "Bkg", -1, 0.0, 100, (4.5, 4.5), children=(n,)))
    s = to_sentence(t, precision=0)
    assert "o_2[A=10,c=(1,3),z=1235,v=0mm/s,ttc=infs]" in s
    assert parse_sentence(s) == round_tree(t, 0)
    empty = SceneTree(Node(0, "Bkg", -1, 0.0, 0, (0.0, 0.0)))
    assert parse_sentence(to_sentence(empty)) == empty


def test_motion_units_are_written_and_checked():
    n = Node(1, "object", 2, 1500.0, 10, (1.0, 2.0), v_radial=-512.0, ttc=2.93, status="visible")
    t = SceneTree(Node(0, "Bkg", -1, 0.0, 100, (4.5, 4.5), children=(n,)))
    s = to_sentence(t)
    assert "v=-512.0mm/s,ttc=2.9s,s=visible" in s
    assert parse_sentence(s) == round_tree(t)
    # sentences written before units were explicit read in the fixed units
    assert parse_sentence(s.replace("mm/s", "").replace("2.9s", "2.9")) == round_tree(t)
    for wrong, where in (("v=-512.0s", "v=-512.0s"), ("ttc=2.9mm/s", "ttc=2.9mm/s")):
        bad = s.replace(where.split("=")[0] + "=" + ("-512.0mm/s" if wrong.startswith("v") else "2.9s"), wrong)
        with pytest.raises(SentenceError, match="is written in"):
            parse_sentence(bad)
    with pytest.raises(SentenceError, match="without a unit"):
        parse_sentence(s.replace("z=1500.0", "z=1500.0s"))


def test_root_label_and_multiple_lines():
    t = SceneTree(Node(0, "Bkg", 7, 0.0, 12, (1.5, 1.0)))
    assert "L=7" in to_sentence(t)
    text = f"\n{to_sentence(t)}\n\n{EXAMPLE}\n"
    a, b = parse_sentences(text)
    assert a == t and to_sentence(b) == EXAMPLE


def test_writer_rejects_what_it_cannot_carry():
    nan_node = Node(1, "object", 0, math.nan, 1, (0.0, 0.0))
    with pytest.raises(InputError, match="NaN"):
        to_sentence(SceneTree(Node(0, "Bkg", -1, 0.0, 1, (0.0, 0.0), children=(nan_node,))))
    with pytest.raises(InputError, match="precision"):
        to_sentence(parse_sentence(EXAMPLE), precision=-1)


# ---------------------------------------------------------------------------------------------
# Round trip of random trees


finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)


@st.composite
def scene_trees(draw: st.DrawFn) -> SceneTree:
    n = draw(st.integers(0, 15))
    ids = draw(st.lists(st.integers(1, 10_000), min_size=n, max_size=n, unique=True))
    parent_index = [draw(st.integers(-1, k - 1)) for k in range(n)]  # -1: the root
    fields = []
    for _ in range(n):
        label = draw(st.integers(0, 60))
        parts_kind = draw(st.sampled_from(["none", "run", "list"]))
        if parts_kind == "run":
            parts = tuple(range(label, label + draw(st.integers(2, 6))))
        elif parts_kind == "list":
            parts = tuple(draw(st.lists(st.integers(0, 60), min_size=1, max_size=5)))
        else:
            parts = ()
        fields.append(
            dict(
                kind=draw(st.sampled_from(["object", "floor", "wall", "ceiling", "compound", "part", "table"])),
                depth_label=label,
                depth=draw(st.floats(0.0, 20_000.0)),
                area=draw(st.integers(0, 10**7)),
                center_xy=(draw(finite), draw(finite)),
                v_radial=draw(st.none() | finite),
                ttc=draw(st.none() | st.floats(0.0, 1e5) | st.just(math.inf)),
                status=draw(st.none() | st.sampled_from(["visible", "entering", "leaving", "occluded"])),
                parts=parts,
            )
        )

    def make(k: int) -> Node:
        kids = tuple(make(j) for j in range(n) if parent_index[j] == k)
        return Node(id=ids[k], children=kids, **fields[k])

    root = Node(
        0,
        "Bkg",
        draw(st.sampled_from([-1, 0, 3])),
        draw(st.floats(0.0, 1e4)),
        draw(st.integers(0, 10**7)),
        (draw(finite), draw(finite)),
        children=tuple(make(j) for j in range(n) if parent_index[j] == -1),
    )
    rels: tuple[Relation, ...] = ()
    if n >= 2:
        rels = tuple(
            draw(
                st.lists(
                    st.builds(Relation, st.sampled_from(ids), st.sampled_from(RELATIONS), st.sampled_from(ids)),
                    max_size=8,
                )
            )
        )
    return SceneTree(root=root, relations=rels)


@settings(max_examples=150, deadline=None)
@given(scene_trees(), st.integers(0, 4))
def test_random_trees_round_trip(tree, precision):
    sentence = to_sentence(tree, precision=precision)
    assert "\n" not in sentence
    back = parse_sentence(sentence)
    assert back == round_tree(tree, precision)
    # Reading and writing again is stable.
    assert to_sentence(back, precision=precision) == sentence


@settings(max_examples=50, deadline=None)
@given(st.lists(scene_trees(), min_size=1, max_size=4))
def test_many_lines_round_trip(trees):
    text = "\n".join(to_sentence(t) for t in trees)
    assert parse_sentences(text) == [round_tree(t, 1) for t in trees]


# ---------------------------------------------------------------------------------------------
# Invalid sentences: position and message


@pytest.mark.parametrize(
    ("text", "column", "what"),
    [
        ("Bkg => ", 5, "unexpected '='"),
        ("Bkg -> object#1 o_3[A=1,c=(1,2),z=3", 36, "end of the line"),
        ("Bkg -> object#1 o_3[A=1,c=(1,2)]", 8, "missing attribute(s) z"),
        ("Bkg -> object#1 o_3[A=1,c=(1,2),z=3,q=1]", 37, "unknown attribute 'q'"),
        ("Bkg -> object#1 o_3[A=1.5,c=(1,2),z=3]", 21, "must be an integer"),
        ("Bkg -> object#1 o_3[A=1,c=3,z=3]", 25, "must be a pair"),
        ("Bkg -> object#1 o_3[A=1,c=(1,2),z=3] object#1 o_2[A=1,c=(1,2),z=3]", 45, "appears twice"),
        ("Bkg -> object#1 o_3[A=1,c=(1,2),z=3] ; 1 near 1", 42, "unknown relation 'near'"),
        ("Bkg -> object#1 o_3[A=1,c=(1,2),z=3] ; 1 left_of 9", 50, "object 9"),
        ("Bkg -> object#1 o_5..3[A=1,c=(1,2),z=3]", 22, "must end above"),
        ("Bkg -> object#1 o_3[A=1,c=(1,2),z=3] $", 38, "unexpected character '$'"),
        ("Bkg -> Bkg#1 o_3[A=1,c=(1,2),z=3]", 8, "start symbol"),
        ("Bkg -> object#0 o_3[A=1,c=(1,2),z=3]", 15, "ids start at 1"),
    ],
)
def test_invalid_sentence_position(text, column, what):
    with pytest.raises(SentenceError) as info:
        parse_sentence(text)
    err = info.value
    assert (err.line, err.column) == (1, column)
    assert what in str(err)
    # The message shows the line and a caret under the offending character.
    _, shown, caret = str(err).split("\n")
    assert shown.strip() == text.strip()
    assert caret.index("^") - 4 == column - 1


def test_error_line_number_in_many_lines():
    text = f"{EXAMPLE}\n\n{EXAMPLE.replace('s=visible', 's=visible,s=leaving')}\n"
    with pytest.raises(SentenceError) as info:
        parse_sentences(text, source="scene.txt")
    assert info.value.line == 3
    assert info.value.column == EXAMPLE.index("s=visible") + len("s=visible,") + 1
    assert str(info.value).startswith("scene.txt:3:")
    assert isinstance(info.value, InputError)


def test_parse_sentence_wants_exactly_one():
    with pytest.raises(SentenceError, match="empty"):
        parse_sentence("  \n")
    with pytest.raises(SentenceError, match="second line") as info:
        parse_sentence(EXAMPLE + "\n" + EXAMPLE)
    assert info.value.line == 2
