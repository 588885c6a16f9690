"""Benchmark: Step 2's event times with clingo-dl (asp/time_dl.lp, the project's
OrderingSearch) against clingo-lpx (bench/time_lpx.lp) on the same Step 2 problems.

Run with `.venv/bin/python -m bench.bench_ordering` (needs `pip install clingo-lpx`;
--help for the options). The problems are built as service.core.generator.extension.extend_testcase
builds them (Step 1 poses in SUMO, events, the cars of Step 2, the first share of the
bounds it searches with); the chain of the four-way stop is grown with extend_testcase
itself. For each problem and theory: building the search (facts, parsing, grounding), the
first answer set, and DRAWS answer sets drawn one after another (each blocked before the
next, as the project does), the median of REPEATS runs with the same seed. Then: whether
the theories agree on satisfiability; how many answer sets they share, and whether the
other theory accepts each one (solved under assumptions on a fresh search); whether every
run gives the same answer sets and times (determinism); whether each assignment keeps
every constraint of the problem (decided exactly, in rationals); and the float check of
tests/core/generator/test_ordering.py (every relation with its margin, times in
[0, duration - margin]).

Variants: dl (asp/time_dl.lp), lpx (bench/time_lpx.lp: the same constraints), and
lpx-strict (clingo-lpx's strict mode: equal(S, T) as |s - t| < m - margin over the
rationals instead of <= m - margin - 1 ms; its values carry an infinitesimal epsilon).
"""

from __future__ import annotations

import argparse
import platform
import re
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

import clingo
import clingo.ast
from clingolpx import ClingoLPXTheory

from service.core.generator.additions import (
    automatic_starts,
    new_car_ids,
    ordering_cars,
    queue_of,
    validate_routes,
)
from service.core.generator.extension import STEP1_SPEED, extend_testcase
from service.core.generator.ordering import (
    Ordering,
    OrderingSearch,
    SearchLimitReached,
)
from service.core.generator.ordering_facts import (
    Limits,
    OrderingCar,
    QueueBounds,
    ordering_facts,
    stop_symbol,
)
from service.core.generator.search import SEARCH_SHARES, order_limits
from service.core.generator.verification import checked_judge
from service.core.motion.poses import generate_poses
from service.core.network import Intersection
from service.core.testcase import (
    TestCase,
    dump_testcase,
    load_testcase_intersection,
    new_testcase,
    parse_testcase,
)

REPEATS = 3
DRAWS = 10
SEED = 0
TIME_LPX = Path(__file__).parent / "time_lpx.lp"
STRICT_EQUAL = "&sum{ S; -T } < G :- simultaneous(S, T), G = m_ms - margin_ms."
VARIANTS = ("dl", "lpx", "lpx-strict")

# (name, network, ego route, duration, chain of extensions grown first, routes of the problem)
CASES: list[tuple[str, str, str, float, list[list[str]], list[str]]] = [
    ("4way L1", "4way-stop", "E2C_1:C2S_1", 30.0, [], ["S2C_1:C2N_1"]),
    ("4way L2", "4way-stop", "E2C_1:C2S_1", 30.0, [["S2C_1:C2N_1"]], ["W2C_1:C2E_1"]),
    (
        "4way L3",
        "4way-stop",
        "E2C_1:C2S_1",
        30.0,
        [["S2C_1:C2N_1"], ["W2C_1:C2E_1"]],
        ["S2C_0:C2N_0"],
    ),
    ("t-stop 2 cars", "t-stop", "E2C_0:C2S_0", 25.0, [], ["W2C_0:C2E_0", "S2C_0:C2W_0"]),
    ("Y 2 cars", "y-uncontrolled", "N2C_0:C2SE_0", 25.0, [], ["SW2C_0:C2N_0", "SE2C_0:C2N_0"]),
]


@dataclass(frozen=True)
class Problem:
    """One Step 2 problem: what OrderingSearch is built from."""

    name: str
    intersection: Intersection
    cars: list[OrderingCar]
    m: float
    limits: Limits
    old_cars: int
    queue: QueueBounds


