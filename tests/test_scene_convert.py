"""tree_to_dict / tree_from_dict: JSON round trips and the dictionary's layout."""

from __future__ import annotations

import json

import pytest
from hypothesis import given, settings
from tests.test_scene_sentence import EXAMPLE, scene_trees

from depthgram.errors import InputError
from depthgram.scene import parse_sentence, tree_from_dict, tree_to_dict


def test_dict_layout_of_example():
    d = tree_to_dict(parse_sentence(EXAMPLE))
    assert [n["id"] for n in d["nodes"]] == [0, 1, 2, 3, 4]
    root, floor, _table, cup, wall = d["nodes"]
    assert root["parent"] is None and root["children"] == [1, 4] and root["kind"] == "Bkg"
    assert floor["parts"] == [4, 5, 6] and floor["parent"] == 0 and floor["children"] == [2]
    assert cup == {
        "id": 3,
        "kind": "object",
        "depth_label": 1,
        "depth": 1420.0,
        "area": 300,
        "center_xy": [290.0, 180.5],
        "parent": 2,
        "children": [],
        "parts": [],
        "v_radial": -120.0,
        "ttc": 11.8,
        "status": "visible",
    }
    assert wall["parts"] == [3, 5, 6]
    assert d["relations"] == [[2, "left_of", 4], [3, "occludes", 2]]


@settings(max_examples=80, deadline=None)
@given(scene_trees())
def test_json_round_trip(tree):
    text = json.dumps(tree_to_dict(tree))
    assert tree_from_dict(json.loads(text)) == tree


def test_malformed_dicts_are_named():
    d = tree_to_dict(parse_sentence(EXAMPLE))
    bad = json.loads(json.dumps(d))
    bad["nodes"][1]["children"].append(99)
    with pytest.raises(InputError, match="unknown child 99"):
        tree_from_dict(bad)
    bad = json.loads(json.dumps(d))
    del bad["nodes"][2]["depth"]
    with pytest.raises(InputError, match="malformed"):
        tree_from_dict(bad)
    bad = json.loads(json.dumps(d))
    bad["nodes"][3]["children"] = [1]  # a cycle: the cup holds the floor
    with pytest.raises(InputError, match="own ancestor"):
        tree_from_dict(bad)
