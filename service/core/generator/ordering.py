"""Step 2: choose the order of events with clingo and clingo-dl (asp/extension.lp, time_dl.lp).

Old non-egos keep their numeric times (their mutual order is given as facts); new non-egos
and the two certificate egos get time symbols, and clingo chooses the perceptible order of
every pair of their events that matters to a rule or to the no-collision requirement, and
whether each stops at a stop sign. Every time symbol is also an integer time in ms under
difference constraints (clingo-dl): old cars' numbers, each symbolic car's least travel
times between its events (service.core.motion.kinematics), the duration, and every chosen relation
with its safety margin. So each answer set comes with event times that meet the necessary
conditions of a speed profile, and an order whose times are inconsistent is never proposed.
Answer sets are drawn lazily, one at a time; search is limited by counts, never by a clock.
The facts it is given are service.core.generator.ordering_facts'.
"""

from __future__ import annotations

import functools
from collections.abc import Collection, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import clingo
import clingo.ast
from clingodl import ClingoDLTheory

from service.core.checker.rules import (
    asp_dir,
    rule_set_file,
)
from service.core.generator.ordering_facts import (
    CarKind,
    Limits,
    OrderingCar,
    QueueBounds,
    ordering_facts,
    stop_symbol,
)
from service.core.network import Intersection

GROUPS = ("complexity", "solvability", "noCollision")
GROUP_EXPLANATIONS = {
    "complexity": "no order of events lets an ego pass the old test-case and still violate "
    "a new car's right-of-way",
    "solvability": "no order of events leaves the new test-case solvable",
    "noCollision": "every order that works needs two cars in each other's lanes at once",
}
SOLVE_LIMIT = 200_000  # conflicts clingo may spend on one answer set: a count, not a clock


class SearchLimitReached(Exception):
    """Step 2 spent its work limit on one answer set without deciding it."""


@dataclass(frozen=True)
class Ordering:
    """One answer set: the chosen relations, the chosen stops, and event times (seconds,
    from clingo-dl) that meet every difference constraint."""

    index: int  # its number in the OrderingSearch that drew it (each search counts from 0)
    relations: tuple[tuple[str, clingo.Symbol, clingo.Symbol], ...]  # ("lessThan"|"equal", s, t)
    stops: frozenset[str]
    violated: tuple[tuple[str, str], ...] = field(default=())  # (new car, rule) by "illegal"
    times: tuple[tuple[str, float], ...] = field(default=())  # (symbol, seconds)
    named: tuple[tuple[str, str, str], ...] = field(default=())  # the relations as text
    # the phase instance chosen for each symbolic entry at a signalized junction:
    # ("phaseAt", symbol, instance) and the instance's span in seconds
    phases: tuple[tuple[str, clingo.Symbol, clingo.Symbol], ...] = field(default=())
    spans: tuple[tuple[str, float, float], ...] = field(default=())  # (symbol, start, end)

    def describe(self) -> list[str]:
        return [f"{kind}({a},{b})" for kind, a, b in self.named]


RULE_FILES = ("extension.lp", "time_dl.lp")


@functools.lru_cache(maxsize=16)
def _parsed(files: tuple[str, ...], text: str) -> tuple[clingo.ast.AST, ...]:
    """The statements of the rule files and of ``text``, parsed once per process (every
    search of a chain reads the same files; the theory rewrites each search's copy)."""
    found: list[clingo.ast.AST] = []
    clingo.ast.parse_files(list(files), found.append)
    if text:
        clingo.ast.parse_string(text, found.append)
    return tuple(found)