def step2_problem(name: str, old: TestCase, routes: Sequence[str], share: float) -> Problem:
    """The cars of Step 2 for ``routes`` added to ``old``, as extend_testcase builds them."""
    junction = load_testcase_intersection(old)
    judge = checked_judge(old, junction)
    new_routes = validate_routes(old, junction, routes)
    ego_route = junction.route(old.ego.route.id)
    ids = new_car_ids(old, len(new_routes))
    starts, _ = automatic_starts(old, judge, new_routes, None, junction)
    tracks = generate_poses(
        junction,
        [(ego_route, old.ego.start.distance), *zip(new_routes, starts, strict=True)],
        STEP1_SPEED,
        old.duration,
        old.timestep,
        old.ego.length,
        old.ego.width,
    )
    new_tracks = dict(zip(ids, tracks[1:], strict=True))
    cars = ordering_cars(old, judge, junction, tracks[0], new_tracks, new_routes, ids)
    tracks_of = {**new_tracks, "ego": tracks[0], "illegal": tracks[0]}
    queue = queue_of(old, judge, junction, cars, tracks_of, ids)
    limits = order_limits(old, share=share)
    return Problem(name, junction, cars, old.params.m, limits, len(old.nonegos), queue.bounds)


def build_problems(share: float) -> list[Problem]:
    problems = []
    grown: dict[tuple[str, ...], TestCase] = {}
    for name, network, ego, duration, chain, routes in CASES:
        old = new_testcase(network, ego, duration=duration)
        key: tuple[str, ...] = (network, ego)
        for step in chain:
            key += (";".join(step),)
            if key not in grown:
                extension = extend_testcase(old, step, seed=0)
                grown[key] = parse_testcase(dump_testcase(extension.testcase))
            old = grown[key]
        problems.append(step2_problem(name, old, routes, share))
    return problems


# A time in ms: (rational part, coefficient of clingo-lpx's infinitesimal epsilon > 0),
# compared lexicographically; clingo-dl's and non-strict clingo-lpx's have no epsilon.
Exact = tuple[Fraction, Fraction]
NUMBER = re.compile(r"-?\d+(/\d+)?")


def parse_lpx(text: str) -> Exact:
    """clingo-lpx's value of a variable: "1200", "11599/2", and in strict mode "10+e",
    "-1*e", "-5+-1*e" (rational + k*e)."""
    if not text.endswith("e"):
        return Fraction(text), Fraction(0)
    head, _, tail = text.rpartition("+")
    k = tail[: -len("*e")] if tail.endswith("*e") else "1"
    if not NUMBER.fullmatch(k) or (head and not NUMBER.fullmatch(head)):
        raise ValueError(f"unexpected clingo-lpx value {text!r}")
    return Fraction(head or "0"), Fraction(k)


class LpxOrderingSearch(OrderingSearch):
    """The project's OrderingSearch with bench/time_lpx.lp and clingo-lpx in place of
    time_dl.lp and clingo-dl (its theory hooks overridden; the exact assignment of every
    answer set kept); everything else is the project's."""

    def __init__(
        self,
        intersection: Intersection,
        cars: Sequence[OrderingCar],
        m: float,
        seed: int,
        limits: Limits,
        queue: QueueBounds | None = None,
        strict: bool = False,
        options: Sequence[tuple[str, str]] = (),
    ) -> None:
        self.strict, self.lpx_options = strict, options
        self.exact: list[dict[str, Exact]] = []  # the assignment of each answer set drawn
        super().__init__(intersection, cars, m, seed, limits, queue)

    def _theory(self) -> Any:
        theory = ClingoLPXTheory()  # type: ignore[no-untyped-call]
        if self.strict:
            theory.configure("strict", "1")
        for name, value in self.lpx_options:  # clingo-lpx's own options
            theory.configure(name, value)
        return theory

    def _options(self) -> list[str]:
        return [f"--const=strict={int(self.strict)}"]

    def _programs(self) -> list[Path]:
        return [*(p for p in super()._programs() if p.name != "time_dl.lp"), TIME_LPX]

    def _program_text(self) -> str:
        return STRICT_EQUAL if self.strict else ""

    def _times(self, model: clingo.Model) -> dict[str, float]:
        exact = {
            str(name): parse_lpx(value.string)
            for name, value in self.theory.assignment(model.thread_id)
            if isinstance(value, clingo.Symbol)
        }
        self.exact.append(exact)
        # Ordering.times in seconds, as the project's: the rational part (epsilon left out)
        return {name: float(value[0]) / 1000.0 for name, value in exact.items()}


