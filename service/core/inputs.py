"""Small files a command is given (parameters, a signal program), read with a size limit
and a depth limit, as the API's bodies are: a link to ``/dev/zero`` or JSON nested 100,000
deep is one line of bad input (InvalidInput), not a machine out of memory or a traceback.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from service.core.errors import InvalidInput

MAX_PARAMETER_FILE_BYTES = 1_000_000  # a parameter file (--rss-params, --signals as JSON)
MAX_JSON_DEPTH = 32  # nested arrays and objects; scengen's own documents need 6


def read_bounded(
    path: Path, what: str, max_bytes: int, check_start: Callable[[bytes], None] | None = None
) -> bytes:
    """The bytes of ``path`` (a file, a pipe: read, never more than ``max_bytes`` + 1);
    InvalidInput naming ``what`` when it cannot be read or is larger. ``check_start`` sees
    the first 64 kB before the rest is read (and may refuse them)."""
    try:
        with Path(path).open("rb") as stream:
            data = stream.read(min(max_bytes + 1, 65_536))
            if check_start is not None:
                check_start(data)
            if len(data) == 65_536:
                data += stream.read(max_bytes + 1 - len(data))
    except OSError as exc:
        raise InvalidInput(f"cannot read {what} {path}: {exc.strerror or exc}") from None
    if len(data) > max_bytes:
        raise InvalidInput(f"{what} {path} is larger than {max_bytes:,} bytes, the limit")
    return data


def parse_json(data: bytes | str, what: str, max_depth: int = MAX_JSON_DEPTH) -> Any:
    """JSON of at most ``max_depth`` nested arrays and objects; InvalidInput naming
    ``what`` otherwise."""
    try:
        value = json.loads(data)
    except UnicodeDecodeError as exc:
        raise InvalidInput(f"{what} is not UTF-8 ({exc.reason})") from None
    except json.JSONDecodeError as exc:
        raise InvalidInput(f"{what} is not JSON: {exc}") from None
    except RecursionError:
        value = None
        depth = max_depth + 1
    else:
        depth = json_depth(value, max_depth)
    if depth > max_depth:
        raise InvalidInput(f"{what} is nested more than {max_depth} levels deep, the limit")
    return value


def json_depth(value: Any, stop: int) -> int:
    """How deep arrays and objects nest in ``value`` (0 for a number), counted up to
    ``stop`` + 1 (no recursion)."""
    deepest, level = 0, [(value, 1)]
    while level:
        item, depth = level.pop()
        if not isinstance(item, dict | list):
            continue
        children = item.values() if isinstance(item, dict) else item
        deepest = max(deepest, depth)
        if deepest > stop:
            return deepest
        level.extend((child, depth + 1) for child in children)
    return deepest


def read_json_file(
    path: Path,
    what: str,
    max_bytes: int = MAX_PARAMETER_FILE_BYTES,
    max_depth: int = MAX_JSON_DEPTH,
) -> Any:
    """A small JSON file a command is given, read within both limits (InvalidInput)."""
    return parse_json(read_bounded(path, what, max_bytes), f"{what} {path}", max_depth)
