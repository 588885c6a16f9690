"""Files written whole or not at all: a temporary file beside the target, then a rename.

An interrupted command (Ctrl-C, a killed process, a full disk) then leaves either the old
file or none, never half a file that a later command would read as a broken document.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Iterator
from pathlib import Path


@contextlib.contextmanager
def replacing(path: Path) -> Iterator[Path]:
    """A temporary path beside ``path`` (same folder, same suffix, so that writers that
    choose their format by the suffix still do) for the caller to write; it becomes
    ``path`` when the block ends without an error, and is removed otherwise."""
    while True:
        temporary = path.parent / f".{path.name[:200]}.{secrets.token_hex(4)}.partial{path.suffix}"
        try:  # the mode a plain open() gives (0o666 less the umask), unlike mkstemp's 0o600
            os.close(os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            break
        except FileExistsError:
            continue
    try:
        yield temporary
        temporary.replace(path)
    finally:
        temporary.unlink(missing_ok=True)


def write_atomically(path: Path, data: str | bytes) -> None:
    """Write ``data`` (text as UTF-8) to ``path`` whole or not at all."""
    content = data.encode() if isinstance(data, str) else data
    with replacing(path) as temporary, temporary.open("wb") as stream:
        stream.write(content)
        stream.flush()
        os.fsync(stream.fileno())