def make_search(
    variant: str, problem: Problem, seed: int, lpx: Sequence[tuple[str, str]] = ()
) -> OrderingSearch:
    args = (problem.intersection, problem.cars, problem.m, seed, problem.limits, problem.queue)
    if variant == "dl":
        return OrderingSearch(*args)
    return LpxOrderingSearch(*args, strict=variant == "lpx-strict", options=lpx)


def exact_times(search: OrderingSearch, ordering: Ordering) -> dict[str, Exact]:
    if isinstance(search, LpxOrderingSearch):
        return search.exact[ordering.index]
    # clingo-dl's times are whole ms, stored as ms / 1000.0: round() recovers them exactly
    return {name: (Fraction(round(t * 1000)), Fraction(0)) for name, t in ordering.times}


def broken_constraints(
    search: OrderingSearch, ordering: Ordering, problem: Problem, strict: bool
) -> list[str]:
    """Every constraint of time_dl.lp (and so of time_lpx.lp) that the assignment breaks,
    decided exactly: rationals, clingo-lpx's epsilon compared lexicographically."""
    times = exact_times(search, ordering)

    def value(symbol: clingo.Symbol) -> Exact:
        if symbol == clingo.Number(0):
            return Fraction(0), Fraction(0)
        return times[str(symbol)]

    def gap(a: clingo.Symbol, b: clingo.Symbol) -> Exact:  # b - a
        (pa, ea), (pb, eb) = value(a), value(b)
        return pb - pa, eb - ea

    def at_least(d: Exact, bound: int) -> bool:
        return d >= (Fraction(bound), Fraction(0))

    def at_most(d: Exact, bound: int) -> bool:
        return d <= (Fraction(bound), Fraction(0))

    m_ms = round(problem.m * 1000)
    margin_ms = round(problem.limits.margin * 1000)
    horizon = next(f.arguments[0].number for f in search.facts if f.match("horizon", 1))
    start = clingo.Number(0)
    found = []
    for fact in search.facts:
        args = fact.arguments
        ok = True
        if fact.match("oldTime", 3):
            ok = at_least(gap(start, args[0]), args[1].number)
            ok = ok and at_most(gap(start, args[0]), args[2].number)
        elif fact.match("symbolicTime", 1):
            ok = at_most(gap(start, args[0]), horizon)
        elif fact.match("minGap", 3) or fact.match("headway", 3):
            ok = at_least(gap(args[0], args[1]), args[2].number)
        elif fact.match("minGapStopped", 4) and args[0].string in ordering.stops:
            ok = at_least(gap(args[1], args[2]), args[3].number)
        elif fact.match("maxGapRunning", 4) and args[0].string not in ordering.stops:
            ok = at_most(gap(args[1], args[2]), args[3].number)
        elif fact.match("maxGapInside", 3):
            ok = at_most(gap(args[0], args[1]), args[2].number)
        elif fact.match("earliest", 2):
            ok = at_least(gap(start, args[0]), args[1].number)
        elif fact.match("latest", 2):
            ok = at_most(gap(start, args[0]), args[1].number)
        elif fact.match("lingerLevel", 3) and not at_most(gap(*args[:2]), args[2].number - 1):
            # the segment lingers (whichever way the answer set chose): what that implies
            ok = all(
                at_least(gap(f.arguments[1], f.arguments[3]), f.arguments[4].number)
                if f.name == "lingerAfter"
                else at_least(gap(f.arguments[3], f.arguments[0]), f.arguments[4].number)
                for f in search.facts
                if (f.match("lingerAfter", 5) or f.match("lingerBefore", 5))
                and f.arguments[:3] == args
            )
        if not ok:
            found.append(f"{fact}")
    for kind, a, b in ordering.relations:
        d = gap(a, b)
        if kind == "lessThan":
            ok = at_least(d, m_ms + margin_ms)
        elif strict:
            bound = (Fraction(m_ms - margin_ms), Fraction(0))
            ok = d < bound and (-d[0], -d[1]) < bound
        else:
            ok = at_most(d, m_ms - margin_ms - 1) and at_least(d, -(m_ms - margin_ms - 1))
        if not ok:
            found.append(f"{kind}({a},{b})")
    return found


