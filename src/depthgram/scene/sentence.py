"""Scene trees as sentences of the attribute grammar, and back (paper, equations 8-12, 14-17).

A sentence is one line: the start symbol ``Bkg`` with the frame's attributes, ``->``, the
objects it supports, each written ``kind#id o_<label>[attributes]`` and followed by
``{ ... }`` with the objects it supports in turn, then ``;`` and the horizontal relations
between siblings. The grammar is ``grammar.lark`` beside this module; it is parsed with
lark's LALR parser.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from functools import lru_cache
from importlib import resources
from typing import Any

from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken

from depthgram.errors import InputError
from depthgram.scene.tree import Node, Relation, SceneTree

__all__ = [
    "RELATIONS",
    "ROOT_KIND",
    "SentenceError",
    "parse_sentence",
    "parse_sentences",
    "round_tree",
    "to_sentence",
]

#: Kind of the start node.
ROOT_KIND = "Bkg"
#: Horizontal relations the language knows.
RELATIONS = ("left_of", "right_of", "above", "below", "in_front_of", "occludes")
#: Depth label of the root when none is written (the background is no depth band).
ROOT_LABEL = -1
#: Units written after the motion attributes: radial velocity in mm/s, time to collision in s.
UNITS = {"v": "mm/s", "ttc": "s"}


class SentenceError(InputError):
    """A sentence that the scene grammar rejects.

    Attributes
    ----------
    line, column : int
        Position of the offending character, both from 1.
    source : str
        Where the text came from (file name, ``-`` for stdin, ``<sentence>``).
    """

    def __init__(self, what: str, *, text: str, line: int, column: int, source: str = "<sentence>"):
        self.line = line
        self.column = column
        self.source = source
        self.what = what
        caret = " " * max(column - 1, 0) + "^"
        super().__init__(f"{source}:{line}:{column}: {what}\n    {text}\n    {caret}")


# ---------------------------------------------------------------------------------------------
# writing


def _num(x: float, precision: int) -> str:
    if math.isnan(x):
        raise InputError("a scene attribute is NaN; the sentence cannot carry it")
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    s = f"{x:.{precision}f}"
    # "-0.0" would read back equal but looks like a sign error to a person.
    return s[1:] if s.startswith("-") and float(s) == 0.0 else s


def _attrs(n: Node, precision: int, root: bool) -> str:
    parts = [
        f"A={int(n.area)}",
        f"c=({_num(n.center_xy[0], precision)},{_num(n.center_xy[1], precision)})",
        f"z={_num(n.depth, precision)}",
    ]
    if root and n.depth_label != ROOT_LABEL:
        parts.append(f"L={int(n.depth_label)}")
    if n.v_radial is not None:
        parts.append(f"v={_num(n.v_radial, precision)}{UNITS['v']}")
    if n.ttc is not None:
        parts.append(f"ttc={_num(n.ttc, precision)}{UNITS['ttc']}")
    if n.status is not None:
        parts.append(f"s={n.status}")
    return "[" + ",".join(parts) + "]"


def _terminal(n: Node) -> str:
    if n.depth_label < 0:
        raise InputError(f"node {n.id}: depth label must be >= 0 to be written as o_<label>, got {n.depth_label}")
    if not n.parts:
        return f"o_{n.depth_label}"
    if len(n.parts) > 1 and n.parts == tuple(range(n.depth_label, n.depth_label + len(n.parts))):
        return f"o_{n.depth_label}..{n.parts[-1]}"
    return f"o_{n.depth_label}(" + ",".join(str(int(p)) for p in n.parts) + ")"


def _write(n: Node, precision: int, out: list[str]) -> None:
    out.append(f"{n.kind}#{n.id} {_terminal(n)}{_attrs(n, precision, False)}")
    if n.children:
        out.append("{")
        for c in n.children:
            _write(c, precision, out)
        out.append("}")


def to_sentence(tree: SceneTree, *, precision: int = 1) -> str:
    """Write a scene tree as one sentence (one line) of the scene grammar.

    Parameters
    ----------
    tree : SceneTree
        The tree; every node's id, kind, label, parts, area, center, depth, v_radial, ttc and
        status are written, and the relations.
    precision : int
        Decimals written for center (px), depth (mm), v_radial (written ``v=-512.0mm/s``)
        and ttc (written ``ttc=2.9s``). Area is an integer pixel count.

    Returns
    -------
    str
        The sentence, without a line break.

    Raises
    ------
    InputError
        For a negative precision, a NaN attribute or a negative depth label below the root.
    """
    if precision < 0:
        raise InputError(f"precision must be >= 0 decimals, got {precision}")
    out = [ROOT_KIND + _attrs(tree.root, precision, True), "->"]
    for c in tree.root.children:
        _write(c, precision, out)
    if tree.relations:
        out.append(";")
        out.append(", ".join(f"{r.a} {r.relation} {r.b}" for r in tree.relations))
    return " ".join(out)


def round_tree(tree: SceneTree, precision: int = 1) -> SceneTree:
    """Return the tree as :func:`parse_sentence` reads it back from ``to_sentence(tree, precision=...)``.

    Floats are rounded to ``precision`` decimals; used to compare round trips.
    """

    def r(x: float | None) -> float | None:
        return None if x is None else float(_num(x, precision))

    def node(n: Node) -> Node:
        return Node(
            id=n.id,
            kind=n.kind,
            depth_label=n.depth_label,
            depth=float(_num(n.depth, precision)),
            area=int(n.area),
            center_xy=(float(_num(n.center_xy[0], precision)), float(_num(n.center_xy[1], precision))),
            v_radial=r(n.v_radial),
            ttc=r(n.ttc),
            status=n.status,
            parts=tuple(int(p) for p in n.parts),
            children=tuple(node(c) for c in n.children),
        )

    return SceneTree(root=node(tree.root), relations=tree.relations)


# ---------------------------------------------------------------------------------------------
# reading


@lru_cache(maxsize=1)
def _parser() -> Lark:
    text = resources.files("depthgram.scene").joinpath("grammar.lark").read_text(encoding="utf-8")
    # LALR with the contextual lexer: linear time, and kinds, keys and relations can share NAME.
    return Lark(text, parser="lalr", lexer="contextual", start="start", maybe_placeholders=False)


class _Reader:
    """Turns one lark parse tree into a SceneTree, checking what the grammar cannot."""

    def __init__(self, text: str, line: int, source: str):
        self.text = text
        self.line = line
        self.source = source
        self.ids: set[int] = set()

    def fail(self, what: str, tok: Token | None) -> SentenceError:
        col = tok.column if tok is not None and tok.column is not None else len(self.text) + 1
        return SentenceError(what, text=self.text, line=self.line, column=int(col), source=self.source)

    def attrs(self, t: Tree[Token] | None, *, root: bool) -> dict[str, tuple[object, Token]]:
        out: dict[str, tuple[object, Token]] = {}
        if t is None:
            return out
        allowed = {"A", "c", "z", "v", "ttc", "s"} | ({"L"} if root else set())
        for a in t.children:
            assert isinstance(a, Tree)
            key_tok, val = a.children
            assert isinstance(key_tok, Token) and isinstance(val, Tree)
            key = str(key_tok)
            if key not in allowed:
                raise self.fail(f"unknown attribute {key!r} (expected one of {', '.join(sorted(allowed))})", key_tok)
            if key in out:
                raise self.fail(f"attribute {key!r} given twice", key_tok)
            toks = [c for c in val.children if isinstance(c, Token)]
            if val.data == "pair":
                value: object = (float(toks[0]), float(toks[1]))
            elif val.data == "number":
                value = float(toks[0])
                if len(toks) > 1:
                    unit = str(toks[1])
                    if UNITS.get(key) != unit:
                        want_unit = f"in {UNITS[key]}" if key in UNITS else "without a unit"
                        raise self.fail(f"attribute {key!r} is written {want_unit}, not {unit!r}", toks[1])
            else:
                value = str(toks[0])
            want = {"c": "pair", "s": "word"}.get(key, "number")
            if val.data != want:
                kind = {"pair": "a pair (x,y)", "word": "a word", "number": "a number"}[want]
                raise self.fail(f"attribute {key!r} must be {kind}", key_tok)
            if key in ("A", "L") and (not float(value).is_integer()):  # type: ignore[arg-type]
                raise self.fail(f"attribute {key!r} must be an integer", key_tok)
            out[key] = (value, key_tok)
        return out

    def node_attrs(self, at: dict[str, tuple[object, Token]], where: Token, *, required: bool) -> dict[str, Any]:
        if required:
            missing = [k for k in ("A", "c", "z") if k not in at]
            if missing:
                raise self.fail(f"missing attribute(s) {', '.join(missing)} (area, center, depth)", where)

        def get(k: str, default: object) -> object:
            return at[k][0] if k in at else default

        def opt(k: str) -> float | None:
            return float(at[k][0]) if k in at else None  # type: ignore[arg-type]

        return {
            "area": int(get("A", 0)),  # type: ignore[call-overload]
            "center_xy": get("c", (0.0, 0.0)),
            "depth": float(get("z", 0.0)),  # type: ignore[arg-type]
            "v_radial": opt("v"),
            "ttc": opt("ttc"),
            "status": at["s"][0] if "s" in at else None,
        }

    def p_object(self, t: Tree[Token], parent: int) -> Node:
        kind_tok, id_tok, term, *rest = t.children
        assert isinstance(kind_tok, Token) and isinstance(id_tok, Token) and isinstance(term, Tree)
        if str(kind_tok) == ROOT_KIND:
            raise self.fail(f"{ROOT_KIND} is the start symbol and cannot be an object's kind", kind_tok)
        nid = int(id_tok)
        if nid == 0:
            raise self.fail("object ids start at 1 (0 is the root Bkg)", id_tok)
        if nid in self.ids:
            raise self.fail(f"object id {nid} appears twice", id_tok)
        self.ids.add(nid)
        tt = [c for c in term.children if isinstance(c, Token)]
        label = int(str(tt[0])[2:])
        if term.data == "run":
            last = int(tt[1])
            if last <= label:
                raise self.fail(f"a compound o_{label}..{last} must end above its first label", tt[1])
            parts: tuple[int, ...] = tuple(range(label, last + 1))
        elif term.data == "part_list":
            parts = tuple(int(x) for x in tt[1:])
        else:
            parts = ()
        attrs_t = next((c for c in rest if isinstance(c, Tree) and c.data == "attrs"), None)
        kids_t = next((c for c in rest if isinstance(c, Tree) and c.data == "children"), None)
        values = self.node_attrs(self.attrs(attrs_t, root=False), kind_tok, required=True)
        kid_trees = [c for c in kids_t.children if isinstance(c, Tree)] if kids_t is not None else []
        kids = tuple(self.p_object(c, nid) for c in kid_trees)
        return Node(id=nid, kind=str(kind_tok), depth_label=label, parts=parts, children=kids, **values)

    def relations(self, t: Tree[Token] | None) -> tuple[Relation, ...]:
        if t is None:
            return ()
        out = []
        for r in t.children:
            assert isinstance(r, Tree)
            a_tok, rel_tok, b_tok = r.children
            assert isinstance(a_tok, Token) and isinstance(rel_tok, Token) and isinstance(b_tok, Token)
            if str(rel_tok) not in RELATIONS:
                raise self.fail(f"unknown relation {str(rel_tok)!r} (expected one of {', '.join(RELATIONS)})", rel_tok)
            for tok in (a_tok, b_tok):
                if int(tok) not in self.ids:
                    raise self.fail(f"relation names object {int(tok)}, which is not in the sentence", tok)
            out.append(Relation(int(a_tok), str(rel_tok), int(b_tok)))
        return tuple(out)

    def sentence(self, t: Tree[Token]) -> SceneTree:
        (bkg,) = t.children
        assert isinstance(bkg, Tree)
        bkg_tok = bkg.children[0]
        assert isinstance(bkg_tok, Token)
        attrs_t = next((c for c in bkg.children if isinstance(c, Tree) and c.data == "attrs"), None)
        rel_t = next((c for c in bkg.children if isinstance(c, Tree) and c.data == "relations"), None)
        at = self.attrs(attrs_t, root=True)
        values = self.node_attrs(at, bkg_tok, required=False)
        label = int(at["L"][0]) if "L" in at else ROOT_LABEL  # type: ignore[call-overload]
        kids = tuple(self.p_object(c, 0) for c in bkg.children if isinstance(c, Tree) and c.data == "p_object")
        root = Node(id=0, kind=ROOT_KIND, depth_label=label, children=kids, **values)
        return SceneTree(root=root, relations=self.relations(rel_t))


_NAMED = {
    "NAME": "a name",
    "INT": "an integer",
    "NUMBER": "a number",
    "TERMINAL": "o_<label>",
    "BKG": "'Bkg'",
    "$END": "the end of the line",
}


def _readable(terminal: str) -> str:
    if terminal in _NAMED:
        return _NAMED[terminal]
    try:
        return repr(_parser().get_terminal(terminal).pattern.value)
    except KeyError:
        return terminal


def _describe(exc: UnexpectedInput) -> str:
    if isinstance(exc, UnexpectedCharacters):
        return f"unexpected character {exc.char!r}"
    if isinstance(exc, UnexpectedEOF):
        return "the sentence ends too early"
    if isinstance(exc, UnexpectedToken):
        if exc.token.type == "$END":
            got = "the end of the line"
        else:
            got = repr(str(exc.token))
        want = sorted(_readable(name) for name in exc.expected)
        return f"unexpected {got}; expected one of {', '.join(want)}" if want else f"unexpected {got}"
    return "invalid sentence"


def _parse_line(text: str, line: int, source: str) -> SceneTree:
    try:
        lt = _parser().parse(text)
    except UnexpectedInput as exc:
        col = getattr(exc, "column", None)
        at_end = isinstance(exc, UnexpectedToken) and exc.token.type == "$END"
        # lark places the end of input on the last token; point just past the text instead.
        if at_end or not isinstance(col, int) or col < 1:
            col = len(text.rstrip()) + 1
        raise SentenceError(_describe(exc), text=text, line=line, column=col, source=source) from None
    return _Reader(text, line, source).sentence(lt)


def parse_sentence(text: str, *, source: str = "<sentence>", first_line: int = 1) -> SceneTree:
    """Read one sentence back into a :class:`SceneTree`.

    Parameters
    ----------
    text : str
        One sentence (leading and trailing blank lines are ignored).
    source : str
        Name used in error messages (a file name, say).
    first_line : int
        Line number of the text's first line in ``source``, for error messages.

    Raises
    ------
    SentenceError
        When the text is not exactly one valid sentence; ``.line`` and ``.column`` point at
        the offending character.
    """
    lines = [(i + first_line, s) for i, s in enumerate(text.splitlines()) if s.strip()]
    if not lines:
        raise SentenceError(
            "empty text: expected a sentence starting with Bkg", text="", line=first_line, column=1, source=source
        )
    if len(lines) > 1:
        n, s = lines[1]
        raise SentenceError(
            "expected one sentence, found a second line (use parse_sentences)", text=s, line=n, column=1, source=source
        )
    n, s = lines[0]
    return _parse_line(s, n, source)


def parse_sentences(text: str | Iterable[str], *, source: str = "<sentences>") -> list[SceneTree]:
    """Read one tree per non-empty line.

    Parameters
    ----------
    text : str or iterable of str
        The sentences, one per line (or already split into lines).
    source : str
        Name used in error messages.

    Raises
    ------
    SentenceError
        At the first invalid line, with its line number in ``text`` and the column.
    """
    lines = text.splitlines() if isinstance(text, str) else [s.rstrip("\n") for s in text]
    return [_parse_line(s, i + 1, source) for i, s in enumerate(lines) if s.strip()]
