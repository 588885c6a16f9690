"""The service's persistent state: uploaded networks, stored test-cases and evaluations.

One relational schema behind SQLAlchemy Core, so the same code runs on the embedded SQLite
file and on PostgreSQL (``SCENGEN_DATABASE_URL``). The database is authoritative: a network's
bytes live in it too, and ``network_file`` materialises them into a local cache on demand, so
any process that can reach the database can work on any stored object.
"""

from __future__ import annotations

import hashlib
import json
import re
import secrets
from collections.abc import Collection, Iterator
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Generic, TypeVar

import sqlalchemy as sa

from service.core.errors import UnknownNetwork, choices
from service.core.network import bundled_networks, file_sha256
from service.core.testcase import (
    MAX_SAMPLES,
    NetworkRef,
    TestCase,
    check_samples,
    dump_testcase,
    parse_testcase,
    testcase_level,
    without_network_path,
)

T = TypeVar("T")
metadata = sa.MetaData()

networks = sa.Table(
    "networks",
    metadata,
    sa.Column("id", sa.String(80), primary_key=True),
    sa.Column("filename", sa.String(255), nullable=False),
    sa.Column("sha256", sa.String(64), nullable=False),
    sa.Column("controls", sa.Text, nullable=False),  # JSON: junction -> control type
    sa.Column("size", sa.Integer, nullable=False),
    sa.Column("content", sa.LargeBinary, nullable=False),
    sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
)

# The original file of a network imported from another format (the network itself is
# the converted .net.xml, in networks)
network_sources = sa.Table(
    "network_sources",
    metadata,
    sa.Column("id", sa.String(80), primary_key=True),  # the network's id
    sa.Column("filename", sa.String(255), nullable=False),
    sa.Column("format", sa.String(20), nullable=False),  # opendrive | openstreetmap
    sa.Column("sha256", sa.String(64), nullable=False),
    sa.Column("content", sa.LargeBinary, nullable=False),
)

testcases = sa.Table(
    "testcases",
    metadata,
    sa.Column("id", sa.String(32), primary_key=True),
    sa.Column("network", sa.String(80), nullable=False, index=True),
    sa.Column("junction", sa.String(255), nullable=False),
    sa.Column("parent", sa.String(32), nullable=True, index=True),
    sa.Column("name", sa.Text, nullable=False),
    sa.Column("nonegos", sa.Integer, nullable=False),
    sa.Column("document", sa.Text, nullable=False),
    sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
    # added later: NULL in a row an older version stored, filled in when it is first read
    sa.Column("level", sa.Integer, nullable=True),
    sa.Column("duration", sa.Float, nullable=True),
)

evaluations = sa.Table(
    "evaluations",
    metadata,
    sa.Column("id", sa.String(32), primary_key=True),
    sa.Column("testcase", sa.String(32), nullable=False, index=True),
    sa.Column("controller", sa.String(255), nullable=False),
    sa.Column("passed", sa.Boolean, nullable=False),
    sa.Column("verdict", sa.Text, nullable=False),  # Verdict.to_dict() as JSON
    sa.Column("seconds", sa.Float, nullable=False),
    sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
)

# The ego's drive of an evaluation (its replay), apart from the verdict: rows of
# [t, x, y, heading, speed, distance], the centre of the ego's footprint
DRIVE_COLUMNS = ["t", "x", "y", "heading", "speed", "distance"]
drives = sa.Table(
    "evaluation_drives",
    metadata,
    sa.Column("id", sa.String(32), primary_key=True),  # the evaluation's id
    sa.Column("trajectory", sa.Text, nullable=False),  # JSON
)


def now() -> datetime:
    return datetime.now(UTC)


def utc(moment: datetime) -> datetime:
    """SQLite hands back naive datetimes; every stored time is UTC."""
    return moment if moment.tzinfo is not None else moment.replace(tzinfo=UTC)