def float_check(ordering: Ordering, problem: Problem) -> list[str]:
    """The check of tests/core/generator/test_ordering.py's last test on Ordering.times
    (seconds, floats): every relation with its margin, every time in [0, duration - margin]."""
    times = dict(ordering.times)
    m, margin = problem.m, problem.limits.margin
    found = []
    for kind, a, b in ordering.relations:
        delta = times[str(b)] - times[str(a)]
        if kind == "lessThan" and not delta >= m + margin - 1e-9:
            found.append(f"lessThan({a},{b}): gap {delta:.4f} s")
        if kind == "equal" and not abs(delta) < m - margin:
            found.append(f"equal({a},{b}): gap {delta:.4f} s")
    stops = {str(stop_symbol(car)) for car in ordering.stops}
    for name, t in times.items():
        if not 0 <= t <= problem.limits.duration - margin:
            unused = name.startswith("s(") and name not in stops
            why = " (stop symbol of a car that does not stop: in no constraint but the horizon)"
            found.append(f"{name} = {t:.4f} s outside [0, duration - margin]{why * unused}")
    return found


Key = tuple[tuple[str, ...], tuple[str, ...]]


def key(ordering: Ordering) -> Key:
    return tuple(ordering.describe()), tuple(sorted(ordering.stops))


@dataclass
class Run:
    ground: float  # s: building the search (facts, parsing, grounding)
    first: float  # s: the first answer set
    draws: float  # s: all draws, one after another
    orderings: list[Ordering]
    limit: bool  # a draw hit SOLVE_LIMIT
    broken: list[str]  # constraints broken (exact)
    checked: list[str]  # what the test's float check rejects
    conflicts: int


def run_once(
    variant: str, problem: Problem, seed: int, draws: int, lpx: Sequence[tuple[str, str]]
) -> Run:
    started = time.perf_counter()
    search = make_search(variant, problem, seed, lpx)
    grounded = time.perf_counter()
    marks = []
    orderings: list[Ordering] = []
    limit = False
    conflicts = 0  # clingo's statistics are per solve call: summed over the draws
    for _ in range(draws):
        try:
            ordering = search.next_ordering()
        except SearchLimitReached:
            limit = True
            ordering = None
        marks.append(time.perf_counter())
        conflicts += int(search.control.statistics["solving"]["solvers"]["conflicts"])
        if ordering is None:
            break
        orderings.append(ordering)
    strict = variant == "lpx-strict"
    broken = [
        f"#{o.index}: {f}"
        for o in orderings
        for f in broken_constraints(search, o, problem, strict)
    ]
    checked = [f"#{o.index}: {f}" for o in orderings for f in float_check(o, problem)]
    return Run(
        grounded - started,
        marks[0] - grounded,
        marks[-1] - grounded,
        orderings,
        limit,
        broken,
        checked,
        conflicts,
    )


def accepts(search: OrderingSearch, ordering: Ordering) -> bool:
    """Whether ``search`` (a fresh one, of the other theory) has an answer set with this
    one's relations and stops: solved under assumptions, so nothing is added to it."""
    atoms = search.control.symbolic_atoms
    assumptions: list[tuple[clingo.Symbol, bool]] = []
    for kind, a, b in ordering.relations:
        atom = clingo.Function(kind, [a, b])
        if atoms[atom] is None:
            return False  # never even ground: the other program cannot choose it
        assumptions.append((atom, True))
    for atom in atoms.by_signature("stoppedAtForkAtTime", 3):
        car = atom.symbol.arguments[0].string
        if car in search.symbolic:
            assumptions.append((atom.symbol, car in ordering.stops))
    search.theory.prepare(search.control)

    def first_only(model: clingo.Model) -> bool:  # stop there: the free choices of
        search.theory.on_model(model)  # lingers(P, Q, L) give many models per answer set
        return False

    result = search.control.solve(assumptions=assumptions, on_model=first_only)
    return bool(result.satisfiable)


def median(runs: Sequence[Run], field: Callable[[Run], float]) -> float:
    return statistics.median(field(r) for r in runs)


