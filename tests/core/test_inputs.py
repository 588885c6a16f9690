"""Small files a command is given are read within a size and a depth limit
(service.core.inputs): what is too large is refused without being read whole, what nests
too deeply without a traceback; a pipe is read like a file."""

from __future__ import annotations

import json
import os
import threading
from pathlib import Path

import pytest

from service.core.errors import InvalidInput
from service.core.inputs import MAX_JSON_DEPTH, json_depth, read_json_file


def test_a_small_file_within_the_limits_is_read(tmp_path: Path) -> None:
    path = tmp_path / "p.json"
    document = {"ego": {"accel_max": 2.0}, "list": [[[1]]]}
    path.write_text(json.dumps(document))
    assert read_json_file(path, "parameters") == document
    assert json_depth(document, MAX_JSON_DEPTH) == 4 and json_depth(1, MAX_JSON_DEPTH) == 0


def test_the_size_limit_reads_no_more_than_it_allows(tmp_path: Path) -> None:
    zero = tmp_path / "zero.json"
    zero.symlink_to("/dev/zero")
    with pytest.raises(InvalidInput, match=r"parameters .*zero.json is larger than 100 bytes"):
        read_json_file(zero, "parameters", max_bytes=100)
    exact = tmp_path / "exact.json"
    exact.write_text(" " * 98 + "{}")
    assert read_json_file(exact, "parameters", max_bytes=100) == {}


def test_nesting_beyond_the_limit_is_refused_however_deep(tmp_path: Path) -> None:
    path = tmp_path / "deep.json"
    for depth in (MAX_JSON_DEPTH + 1, 100_000):
        path.write_text("[" * depth + "]" * depth)
        with pytest.raises(InvalidInput, match=f"nested more than {MAX_JSON_DEPTH} levels"):
            read_json_file(path, "parameters")
    path.write_text("[" * MAX_JSON_DEPTH + "]" * MAX_JSON_DEPTH)
    assert json_depth(read_json_file(path, "parameters"), MAX_JSON_DEPTH) == MAX_JSON_DEPTH


@pytest.mark.parametrize(
    ("content", "message"),
    [(b"\xff{}", "is not UTF-8"), (b"{", "is not JSON"), (b"", "is not JSON")],
)
def test_what_is_not_json_is_named(content: bytes, message: str, tmp_path: Path) -> None:
    path = tmp_path / "bad.json"
    path.write_bytes(content)
    with pytest.raises(InvalidInput, match=message):
        read_json_file(path, "parameters")
    with pytest.raises(InvalidInput, match=r"cannot read parameters .*missing\.json"):
        read_json_file(tmp_path / "missing.json", "parameters")


def test_a_pipe_is_read_like_a_file(tmp_path: Path) -> None:
    """Process substitution (--rss-params <(...)) gives a pipe: read to its end."""
    fifo = tmp_path / "pipe.json"
    os.mkfifo(fifo)
    writer = threading.Thread(target=lambda: fifo.write_text('{"a": 1}'))
    writer.start()
    assert read_json_file(fifo, "parameters") == {"a": 1}
    writer.join()
