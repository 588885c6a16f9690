"""Co-simulation over TraCI: a test-case run in SUMO as a TraCI server for two clients.

scengen is client order 1: it scripts every other road user exactly as the replay does
(run.py's loop, ``drive``). The driving stack under test is client order 2: it connects to
HOST:PORT, calls ``setOrder(2)`` and drives the vehicle ``ego`` with any TraCI command it
likes, or with none (then SUMO's own driver drives, as ``--controller sumo``). A step
advances only when both clients have asked for it, so the stack may take as long as it
needs per step. The run ends when the ego has passed its goal (it leaves the simulation)
or the test-case's duration is over; then SUMO closes the connection.

SUMO's TraCI server listens on every interface and cannot be told otherwise, so SUMO
listens on a free port of its own and a relay listens on HOST:PORT (127.0.0.1 unless told
otherwise): it passes the stack's bytes to SUMO and back, and tells when the stack has left.

Standalone like run.py (the standard library and SUMO's traci only): every bundle ships it
beside run.py (``python run.py --cosim PORT``), and ``scengen cosim`` runs the same code.
"""

from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

CLIENT_ORDER = 2  # the driving stack's setOrder
CMD_CLOSE = 0x7F  # TraCI's close command (traci.constants.CMD_CLOSE)
SCENGEN_ORDER = 1
SUMO_START = 60.0  # seconds SUMO may take to load the network and listen
Row = dict[str, float]


class ClientFault(Exception):
    """The driving stack's fault: it never came, left before the end, or took the ego off
    its route. No verdict on the ego."""


class ListenFailed(Exception):
    """HOST:PORT cannot be listened on (taken, or not an address of this machine)."""


class BudgetOver(Exception):
    """The run went on past its budget (counted from the client's arrival): no verdict."""


class Relay:
    """Listens on ``host``:``port`` for the driving stack and, once it came, passes its
    bytes to SUMO and back (one thread each way)."""

    def __init__(self, host: str, port: int) -> None:
        self.host = host
        self._listener = socket.create_server((host, port))  # OSError: the port is taken
        self.port = int(self._listener.getsockname()[1])
        self.left = threading.Event()  # the stack closed its connection
        self._sockets: list[socket.socket] = []

    def accept(self, wait: float) -> None:
        """Wait up to ``wait`` seconds for the stack; ClientFault if it does not come."""
        self._listener.settimeout(wait)
        try:
            client, _ = self._listener.accept()
        except TimeoutError:
            raise ClientFault(
                f"no TraCI client came to {self.host}:{self.port} within {wait:g} s "
                "(--wait); nothing was judged"
            ) from None
        finally:
            self._listener.close()
        client.settimeout(None)
        client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._sockets.append(client)

    def connect(self, sumo: socket.socket) -> None:
        """Join the stack's connection to ``sumo`` (a connection to SUMO's own port)."""
        client = self._sockets[0]
        self._sockets.append(sumo)
        for source, target, ended in ((client, sumo, self.left), (sumo, client, None)):
            threading.Thread(target=_pump, args=(source, target, ended), daemon=True).start()

    def close(self) -> None:
        self._listener.close()
        for connection in self._sockets:
            with contextlib.suppress(OSError):
                connection.shutdown(socket.SHUT_RDWR)
            connection.close()


def _pump(source: socket.socket, target: socket.socket, ended: threading.Event | None) -> None:
    """Copy ``source`` to ``target`` until ``source`` ends; then end ``target``'s writing.
    ``ended`` (the stack's side): set when the stack closes, before SUMO can know it (a
    TraCI close command is seen before it is passed on), so that scengen's next step finds
    it set whatever the threads' timing."""
    closes = CloseWatch()
    try:
        while data := source.recv(65536):
            if ended is not None and closes.seen_in(data):
                ended.set()
            target.sendall(data)
    except OSError:
        pass
    finally:
        if ended is not None:
            ended.set()
        with contextlib.suppress(OSError):
            target.shutdown(socket.SHUT_WR)