def lpx_option(text: str) -> tuple[str, str]:
    name, _, value = text.partition("=")
    return name, value


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=REPEATS)
    parser.add_argument("--draws", type=int, default=DRAWS)
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument(
        "--share",
        type=float,
        default=SEARCH_SHARES[0],
        help="share of the bounds Step 2 times with (extend_testcase tries "
        f"{', '.join(map(str, SEARCH_SHARES))} in turn)",
    )
    parser.add_argument("--variants", default=",".join(VARIANTS))
    parser.add_argument(
        "--lpx",
        type=lpx_option,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a clingo-lpx option for the lpx variants, e.g. select=match "
        "(propagate-bounds=changed|full corrupted the heap in our runs)",
    )
    options = parser.parse_args()
    variants = options.variants.split(",")
    started = time.perf_counter()
    problems = build_problems(options.share)
    print(f"built {len(problems)} problems in {time.perf_counter() - started:.1f} s")
    lpx = " ".join(f"--{n}={v}" for n, v in options.lpx) or "defaults"
    print(
        f"\n{date_line()}; seed {options.seed}, share {options.share:g} of the bounds, "
        f"median of {options.repeats} runs, {options.draws} draws; clingo-lpx {lpx}\n"
    )
    print(
        "| problem | symbols | theory | ground ms | first ms | draws ms | draws × dl | found "
        "| SAT | answer sets vs dl | deterministic | conflicts | constraints kept "
        "| test check |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    notes: list[str] = []
    for problem in problems:
        symbols = len([f for f in ordering_facts_of(problem) if f.match("symbolicTime", 1)])
        results = {
            variant: [
                run_once(variant, problem, options.seed, options.draws, options.lpx)
                for _ in range(options.repeats)
            ]
            for variant in variants
        }
        reference_name = "dl" if "dl" in results else variants[0]
        reference = results[reference_name]
        base = [key(o) for o in reference[0].orderings]
        base_draws = median(reference, lambda r: r.draws)
        for variant, runs in results.items():
            keys = [key(o) for o in runs[0].orderings]
            same_runs = all(
                [key(o) for o in r.orderings] == keys
                and [o.times for o in r.orderings] == [o.times for o in runs[0].orderings]
                for r in runs
            )
            if runs is reference:
                same = "-"
            elif keys == base:
                same = "same sequence"
            else:
                same = f"{len(set(keys) & set(base))}/{len(base)} shared"
            sat = "SAT" if runs[0].orderings else ("limit" if runs[0].limit else "UNSAT")
            broken = [f for r in runs for f in r.broken]
            checked = [f for r in runs for f in r.checked]
            notes += [f"{problem.name} {variant}: broken {f}" for f in dict.fromkeys(broken)]
            notes += [f"{problem.name} {variant}: test check {f}" for f in dict.fromkeys(checked)]
            draws = median(runs, lambda r: r.draws)
            cross = ""
            if runs is not reference:
                there = make_search(reference_name, problem, options.seed, options.lpx)
                back = make_search(variant, problem, options.seed, options.lpx)
                forward = sum(accepts(there, o) for o in runs[0].orderings)
                backward = sum(accepts(back, o) for o in reference[0].orderings)
                cross = f"; {forward}/{len(keys)} by {reference_name}, {backward}/{len(base)} back"
            print(
                f"| {problem.name} | {symbols} | {variant} "
                f"| {1000 * median(runs, lambda r: r.ground):.1f} "
                f"| {1000 * median(runs, lambda r: r.first):.1f} "
                f"| {1000 * draws:.1f} | {draws / base_draws:.2f} "
                f"| {len(runs[0].orderings)} | {sat} | {same}{cross} "
                f"| {'yes' if same_runs else 'no'} | {runs[0].conflicts} "
                f"| {'yes' if not broken else f'no ({len(broken)})'} "
                f"| {'passes' if not checked else f'fails ({len(checked)})'} |"
            )
    if notes:
        print("\nfindings (each once):")
        for note in notes[:60]:
            print(f"- {note}")
        if len(notes) > 60:
            print(f"- ... and {len(notes) - 60} more")


def ordering_facts_of(problem: Problem) -> list[clingo.Symbol]:
    return ordering_facts(problem.intersection, problem.cars, problem.m, problem.limits)[0]


def date_line() -> str:
    return (
        f"{time.strftime('%Y-%m-%d')}, Python {platform.python_version()}, "
        f"clingo {clingo.__version__}, {platform.machine()}"
    )


if __name__ == "__main__":
    main()
