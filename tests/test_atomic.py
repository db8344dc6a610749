"""Outputs that respect what they write to (issue 32.1): regular files atomically, devices and FIFOs directly."""

from __future__ import annotations

import os
import stat
import threading
from pathlib import Path

import pytest

from depthgram.atomic import atomic_open, atomic_path
from depthgram.cli import main


def test_a_regular_file_is_replaced_whole_and_keeps_no_temporary(tmp_path: Path) -> None:
    out = tmp_path / "a.txt"
    out.write_text("old", encoding="utf-8")
    with atomic_open(out) as fh:
        fh.write("new")
        assert out.read_text(encoding="utf-8") == "old"  # not visible before the block ends
    assert out.read_text(encoding="utf-8") == "new"
    assert [p.name for p in tmp_path.iterdir()] == ["a.txt"]


def test_a_new_file_gets_the_permissions_of_any_new_file(tmp_path: Path) -> None:
    plain = tmp_path / "plain.txt"
    plain.write_text("x", encoding="utf-8")
    out = tmp_path / "out.txt"
    with atomic_open(out) as fh:
        fh.write("x")
    # a temporary file made private (mkstemp's 0600) must not leave the output private
    assert stat.S_IMODE(out.stat().st_mode) == stat.S_IMODE(plain.stat().st_mode)


def test_replacing_keeps_the_files_permissions(tmp_path: Path) -> None:
    out = tmp_path / "out.txt"
    out.write_text("old", encoding="utf-8")
    out.chmod(0o640)
    with atomic_open(out) as fh:
        fh.write("new")
    assert stat.S_IMODE(out.stat().st_mode) == 0o640


def test_a_symlink_is_followed_not_replaced(tmp_path: Path) -> None:
    target = tmp_path / "target.txt"
    target.write_text("old", encoding="utf-8")
    link = tmp_path / "link.txt"
    link.symlink_to(target)
    with atomic_open(link) as fh:
        fh.write("new")
    assert link.is_symlink() and target.read_text(encoding="utf-8") == "new"


@pytest.fixture
def null_device(tmp_path: Path) -> str:
    """A character device like /dev/null: a private copy when we may make one, else /dev/null itself.

    Run as root, a regression would replace the machine's /dev/null with a regular file (the bug
    of issue 32.1 did, for every process on it), so root tests a node of its own.
    """
    node = tmp_path / "null"
    try:
        os.mknod(node, 0o666 | stat.S_IFCHR, os.stat("/dev/null").st_rdev)
        with open(node, "w", encoding="utf-8") as fh:
            fh.write("")
    except OSError:
        return "/dev/null"
    return str(node)


def test_a_character_device_stays_one(null_device: str) -> None:
    # issue 32.1: `describe --json /dev/null` as root replaced /dev/null with a regular file
    before = os.stat(null_device)
    assert stat.S_ISCHR(before.st_mode)
    with atomic_path(null_device) as p:
        assert str(p) == null_device  # written in place: a device cannot be renamed over
        p.write_text("discarded", encoding="utf-8")
    with atomic_open(null_device) as fh:
        fh.write("discarded")
    after = os.stat(null_device)
    assert stat.S_ISCHR(after.st_mode) and after.st_rdev == before.st_rdev and after.st_ino == before.st_ino


def test_describe_to_a_character_device_writes_through_it(null_device: str) -> None:
    before = os.stat(null_device)
    assert main(["describe", "sim:approach?frames=2", "--quiet", "--json", null_device]) == 0
    after = os.stat(null_device)
    assert stat.S_ISCHR(after.st_mode) and after.st_ino == before.st_ino


def _reader(fifo: Path, got: list[bytes]) -> threading.Thread:
    def read() -> None:
        with open(fifo, "rb") as fh:
            got.append(fh.read())

    t = threading.Thread(target=read, daemon=True)
    t.start()
    return t


def test_a_fifo_is_streamed_to_its_reader(tmp_path: Path) -> None:
    fifo = tmp_path / "f"
    os.mkfifo(fifo)
    got: list[bytes] = []
    t = _reader(fifo, got)
    with atomic_open(fifo) as fh:
        fh.write("line 1\nline 2\n")
    t.join(timeout=60)
    assert got == [b"line 1\nline 2\n"]
    assert stat.S_ISFIFO(fifo.stat().st_mode) and [p.name for p in tmp_path.iterdir()] == ["f"]


def test_describe_into_a_fifo_reaches_its_reader(tmp_path: Path) -> None:
    # issue 32.1: `mkfifo f; (cat f > got) & depthgram describe ... --json f` gave the reader nothing
    fifo = tmp_path / "f"
    os.mkfifo(fifo)
    got: list[bytes] = []
    t = _reader(fifo, got)
    assert main(["describe", "sim:approach?frames=3", "--quiet", "--json", str(fifo)]) == 0
    t.join(timeout=60)
    lines = got[0].decode().splitlines()
    assert len(lines) == 3 and all(line.startswith("{") for line in lines)
    assert stat.S_ISFIFO(fifo.stat().st_mode)


def test_two_writers_of_one_file_both_finish_and_leave_one_whole_file(tmp_path: Path) -> None:
    # issue 32.1: the temporary name was fixed, so two runs writing one file raced and one failed
    out = tmp_path / "scenes.jsonl"
    inside = threading.Barrier(2)
    texts = {n: f"writer {n}\n" * 20000 for n in (1, 2)}
    errors: list[BaseException] = []

    def write(n: int) -> None:
        try:
            with atomic_open(out) as fh:
                inside.wait(timeout=60)  # both temporaries are open at once
                for line in texts[n].splitlines(keepends=True):
                    fh.write(line)
        except BaseException as exc:  # reported by the assertion below
            errors.append(exc)

    threads = [threading.Thread(target=write, args=(n,)) for n in (1, 2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=120)
    assert errors == []
    assert out.read_text(encoding="utf-8") in texts.values()
    assert [p.name for p in tmp_path.iterdir()] == ["scenes.jsonl"]


def test_a_failed_write_removes_its_unique_temporary(tmp_path: Path) -> None:
    out = tmp_path / "a.png"
    with pytest.raises(RuntimeError), atomic_path(out) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".png" and tmp != out
        tmp.write_bytes(b"half")
        raise RuntimeError("killed mid-write")
    assert list(tmp_path.iterdir()) == []


def test_a_unix_socket_is_streamed_to_its_listener(tmp_path: Path) -> None:
    import socket

    path = tmp_path / "s"
    got: list[bytes] = []
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as server:
        server.bind(str(path))
        server.listen(1)

        def accept() -> None:
            conn, _ = server.accept()
            with conn:
                chunks = []
                while chunk := conn.recv(65536):
                    chunks.append(chunk)
                got.append(b"".join(chunks))

        t = threading.Thread(target=accept, daemon=True)
        t.start()
        with atomic_open(path) as fh:
            fh.write("over the socket\n")
        t.join(timeout=60)
    assert got == [b"over the socket\n"] and stat.S_ISSOCK(path.stat().st_mode)