class CloseWatch:
    """Reads a TraCI client's bytes as its messages (a 4-byte length, then commands of a
    1-byte length, or 0 and a 4-byte length, and an id) and tells when one holds the
    close command."""

    def __init__(self) -> None:
        self._pending = b""
        self._lost = False  # bytes that are no TraCI message: nothing more to read

    def seen_in(self, data: bytes) -> bool:
        """Whether the messages ``data`` completes hold a close command."""
        self._pending += data
        found = False
        while not self._lost and len(self._pending) >= 4:
            size = int.from_bytes(self._pending[:4], "big")
            if size < 4:
                self._lost = True
            elif len(self._pending) < size:
                break
            else:
                message, self._pending = self._pending[4:size], self._pending[size:]
                found = found or _holds_close(message)
        return found


def _holds_close(message: bytes) -> bool:
    offset = 0
    while offset + 1 < len(message):
        length, command = message[offset], message[offset + 1]
        if length == 0 and offset + 6 <= len(message):  # a long command
            length = int.from_bytes(message[offset + 1 : offset + 5], "big")
            command = message[offset + 5]
        if command == CMD_CLOSE:
            return True
        if length <= 0:
            return False
        offset += length
    return False


def free_port() -> int:
    """A port free on this machine now (for SUMO's own server)."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def connect_to_sumo(port: int, process: subprocess.Popen[bytes]) -> socket.socket:
    """A connection to SUMO's server once it listens (it loads the network first). Only
    refused attempts are retried: SUMO counts every accepted connection as a client."""
    deadline = time.monotonic() + SUMO_START
    while True:
        if process.poll() is not None:
            raise RuntimeError(f"SUMO ended before it listened (exit code {process.returncode})")
        try:
            connection = socket.create_connection(("127.0.0.1", port))
        except ConnectionRefusedError:
            if time.monotonic() > deadline:
                raise RuntimeError(f"SUMO did not listen within {SUMO_START:g} s") from None
            time.sleep(0.02)
            continue
        connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        return connection


def route_keeper(relay: Relay) -> Callable[[Any, Row, set[str]], str | None]:
    """The runner's ``on_step`` for a co-simulation: ClientFault when the stack has left,
    or when the ego is on a road that is not on its route (a junction's internal lanes
    between two of its roads are on it)."""
    route: list[str] = []

    def step(traci: Any, row: Row, present: set[str]) -> str | None:
        if relay.left.is_set():
            raise ClientFault(
                f"the TraCI client closed its connection at {row['t']:.2f} s, before the "
                "ego passed its goal or the test-case ended; nothing was judged"
            )
        if not route:
            route.extend(traci.vehicle.getRoute("ego"))
        road = traci.vehicle.getRoadID("ego")
        if not road.startswith(":") and road not in route:
            raise ClientFault(
                f"the ego left its route at {row['t']:.2f} s: it is on road {road!r}, its "
                f"route is {' '.join(route)} (a moveToXY maps it onto its route with "
                "keepRoute=1); nothing was judged"
            )
        return None

    return step


def cosimulate(
    runner: Any,
    traci: Any,
    plan_file: Path,
    program: str,
    host: str,
    port: int,
    wait: float,
    budget: float,
    say: Callable[[str], None],
) -> list[Row]:
    """Run the plan as a co-simulation (``runner``: run.py's module, ``traci``: SUMO's
    traci package, ``program``: the sumo binary) and return the ego's rows. ClientFault,
    BudgetOver, ListenFailed. SUMO and the relay
    are gone afterwards, whatever happened (Ctrl-C included)."""
    plan = runner.load_plan(plan_file)
    controller = plan["controllers"]["sumo"]  # the ego's driver when the stack sends nothing
    try:
        relay = Relay(host, port)
    except OverflowError:  # socket's word for a port out of range
        raise ListenFailed(f"--port {port} is not a port: give 1 to 65535, or 0 for any free "
                           "port") from None  # fmt: skip
    except OSError as exc:
        raise ListenFailed(
            f"cannot listen on {host}:{port}: {exc.strerror or exc} (another program listens "
            "there, or the address is not this machine's: choose another --port or --host)"
        ) from None
    over = threading.Event()
    process: subprocess.Popen[bytes] | None = None
    timer: threading.Timer | None = None
    connection = None
    try:
        with tempfile.TemporaryDirectory(prefix="scengen-cosim-") as scratch:
            types = runner.write_types(plan, plan_file.parent, controller,
                                       Path(scratch) / "types.xml")  # fmt: skip
            sumo_port = free_port()
            arguments = runner.sumo_arguments(plan, plan_file.parent, types)
            process = subprocess.Popen(
                [program, *arguments, "--remote-port", str(sumo_port), "--num-clients", "2"],
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                preexec_fn=_die_with_parent if sys.platform == "linux" else None,
            )  # fmt: skip
            say(f"waiting for a TraCI client with order {CLIENT_ORDER} on {host}:{relay.port}")
            relay.accept(wait)
            relay.connect(connect_to_sumo(sumo_port, process))
            timer = threading.Timer(budget, _expire, (over, process))
            timer.daemon = True
            timer.start()
            connection = traci.connect(sumo_port, 0, "127.0.0.1", process)  # listens: no retries
            connection.getVersion()
            connection.setOrder(SCENGEN_ORDER)
            rows, _ = runner.drive(connection, plan, controller, route_keeper(relay))
            return list(rows)
    except ClientFault:
        raise
    except Exception:
        if over.is_set():
            raise BudgetOver(
                f"the co-simulation ran past its budget of {budget:g} s (--budget); "
                "nothing was judged"
            ) from None
        if relay.left.is_set():  # SUMO's answer to our step never came: the client left
            raise ClientFault(
                "the TraCI client closed its connection before the ego passed its goal or "
                "the test-case ended; nothing was judged"
            ) from None
        raise
    finally:
        if timer is not None:
            timer.cancel()
        if process is not None:
            # as service.core.budget.kill_and_reap (this module is standalone): a Ctrl-C
            # inside Popen.poll() can leave Popen's lock held, and wait() would never return
            process.kill()
            try:
                process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ChildProcessError):
                    os.waitpid(process.pid, 0)
        if connection is not None:
            with contextlib.suppress(Exception):  # SUMO is gone: the goodbye cannot arrive
                connection.close(wait=False)
        relay.close()


def _die_with_parent() -> None:
    """In SUMO's process before it starts (Linux): SUMO is killed when the process that
    started it dies, however it dies (a SIGKILL leaves no SUMO waiting for clients)."""
    import ctypes
    import signal

    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG


def _expire(over: threading.Event, process: subprocess.Popen[bytes]) -> None:
    """The budget is over: kill SUMO, so that every call blocked on its sockets returns."""
    over.set()
    process.kill()


def bundle_main(runner: Any, traci: Any, program: str, args: Any) -> int:
    """``python run.py --cosim PORT``: the co-simulation of a bundle, without scengen. The
    ego's trajectory is written as FCD for ``scengen check``. Exit 0 with the trajectory, 2
    when HOST:PORT cannot be listened on, 3 past the budget or when SUMO fails, 4 the
    client's fault."""

    def say(line: str) -> None:
        print(f"run.py: {line}", file=sys.stderr, flush=True)

    try:
        rows = cosimulate(runner, traci, args.plan, program, args.host, args.cosim, args.wait,
                          args.budget, say)  # fmt: skip
    except ListenFailed as exc:
        say(str(exc))
        return 2
    except ClientFault as exc:
        say(str(exc))
        return 4
    except BudgetOver as exc:
        say(str(exc))
        return 3
    except Exception as exc:  # SUMO's own errors: TraCIException, FatalTraCIError, ...
        say(f"SUMO failed: {exc}")
        return 3
    args.fcd_output.write_text(runner.fcd_text(rows))
    say(f"the TraCI client drove the ego until {rows[-1]['t'] if rows else 0.0:.2f} s; "
        f"wrote {args.fcd_output}")  # fmt: skip
    return 0