class OrderingSearch:
    """Answer sets of Step 2, drawn one at a time, each with its event times."""

    def __init__(
        self,
        intersection: Intersection,
        cars: Sequence[OrderingCar],
        m: float,
        seed: int,
        limits: Limits,
        queue: QueueBounds | None = None,
    ) -> None:
        self.cars = {car.car: car for car in cars}
        self.facts, self.symbols = ordering_facts(intersection, cars, m, limits, seed, queue)
        self.theory = self._theory()
        self.control = clingo.Control(
            [
                "--models=0",
                "--warn=none",
                "--heuristic=Domain",
                f"--seed={seed}",
                "--rand-freq=0.02",
                f"--solve-limit={SOLVE_LIMIT}",
                f"--const=m_ms={round(m * 1000)}",
                f"--const=margin_ms={round(limits.margin * 1000)}",
                *self._options(),
            ]
        )
        self.theory.register(self.control)
        files = (str(rule_set_file(intersection.control)), *map(str, self._programs()))
        with clingo.ast.ProgramBuilder(self.control) as builder:
            for statement in _parsed(files, self._program_text()):
                self.theory.rewrite_ast(statement, builder.add)
        with self.control.backend() as backend:
            for fact in self.facts:
                backend.add_rule([backend.add_atom(fact)])
        self.control.ground([("base", [])])
        for group in GROUPS:
            self._enforce(group, True)
        self.symbolic = {c for c, car in self.cars.items() if car.kind is not CarKind.OLD}
        self.spans = {
            instance.index: (instance.start, instance.end)
            for instance in (
                intersection.signals.instances(limits.duration) if intersection.signals else []
            )
        }
        self.drawn = 0
        self.learned = 0
        self._names: dict[clingo.Symbol, tuple[str, str]] = {}

    # The theory of the event times. bench/bench_ordering.py overrides these five to run the
    # same search with clingo-lpx; nothing else differs between the two.
    def _theory(self) -> Any:
        return ClingoDLTheory()  # type: ignore[no-untyped-call]

    def _options(self) -> list[str]:
        return []

    def _programs(self) -> list[Path]:
        return [asp_dir() / name for name in RULE_FILES]

    def _program_text(self) -> str:
        return ""

    def _times(self, model: clingo.Model) -> dict[str, float]:
        """The answer set's times in seconds (clingo-dl assigns whole milliseconds)."""
        return {
            str(name): value / 1000.0
            for name, value in self.theory.assignment(model.thread_id)
            if isinstance(value, int)
        }

    def _enforce(self, group: str, value: bool) -> None:
        self.control.assign_external(clingo.Function("enforce", [clingo.Function(group)]), value)

    def _solve(self) -> tuple[list[clingo.Symbol], dict[str, float]] | None:
        """The first answer set of the program as it stands, with its times."""
        self.theory.prepare(self.control)
        with self.control.solve(yield_=True, on_model=self.theory.on_model) as handle:
            model = next(iter(handle), None)
            if model is None:
                if handle.get().unknown:
                    raise SearchLimitReached(
                        f"Step 2 spent its limit of {SOLVE_LIMIT} conflicts without an answer"
                    )
                return None
            return model.symbols(shown=True), self._times(model)

    def satisfiable(self) -> bool:
        return self._solve() is not None

    def next_ordering(self) -> Ordering | None:
        """The next answer set, or None when there is none left. Each is drawn afresh and
        then blocked, so what Step 3 learns (``forbid``) prunes the search that follows."""
        found = self._solve()
        if found is None:
            return None
        ordering = self._ordering(self.drawn, *found)
        self.drawn += 1
        self.block(ordering)
        return ordering

    def block(self, ordering: Ordering) -> None:
        """Rule out this answer set (its relations and stops) from the search that follows."""
        literals = [f"{kind}({a},{b})" for kind, a, b in (*ordering.named, *ordering.phases)]
        for car in sorted(self.symbolic):
            stop = f'stoppedAtForkAtTime("{car}",_,{stop_symbol(car)})'
            literals.append(stop if car in ordering.stops else f"not {stop}")
        self._add_constraint(literals)

    def block_alike(
        self,
        relations: Sequence[tuple[str, clingo.Symbol, clingo.Symbol]],
        stops: Collection[str],
        cars: Collection[str],
    ) -> None:
        """Rule out every answer set with all of ``relations`` in which, of ``cars``, just
        those of ``stops`` stop at their sign (the answer sets alike in these)."""
        literals = [f"{kind}({a},{b})" for kind, a, b in relations]
        for car in sorted(cars):
            stop = f'stoppedAtForkAtTime("{car}",_,{stop_symbol(car)})'
            literals.append(stop if car in stops else f"not {stop}")
        self._add_constraint(literals)

    def forbid(self, relations: Sequence[tuple[str, clingo.Symbol, clingo.Symbol]]) -> None:
        """Rule out every answer set with all of these relations (they cannot hold together)."""
        self._add_constraint([f"{kind}({a},{b})" for kind, a, b in relations])

    def _add_constraint(self, literals: Sequence[str]) -> None:
        name = f"learned{self.learned}"
        self.learned += 1
        self.control.add(name, [], ":- " + ", ".join(literals) + ".")
        self.control.ground([(name, [])])

    def _named(self, symbol: clingo.Symbol) -> tuple[str, str]:
        """A time symbol's text and car, remembered (each is a call into clingo)."""
        found = self._names.get(symbol)
        if found is None:
            found = self._names[symbol] = (str(symbol), str(symbol.arguments[0].string))
        return found

    def _ordering(
        self, index: int, atoms: Sequence[clingo.Symbol], times: dict[str, float]
    ) -> Ordering:
        relations = []
        stops = set()
        violated = []
        phases = []
        symbolic = self.symbolic
        for atom in atoms:  # only the shown atoms (extension.lp's #show)
            name, arguments = atom.name, atom.arguments
            if name in ("lessThan", "equal"):
                a, b = arguments
                (text_a, car_a), (text_b, car_b) = self._named(a), self._named(b)
                if car_a in symbolic or car_b in symbolic:
                    if name == "equal" and text_a > text_b:
                        continue  # each simultaneity once
                    relations.append(((name, text_a, text_b), (name, a, b)))
            elif name == "stoppedAtForkAtTime" and arguments[0].string in symbolic:
                stops.add(arguments[0].string)
            elif name == "violatesRightOfForRule" and arguments[0].string == "illegal":
                violated.append((arguments[1].string, str(arguments[2])))
            elif name == "phaseAt" and self._named(arguments[0])[1] in symbolic:
                phases.append(("phaseAt", arguments[0], arguments[1]))
        relations.sort(key=lambda pair: pair[0])
        return Ordering(
            index,
            tuple(symbols for _, symbols in relations),
            frozenset(stops),
            tuple(sorted(violated)),
            tuple(sorted(times.items())),
            tuple(named for named, _ in relations),
            tuple(sorted(phases, key=lambda p: str(p[1]))),
            tuple(
                (str(symbol), *self.spans[instance.number])
                for _, symbol, instance in sorted(phases, key=lambda p: str(p[1]))
            ),
        )

    def latest_event(self) -> float | None:
        """The latest symbolic time of the first answer set, in seconds; None when there
        is none."""
        found = self._solve()
        if found is None:
            return None
        events = {str(symbol) for symbol, timed in self.symbols.items()
                  if timed.car in self.symbolic}  # fmt: skip
        return max((t for name, t in found[1].items() if name in events), default=None)

    def explain_unsatisfiable(self) -> str:
        """Which requirement could not be met: the first group whose release makes it SAT."""
        for group in GROUPS:
            self._enforce(group, False)
            satisfiable = self.satisfiable()
            self._enforce(group, True)
            if satisfiable:
                return GROUP_EXPLANATIONS[group]
        return "no order of events meets the requirements even one at a time"
