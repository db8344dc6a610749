"""depthgram.scene: the scene language (paper section 4): parse trees, sentences, dictionaries.

``build_tree`` turns segmented objects into a :class:`SceneTree`; ``to_sentence`` writes it
as one line of the attribute grammar in ``grammar.lark``; ``parse_sentence`` reads it back.
"""

from depthgram.scene.build import TreeConfig, build_tree, support_depth_at
from depthgram.scene.convert import tree_from_dict, tree_to_dict
from depthgram.scene.sentence import (
    RELATIONS,
    SentenceError,
    parse_sentence,
    parse_sentences,
    round_tree,
    to_sentence,
)
from depthgram.scene.tree import Motion, Node, Relation, SceneTree

__all__ = [
    "RELATIONS",
    "Motion",
    "Node",
    "Relation",
    "SceneTree",
    "SentenceError",
    "TreeConfig",
    "build_tree",
    "parse_sentence",
    "parse_sentences",
    "round_tree",
    "support_depth_at",
    "to_sentence",
    "tree_from_dict",
    "tree_to_dict",
]
