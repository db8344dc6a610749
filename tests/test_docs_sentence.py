"""docs/sentence.md: every example sentence parses and is written back unchanged (issue 16, item 5)."""

from __future__ import annotations

import re
from pathlib import Path

from depthgram.scene import parse_sentence, to_sentence
from depthgram.scene.sentence import RELATIONS
from depthgram.segmentation import KINDS

DOC = Path(__file__).resolve().parents[1] / "docs" / "sentence.md"


def _examples() -> list[str]:
    blocks = re.findall(r"```\n(.*?)```", DOC.read_text(encoding="utf-8"), re.S)
    return [line for block in blocks for line in block.splitlines() if line.startswith("Bkg")]


def test_every_example_round_trips() -> None:
    examples = _examples()
    assert len(examples) >= 3
    for i, sentence in enumerate(examples):
        tree = parse_sentence(sentence, source=str(DOC), first_line=i + 1)
        assert to_sentence(tree) == sentence


def test_every_kind_and_relation_is_explained() -> None:
    text = DOC.read_text(encoding="utf-8")
    for word in (*KINDS, *RELATIONS, "o_L..M", "o_L(p,q,...)", "{ ... }", "entering", "leaving", "occluded"):
        assert f"`{word}`" in text or f"`A {word} B`" in text, word
