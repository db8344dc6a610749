"""``depthgram parse``: one JSON line per sentence; bad sentences give file, line, column, exit 2."""

from __future__ import annotations

import io
import json

from tests.test_scene_sentence import EXAMPLE

from depthgram.cli import main
from depthgram.scene import parse_sentence, tree_from_dict


def test_parse_file_prints_json_lines(tmp_path, capsys):
    path = tmp_path / "scenes.txt"
    second = "Bkg[A=12,c=(1.5,1.0),z=0.0] -> object#1 o_0[A=3,c=(1.0,1.0),z=800.0]"
    path.write_text(f"{EXAMPLE}\n\n{second}\n")
    assert main(["parse", str(path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 2
    assert tree_from_dict(json.loads(lines[0])) == parse_sentence(EXAMPLE)
    assert tree_from_dict(json.loads(lines[1])) == parse_sentence(second)


def test_parse_stdin(monkeypatch, capsys):
    monkeypatch.setattr("sys.stdin", io.StringIO(EXAMPLE + "\n"))
    assert main(["parse", "-"]) == 0
    (line,) = capsys.readouterr().out.splitlines()
    assert json.loads(line)["relations"] == [[2, "left_of", 4], [3, "occludes", 2]]


def test_bad_sentence_names_file_line_column(tmp_path, capsys):
    path = tmp_path / "bad.txt"
    path.write_text(f"{EXAMPLE}\n{EXAMPLE.replace('left_of', 'leftof')}\n")
    assert main(["parse", str(path)]) == 2
    captured = capsys.readouterr()
    assert len(captured.out.splitlines()) == 1  # the good first line was printed
    column = EXAMPLE.index("left_of") + 1
    assert f"{path}:2:{column}: unknown relation 'leftof'" in captured.err
    assert "^" in captured.err


def test_missing_file(tmp_path, capsys):
    assert main(["parse", str(tmp_path / "nope.txt")]) == 2
    assert "no such file" in capsys.readouterr().err