def add_missing_columns(engine: sa.Engine) -> None:
    """Add the columns a newer version added to a table of an older database (each such
    column is nullable: the rows stored before hold NULL there). Safe when several
    processes start at once: a column another one added meanwhile is fine."""
    inspector = sa.inspect(engine)
    for table in metadata.sorted_tables:
        present = {column["name"] for column in inspector.get_columns(table.name)}
        for column in table.columns:
            if column.name in present:
                continue
            kind = column.type.compile(engine.dialect)
            try:
                with engine.begin() as connection:
                    connection.exec_driver_sql(
                        f"ALTER TABLE {table.name} ADD COLUMN {column.name} {kind}"
                    )
            except sa.exc.DBAPIError:
                added = {c["name"] for c in sa.inspect(engine).get_columns(table.name)}
                if column.name not in added:
                    raise


def summary_of(document: str) -> tuple[int, float]:
    """The level and the duration of a stored test-case document (read, not validated)."""
    data = json.loads(document)
    level = max((int(car["added_in"]) for car in data.get("nonegos", [])), default=0)
    return level, float(data.get("duration", 20.0))


def testcase_id(document: str) -> str:
    """Content address of a test-case: the same bytes are the same stored test-case."""
    return hashlib.sha256(document.encode()).hexdigest()[:16]


def network_id(filename: str, content: bytes, controls: dict[str, str]) -> str:
    """``<file stem>-<12 hex>`` over the bytes and the control overrides."""
    stem = re.sub(r"[^A-Za-z0-9_.-]+", "-", filename.removesuffix(".xml").removesuffix(".net"))
    digest = hashlib.sha256(content + json.dumps(controls, sort_keys=True).encode())
    return f"{stem.strip('-.')[:60] or 'network'}-{digest.hexdigest()[:12]}"


def safe_filename(name: str) -> str:
    """A file name without directories or odd characters, ending in .net.xml."""
    stem = re.sub(r"[^A-Za-z0-9_.-]+", "-", Path(name).name).strip("-.")
    stem = stem.removesuffix(".xml").removesuffix(".net") or "network"
    return f"{stem[:80]}.net.xml"


@dataclass(frozen=True)
class NetworkRecord:
    id: str
    filename: str
    sha256: str
    controls: dict[str, str]
    size: int
    created_at: datetime | None  # None for a bundled network
    bundled: bool
    source: dict[str, str] | None = None  # imported: format, filename, sha256 of the original

    def junction_and_control(
        self, junction: str | None, control: str | None
    ) -> tuple[str | None, str | None]:
        """The junction and control type a request means: a stored override of the named
        junction, or the only overridden junction when none is named (None: let the
        loader decide, or name the choices)."""
        if control is None and junction is not None:
            control = self.controls.get(junction)
        if control is None and junction is None and len(self.controls) == 1:
            junction, control = next(iter(self.controls.items()))
        return junction, control


@dataclass(frozen=True)
class TestCaseRecord:
    id: str
    network: str
    junction: str
    parent: str | None
    name: str
    nonegos: int
    document: str
    created_at: datetime
    level: int  # of the extension that added its last cars; 0: the ego alone
    duration: float  # seconds

    @property
    def testcase(self) -> TestCase:
        return parse_testcase(self.document)


@dataclass(frozen=True)
class StoredTestCase:
    """A test-case as the store keeps it: its document's text and the columns beside it
    (``stored_form``). Made where the document is parsed anyway (a worker process, for a
    large one), it lets a server store and answer a test-case without parsing it again."""

    id: str
    document: str
    network: NetworkRef
    junction: str
    name: str
    nonegos: int
    level: int
    duration: float
    timestep: float


def stored_form(testcase: TestCase) -> StoredTestCase:
    """What the store keeps of ``testcase``. A network's ``path`` is where a file on a
    client's disk found its network: no place on the server, so it is not kept, and the
    same test-case has the same id wherever it was written."""
    kept = without_network_path(testcase)
    document = dump_testcase(kept)
    return StoredTestCase(
        id=testcase_id(document),
        document=document,
        network=kept.network,
        junction=testcase.junction,
        name=testcase.name,
        nonegos=len(testcase.nonegos),
        level=testcase_level(testcase),
        duration=testcase.duration,
        timestep=testcase.timestep,
    )


@dataclass(frozen=True)
class EvaluationRecord:
    id: str
    testcase: str
    controller: str
    passed: bool
    verdict: dict[str, Any]
    seconds: float
    created_at: datetime


