"""Where a test-case's network is found, and how a document names it (its reference, its
content hash, its file's path relative to the document)."""

from __future__ import annotations

import hashlib
import os
import stat
from collections.abc import Sequence
from pathlib import Path, PurePosixPath

from service.core.errors import InvalidTestCase, UnknownNetwork
from service.core.network import bundled_networks, file_sha256, resolve_network
from service.core.network.convert import FORMATS, source_format
from service.core.testcase.document import dump_testcase
from service.core.testcase.model import NetworkRef, TestCase

# Where this process has read a non-bundled network from, by content hash: a test-case
# names such a network by its file name (no machine's paths), and a library caller that made
# it from a path can go on without saying the path again.
_READ_FROM: dict[str, Path] = {}


def network_ref(network: str | Path) -> NetworkRef:
    """How a test-case names a network: a bundled short name; else the path as given when
    it is relative (to the working directory), or the file's name: never an absolute path
    of this machine. The content hash identifies the file wherever it is."""
    path = resolve_network(network)
    digest = file_sha256(path)
    name = str(network)
    if bundled_networks().get(name) == path:
        return NetworkRef(ref=name, sha256=digest)
    _READ_FROM[digest] = path
    given = Path(network)
    named = given if source_format(given) else path  # an imported map: its own name
    return NetworkRef(ref=named.name if given.is_absolute() else given.as_posix(), sha256=digest)


def local_network_name(ref: str) -> str:
    """The file name a network has next to a test-case that names it ``ref`` (where
    ``scengen export`` puts it): the reference's file name; a server's network id gets the
    ``.net.xml`` suffix."""
    name = PurePosixPath(ref).name
    return name if name.endswith(".xml") else f"{name}.net.xml"


def with_network_path(testcase: TestCase, network_file: Path | None, folder: Path) -> TestCase:
    """``testcase`` as it is written into ``folder``: its network's ``path`` is
    ``network_file`` relative to that folder, so that the test-case finds the file from
    wherever it is read, and moving both together keeps it so. A bundled network (found by
    name anywhere) and a test-case without a known file get no path."""
    path = None
    if network_file is not None and testcase.network.ref not in bundled_networks():
        path = Path(os.path.relpath(network_file.resolve(), folder.resolve())).as_posix()
    if path == testcase.network.path:
        return testcase
    network = testcase.network.model_copy(update={"path": path})
    return testcase.model_copy(update={"network": network})


def without_network_path(testcase: TestCase) -> TestCase:
    """``testcase`` without its network's ``path``: the same test-case wherever it was
    written (a server stores it so, and a parent's hash is taken of it)."""
    return with_network_path(testcase, None, Path())


def document_sha256(testcase: TestCase) -> str:
    """The hash of a test-case's document, the same wherever the file was written."""
    return hashlib.sha256(dump_testcase(without_network_path(testcase)).encode()).hexdigest()


def find_network_file(
    testcase: TestCase,
    network_file: Path | None = None,
    near: Path | None = None,
    search_path: Sequence[Path] = (),
) -> tuple[Path, str]:
    """The file of a test-case's network (a map as it is, not converted) and how it was
    found. The places, in order: the network's ``path`` from ``near`` (the folder the
    test-case was read from); a file of its name in ``near``; ``network_file``; a file of
    its name in a folder of ``search_path``; the bundled network of that name; the
    reference as a path from the working directory (older test-cases); a file this process
    made a test-case from. The first whose bytes have the test-case's sha256 wins; when
    files are found but none has it, InvalidTestCase names each file and both hashes."""
    candidates = _network_candidates(testcase, network_file, near, search_path)
    ref, digest = testcase.network.ref, testcase.network.sha256
    reasons = [(path, how, _not_read(path, how)) for path, how in candidates]
    candidates = [(path, how) for path, how, why in reasons if why is None]
    # a reference that is no file name (a server's network id) was only a guess: not named
    refused = [
        (path, how, why)
        for path, how, why in reasons
        if why is not None and (how, why) != ("as named", _NO_NETWORK_NAME)
    ]
    present = [(path, how) for path, how in candidates if path.is_file()]
    found = [(path, how, file_sha256(resolve_network(path))) for path, how in present]
    for path, how, sha256 in found:
        if sha256 == digest:
            return path.resolve(), how
    if found:
        others = "; ".join(f"{path.resolve()} ({how}) has sha256 {sha}" for path, how, sha in found)
        raise InvalidTestCase(
            f"network.sha256: the test-case was made on {ref} with sha256 {digest}, but "
            f"{others}: the network has changed since; pass the file it was made on "
            "with --network FILE"
        )
    looked = ", ".join(f"{path.resolve()} ({how})" for path, how in candidates)
    skipped = "".join(f"; {path} ({how}) was not read: {why}" for path, how, why in refused)
    raise UnknownNetwork(
        f"network {ref!r} (sha256 {digest[:12]}...) is not at {looked}{skipped}: pass its "
        "file with --network FILE, or name its folder in SCENGEN_NETWORK_PATH",
        network=ref,
    )


# What the document names (its network's path, its reference as a path) is read only when
# it is a network's file: by its name (and the name a link points to) and a regular file,
# checked without opening it. /etc/shadow or a FIFO is never read, nor its digest printed.
_FROM_THE_DOCUMENT = ("its path from the test-case", "as named")
_NETWORK_SUFFIXES = (".net.xml", *FORMATS)
_NO_NETWORK_NAME = f"a network's file name ends in {', '.join(_NETWORK_SUFFIXES)}"


def _not_read(path: Path, how: str) -> str | None:
    """Why a place the document names is not read (None: it may be)."""
    if how not in _FROM_THE_DOCUMENT:
        return None
    names = (path.name, path.resolve().name)
    if not all(name.lower().endswith(_NETWORK_SUFFIXES) for name in names):
        return _NO_NETWORK_NAME
    try:
        mode = path.stat().st_mode
    except OSError:
        return None  # nothing there: looked for, not found
    return None if stat.S_ISREG(mode) else "not a regular file"


def _network_candidates(
    testcase: TestCase, network_file: Path | None, near: Path | None, search_path: Sequence[Path]
) -> list[tuple[Path, str]]:
    """Where ``find_network_file`` looks, in order, each place once."""
    ref = testcase.network.ref
    names = [local_network_name(ref)]
    if source_format(ref):  # the map itself, converted again
        names.append(PurePosixPath(ref).name)
    candidates: list[tuple[Path, str]] = []
    if near is not None:
        if testcase.network.path is not None:
            candidates.append((near / testcase.network.path, "its path from the test-case"))
        candidates += [(near / name, "next to the test-case") for name in names]
    if network_file is not None:
        candidates.append((network_file, "given with --network"))
    for folder in search_path:
        candidates += [(folder / name, "on SCENGEN_NETWORK_PATH") for name in names]
    if ref in bundled_networks():
        candidates.append((bundled_networks()[ref], "bundled"))
    else:
        candidates.append((Path(ref), "as named"))
    if testcase.network.sha256 in _READ_FROM:
        candidates.append((_READ_FROM[testcase.network.sha256], "read before by this process"))
    unique: dict[Path, tuple[Path, str]] = {}
    for path, how in candidates:  # next to the test-case and as named can be one place
        unique.setdefault(path.resolve(), (path, how))
    return list(unique.values())