@dataclass(frozen=True)
class Page(Generic[T]):
    items: list[T]
    total: int


class Store:
    """Every read and write of the service's state; safe to share within one process."""

    def __init__(self, url: str, cache_dir: Path, max_samples: int = MAX_SAMPLES) -> None:
        self.url = url
        self.cache_dir = cache_dir
        self.max_samples = max_samples  # per car, in test-cases clients send (SCENGEN_MAX_SAMPLES)
        if url.startswith("sqlite:///"):
            Path(url.removeprefix("sqlite:///")).parent.mkdir(parents=True, exist_ok=True)
        connect_args = (
            {"check_same_thread": False, "timeout": 30} if url.startswith("sqlite") else {}
        )
        self.engine = sa.create_engine(url, connect_args=connect_args, pool_pre_ping=True)
        metadata.create_all(self.engine)
        add_missing_columns(self.engine)

    def ping(self) -> None:
        with self.engine.connect() as connection:
            connection.execute(sa.text("SELECT 1"))

    def close(self) -> None:
        self.engine.dispose()

    # networks

    def add_network(
        self,
        filename: str,
        content: bytes,
        controls: dict[str, str],
        source: tuple[str, str, bytes] | None = None,
    ) -> NetworkRecord:
        """Store an uploaded network (idempotent: the same bytes and overrides, the same id).
        ``source``: the format, file name and bytes of the map it was converted from; the id
        is then made from those bytes."""
        ident = network_id(*(source[1:] if source else (filename, content)), controls)
        existing = self.network(ident)
        if existing is not None:
            return existing
        row = {
            "id": ident,
            "filename": safe_filename(filename),
            "sha256": hashlib.sha256(content).hexdigest(),
            "controls": json.dumps(controls, sort_keys=True),
            "size": len(content),
            "content": content,
            "created_at": now(),
        }
        try:
            with self.engine.begin() as connection:
                connection.execute(networks.insert().values(**row))
                if source is not None:
                    kind, name, original = source
                    connection.execute(
                        network_sources.insert().values(
                            id=ident, filename=Path(name).name[:255], format=kind,
                            sha256=hashlib.sha256(original).hexdigest(), content=original,
                        )
                    )  # fmt: skip
        except sa.exc.IntegrityError:
            pass  # uploaded concurrently: the same bytes and overrides, the same network
        found = self.network(ident)
        assert found is not None
        return found

    def network(self, ident: str) -> NetworkRecord | None:
        """A bundled or uploaded network, or None."""
        bundled = bundled_networks()
        if ident in bundled:
            return _bundled_record(ident, bundled[ident])
        columns = [c for c in networks.c if c.name != "content"]
        with self.engine.connect() as connection:
            row = connection.execute(sa.select(*columns).where(networks.c.id == ident)).first()
            source = connection.execute(
                sa.select(network_sources.c.format, network_sources.c.filename,
                          network_sources.c.sha256).where(network_sources.c.id == ident)
            ).first()  # fmt: skip
        return None if row is None else _network_record(row._mapping, source)

    def network_source(self, ident: str) -> tuple[str, bytes] | None:
        """The original file (name, bytes) of an imported network, or None."""
        with self.engine.connect() as connection:
            row = connection.execute(
                sa.select(network_sources.c.filename, network_sources.c.content).where(
                    network_sources.c.id == ident
                )
            ).first()
        return None if row is None else (row.filename, row.content)

    def list_networks(self) -> list[NetworkRecord]:
        columns = [c for c in networks.c if c.name != "content"]
        with self.engine.connect() as connection:
            rows = connection.execute(sa.select(*columns).order_by(networks.c.created_at))
            sources = {
                row.id: row
                for row in connection.execute(
                    sa.select(network_sources.c.id, network_sources.c.format,
                              network_sources.c.filename, network_sources.c.sha256)
                )
            }  # fmt: skip
            uploaded = [_network_record(row._mapping, sources.get(row.id)) for row in rows]
        bundled = [_bundled_record(name, path) for name, path in bundled_networks().items()]
        return bundled + uploaded

    def network_file(self, ident: str) -> Path:
        """A local path to the network's bytes (bundled file, or the cached upload)."""
        bundled = bundled_networks()
        if ident in bundled:
            return bundled[ident]
        with self.engine.connect() as connection:
            row = connection.execute(
                sa.select(networks.c.filename, networks.c.content).where(networks.c.id == ident)
            ).first()
        if row is None:
            raise KeyError(ident)
        path = self.cache_dir / "networks" / ident / safe_filename(row.filename)
        if not path.is_file():
            path.parent.mkdir(parents=True, exist_ok=True)
            partial = path.with_suffix(f".{secrets.token_hex(4)}.part")
            partial.write_bytes(row.content)
            partial.replace(path)
        return path

    def network_file_for(self, testcase: TestCase) -> Path:
        """The local file of a test-case's network, which must be bundled or uploaded: by
        its id, or (a test-case made from a file, which names it by file name) by the
        content hash of an uploaded network."""
        return self.network_file(self.network_id_for(testcase))

    def network_file_of(self, network: NetworkRef) -> Path:
        """``network_file_for`` a test-case's network reference."""
        return self.network_file(self.network_id_of(network))

    def network_id_for(self, testcase: TestCase) -> str:
        """The id of a test-case's network here (``network_file_for``); UnknownNetwork
        when it is neither bundled nor uploaded."""
        return self.network_id_of(testcase.network)

    def network_id_of(self, network: NetworkRef) -> str:
        """``network_id_for`` a test-case's network reference."""
        ident = network.ref
        if self.network(ident) is None:
            with self.engine.connect() as connection:
                same = connection.execute(
                    sa.select(networks.c.id)
                    .where(networks.c.sha256 == network.sha256)
                    .order_by(networks.c.created_at, networks.c.id)
                ).first()
            if same is None:
                known = [n.id for n in self.list_networks()]
                raise UnknownNetwork(
                    f"network.ref: {ident!r} is neither bundled nor uploaded here (no uploaded "
                    f"network has its sha256 either); upload it with POST /networks first. "
                    f"Known networks: {choices(known)}",
                    network=ident,
                )
            ident = same.id
        return str(ident)

    def check_inline(self, document: dict[str, Any]) -> TestCase:
        """A test-case a client sent inline, validated, within this server's limits, on a
        network this service has (InvalidTestCase or UnknownNetwork otherwise)."""
        testcase = parse_testcase(document)
        check_samples(testcase.duration, testcase.timestep, self.max_samples)
        self.network_id_for(testcase)
        return testcase

    def keep_inline(self, document: dict[str, Any]) -> TestCaseRecord:
        """Store a test-case a client sent inline (nothing submitted is lost), after
        ``check_inline``."""
        return self.add_testcase(self.check_inline(document))

    def delete_network(self, ident: str) -> None:
        with self.engine.begin() as connection:
            connection.execute(networks.delete().where(networks.c.id == ident))
            connection.execute(network_sources.delete().where(network_sources.c.id == ident))

    # test-cases

    def add_testcase(self, testcase: TestCase, parent: str | None = None) -> TestCaseRecord:
        """Store a test-case under its content address (idempotent; ``stored_form``)."""
        return self.add_stored(stored_form(testcase), parent)

    def add_stored(self, stored: StoredTestCase, parent: str | None = None) -> TestCaseRecord:
        """Store a test-case in its stored form (idempotent: the same bytes, the same
        record). The document is written, never read back."""
        existing = self.testcase_head(stored.id)
        if existing is None:
            row = {
                "id": stored.id,
                "network": stored.network.ref,
                "junction": stored.junction,
                "parent": parent,
                "name": stored.name,
                "nonegos": stored.nonegos,
                "document": stored.document,
                "created_at": now(),
                "level": stored.level,
                "duration": stored.duration,
            }
            try:
                with self.engine.begin() as connection:
                    connection.execute(testcases.insert().values(**row))
            except sa.exc.IntegrityError:
                pass  # stored concurrently by another request: the same bytes, the same record
            existing = self.testcase_head(stored.id)
            assert existing is not None
        return replace(existing, document=stored.document)

    def stored_testcases(self, idents: Collection[str]) -> set[str]:
        """Which of ``idents`` are stored test-cases (one query, no document read)."""
        if not idents:
            return set()
        with self.engine.connect() as connection:
            query = sa.select(testcases.c.id).where(testcases.c.id.in_(sorted(idents)))
            return set(connection.execute(query).scalars())

    def testcase(self, ident: str) -> TestCaseRecord | None:
        with self.engine.connect() as connection:
            row = connection.execute(sa.select(testcases).where(testcases.c.id == ident)).first()
        if row is None:
            return None
        found = dict(row._mapping)
        if found["level"] is None or found["duration"] is None:  # stored by an older version
            found["level"], found["duration"] = self._fill_summary(ident, found["document"])
        return _testcase_record(found)

    def testcase_head(self, ident: str) -> TestCaseRecord | None:
        """A test-case's record without its document (``document`` is empty): whether it
        exists, and what a summary shows, without reading its trajectories."""
        query = sa.select(*[c for c in testcases.c if c.name != "document"])
        with self.engine.connect() as connection:
            row = connection.execute(query.where(testcases.c.id == ident)).first()
        if row is None:
            return None
        found = dict(row._mapping)
        if found["level"] is None or found["duration"] is None:  # stored by an older version
            found["level"], found["duration"] = self._fill_summaries([ident])[ident]
        return _testcase_record({**found, "document": ""})

    def _fill_summary(self, ident: str, document: str) -> tuple[int, float]:
        """The level and duration of a row an older version stored, written into it."""
        level, duration = summary_of(document)
        with self.engine.begin() as connection:
            connection.execute(
                testcases.update()
                .where(testcases.c.id == ident)
                .values(level=level, duration=duration)
            )
        return level, duration

    def _fill_summaries(self, idents: list[str]) -> dict[str, tuple[int, float]]:
        if not idents:
            return {}
        with self.engine.connect() as connection:
            rows = list(
                connection.execute(
                    sa.select(testcases.c.id, testcases.c.document).where(
                        testcases.c.id.in_(idents)
                    )
                )
            )
        return {row.id: self._fill_summary(row.id, row.document) for row in rows}

    def list_testcases(
        self,
        network: str | None = None,
        parent: str | None = None,
        roots_only: bool = False,
        limit: int = 50,
        offset: int = 0,
    ) -> Page[TestCaseRecord]:
        """Newest first; the records carry no document (``document`` is empty): a page of
        summaries must not load every trajectory."""
        query = sa.select(*[c for c in testcases.c if c.name != "document"])
        if network is not None:
            query = query.where(testcases.c.network == network)
        if parent is not None:
            query = query.where(testcases.c.parent == parent)
        if roots_only:
            query = query.where(testcases.c.parent.is_(None))
        counted = sa.select(sa.func.count()).select_from(query.subquery())
        ordered = query.order_by(testcases.c.created_at.desc(), testcases.c.id)
        with self.engine.connect() as connection:
            total = connection.execute(counted).scalar_one()
            rows = connection.execute(ordered.limit(limit).offset(offset))
            found = [dict(row._mapping) for row in rows]
        missing = [row["id"] for row in found if row["level"] is None or row["duration"] is None]
        filled = self._fill_summaries(missing)  # rows an older version stored
        for row in found:
            if row["id"] in filled:
                row["level"], row["duration"] = filled[row["id"]]
        return Page([_testcase_record({**row, "document": ""}) for row in found], total)

    def children(self, ident: str) -> list[TestCaseRecord]:
        return self.list_testcases(parent=ident, limit=1000).items

    def ancestors(self, ident: str) -> Iterator[TestCaseRecord]:
        """The parent, its parent, ... up to a test-case without one (without documents,
        as ``testcase_head``)."""
        seen = {ident}
        record = self.testcase_head(ident)
        while record is not None and record.parent is not None and record.parent not in seen:
            seen.add(record.parent)
            record = self.testcase_head(record.parent)
            if record is not None:
                yield record

    def count_testcases_on(self, network: str) -> int:
        return self.list_testcases(network=network, limit=1).total

    def delete_testcase(self, ident: str) -> None:
        with self.engine.begin() as connection:
            judged = sa.select(evaluations.c.id).where(evaluations.c.testcase == ident)
            connection.execute(drives.delete().where(drives.c.id.in_(judged)))
            connection.execute(evaluations.delete().where(evaluations.c.testcase == ident))
            connection.execute(testcases.delete().where(testcases.c.id == ident))

    # evaluations

    def add_evaluation(
        self,
        testcase: str,
        controller: str,
        verdict: dict[str, Any],
        seconds: float,
        ident: str | None = None,
        drive: list[list[float]] | str | None = None,
    ) -> EvaluationRecord:
        """Store a verdict, and the ego's ``drive`` when given (rows, or their JSON text);
        with ``ident`` (a job item's), at most once."""
        if ident is not None:
            existing = self.evaluation(ident)
            if existing is not None:
                return existing
        row = {
            "id": ident or secrets.token_hex(8),
            "testcase": testcase,
            "controller": controller,
            "passed": bool(verdict["passed"]),
            "verdict": json.dumps(verdict, sort_keys=True),
            "seconds": seconds,
            "created_at": now(),
        }
        try:
            with self.engine.begin() as connection:
                connection.execute(evaluations.insert().values(**row))
                if drive is not None:
                    trajectory = (
                        drive
                        if isinstance(drive, str)
                        else json.dumps(drive, separators=(",", ":"))
                    )
                    connection.execute(drives.insert().values(id=row["id"], trajectory=trajectory))
        except sa.exc.IntegrityError:
            if ident is None:
                raise
            found = self.evaluation(ident)  # stored concurrently by a duplicate delivery
            assert found is not None
            return found
        return EvaluationRecord(**{**row, "verdict": verdict})  # type: ignore[arg-type]

    def evaluation(self, ident: str) -> EvaluationRecord | None:
        with self.engine.connect() as connection:
            row = connection.execute(
                sa.select(evaluations).where(evaluations.c.id == ident)
            ).first()
        return None if row is None else _evaluation_record(row._mapping)

    def drive(self, ident: str) -> list[list[float]] | None:
        """The ego's drive of an evaluation, or None (stored before drives were kept)."""
        found = self.drive_text(ident)
        return None if found is None else list(json.loads(found))

    def drive_text(self, ident: str) -> str | None:
        """``drive`` as its stored JSON text (compact), not parsed."""
        with self.engine.connect() as connection:
            found = connection.execute(
                sa.select(drives.c.trajectory).where(drives.c.id == ident)
            ).scalar()
        return None if found is None else str(found)

    def evaluations_passed(self, idents: list[str]) -> list[bool]:
        """Whether each stored evaluation among ``idents`` passed (one query)."""
        if not idents:
            return []
        with self.engine.connect() as connection:
            return list(
                connection.execute(
                    sa.select(evaluations.c.passed).where(evaluations.c.id.in_(idents))
                ).scalars()
            )

    def list_evaluations(
        self, testcase: str | None = None, limit: int = 50, offset: int = 0
    ) -> Page[EvaluationRecord]:
        query = sa.select(evaluations)
        if testcase is not None:
            query = query.where(evaluations.c.testcase == testcase)
        counted = sa.select(sa.func.count()).select_from(query.subquery())
        ordered = query.order_by(evaluations.c.created_at.desc(), evaluations.c.id)
        with self.engine.connect() as connection:
            total = connection.execute(counted).scalar_one()
            rows = connection.execute(ordered.limit(limit).offset(offset))
            return Page([_evaluation_record(row._mapping) for row in rows], total)


def _bundled_record(name: str, path: Path) -> NetworkRecord:
    return NetworkRecord(name, path.name, file_sha256(path), {}, path.stat().st_size, None, True)


def _network_record(row: Any, source: Any = None) -> NetworkRecord:
    return NetworkRecord(
        row["id"],
        row["filename"],
        row["sha256"],
        json.loads(row["controls"]),
        row["size"],
        utc(row["created_at"]),
        False,
        None
        if source is None
        else {"format": source.format, "filename": source.filename, "sha256": source.sha256},
    )


def _testcase_record(row: Any) -> TestCaseRecord:
    return TestCaseRecord(**{**row, "created_at": utc(row["created_at"])})


def _evaluation_record(row: Any) -> EvaluationRecord:
    return EvaluationRecord(
        **{**row, "verdict": json.loads(row["verdict"]), "created_at": utc(row["created_at"])}
    )
