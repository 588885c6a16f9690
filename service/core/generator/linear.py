"""Linear programs for Step 3: HiGHS for optima, z3 for choices and proofs.

Step 3 solves many small linear programs (tens of variables, hundreds of rows). Their
optima come from HiGHS's simplex (highspy), which solves one in about two milliseconds
where z3's optimiser took from 0.05 to several seconds (docs/benchmarks.md). Programs with
Boolean choices (the speed-grid plans) and unsatisfiable cores (the proofs that an order
cannot be timed) stay with z3: exact over the rationals, the numbers written as SMT-LIB
text with small denominators (a float's exact value has 2^52 in its denominator, which
slows z3's exact simplex down by orders of magnitude). Every solve is limited by a count
of work (HiGHS's simplex iterations, z3's ``rlimit``), never by a clock. HiGHS keeps every
row to within its feasibility tolerance (1e-7); the samples of every curve are checked
against the motion invariants and the checker afterwards, never the solver's word.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable, Sequence

import highspy
import numpy as np
import z3
from highspy._core import _Highs

GRID = 10**6  # floats enter as multiples of a millionth


@functools.lru_cache(maxsize=65536)
def _number(value: float) -> str:
    """``value`` as SMT-LIB text: a rational with denominator GRID (a small denominator)."""
    scaled = round(value * GRID)
    whole, rest = divmod(abs(scaled), GRID)
    text = str(whole) if rest == 0 else f"(/ {abs(scaled)} {GRID})"
    return f"(- {text})" if scaled < 0 else text


class Linear:
    """A linear expression: coefficients of variables, plus a constant (floats; rationals
    with small denominators only where z3 reads them)."""

    __slots__ = ("constant", "terms")

    def __init__(self, terms: dict[str, float] | None = None, constant: float = 0.0):
        self.terms = terms or {}
        self.constant = constant

    @staticmethod
    def of(value: Linear | float) -> Linear:
        return value if isinstance(value, Linear) else Linear(constant=float(value))

    def __add__(self, other: Linear | float) -> Linear:
        other = Linear.of(other)
        terms = dict(self.terms)
        for name, coefficient in other.terms.items():
            terms[name] = terms.get(name, 0.0) + coefficient
        return Linear(terms, self.constant + other.constant)

    __radd__ = __add__

    def __neg__(self) -> Linear:
        return Linear({n: -c for n, c in self.terms.items()}, -self.constant)

    def __sub__(self, other: Linear | float) -> Linear:
        other = Linear.of(other)
        terms = dict(self.terms)
        for name, coefficient in other.terms.items():
            terms[name] = terms.get(name, 0.0) - coefficient
        return Linear(terms, self.constant - other.constant)

    def __rsub__(self, other: Linear | float) -> Linear:
        return Linear.of(other) - self

    def __mul__(self, factor: float) -> Linear:
        scale = float(factor)
        return Linear({n: c * scale for n, c in self.terms.items()}, self.constant * scale)

    __rmul__ = __mul__

    def smt(self) -> str:
        parts = [f"(* {_number(c)} {n})" for n, c in self.terms.items() if c != 0]
        if self.constant != 0 or not parts:
            parts.append(_number(self.constant))
        return parts[0] if len(parts) == 1 else f"(+ {' '.join(parts)})"


Operand = Linear | float


class LinearProgram:
    """Variables, constraints and an objective. A program of real variables only is solved
    by HiGHS's simplex (an optimum within HiGHS's tolerances, limited by a count of simplex
    iterations); Boolean choices that switch constraints on (a mixed-integer program) and
    unsatisfiable cores are z3's, exact over the rationals and limited by z3's ``rlimit``.
    Every limit is a count of work, never a clock."""

    def __init__(self, work: int) -> None:
        self.work = work
        self.names: list[str] = []
        self.booleans: list[str] = []
        self.rows: list[_Row] = []
        self.logic: list[str] = []  # SMT-LIB atoms over the Booleans (choices, conditions)
        self.objective: Linear | None = None

    def copy(self) -> LinearProgram:
        """The same variables, constraints and objective, to add more to."""
        twin = LinearProgram(self.work)
        twin.names, twin.booleans = list(self.names), list(self.booleans)
        twin.rows, twin.logic, twin.objective = list(self.rows), list(self.logic), self.objective
        return twin

    def choice(self, prefix: str, count: int) -> list[str]:
        """``count`` new Booleans of which exactly one holds."""
        names = [f"{prefix}_{k}" for k in range(count)]
        self.booleans += names
        ones = " ".join("1" for _ in names)
        self.logic.append(f"((_ pbeq 1 {ones}) {' '.join(names)})")
        return names

    def when(
        self,
        condition: Sequence[str],
        low: float | None,
        term: Linear,
        high: float | None,
    ) -> None:
        """``low <= term <= high`` whenever every Boolean of ``condition`` holds (a missing
        bound is no bound); with neither bound, the condition itself is ruled out."""
        premise = condition[0] if len(condition) == 1 else f"(and {' '.join(condition)})"
        body = Linear(term.terms)
        atoms = []
        if low is not None:
            atoms.append(f"(>= {body.smt()} {_number(low - term.constant)})")
        if high is not None:
            atoms.append(f"(<= {body.smt()} {_number(high - term.constant)})")
        if not atoms:
            self.logic.append(f"(not {premise})")
            return
        conclusion = atoms[0] if len(atoms) == 1 else f"(and {' '.join(atoms)})"
        self.logic.append(f"(=> {premise} {conclusion})")

    def variable(
        self, name: str, low: Operand | None = None, high: Operand | None = None
    ) -> Linear:
        self.names.append(name)
        term = Linear({name: 1.0})
        if low is not None and low != -math.inf:
            self.at_least(term, low)
        if high is not None and high != math.inf:
            self.at_most(term, high)
        return term

    def magnitude(self, expression: Operand) -> Linear:
        """A new variable at least as large as |expression| (minimised, it equals it)."""
        size = self.variable(f"abs{len(self.names)}")
        self.at_least(size, expression)
        self.at_least(size, -Linear.of(expression))
        return size

    def _add(self, relation: str, left: Operand, right: Operand, label: str | None) -> None:
        difference = Linear.of(left) - Linear.of(right)
        bound = -difference.constant
        low = bound if relation in (">=", "=") else None
        high = bound if relation in ("<=", "=") else None
        self.rows.append(_Row(difference.terms, low, high, label))

    def at_most(self, left: Operand, right: Operand, label: str | None = None) -> None:
        self._add("<=", left, right, label)

    def at_least(self, left: Operand, right: Operand, label: str | None = None) -> None:
        self._add(">=", left, right, label)

    def equal(self, left: Operand, right: Operand) -> None:
        self._add("=", left, right, None)

    def minimize(self, objective: Linear) -> None:
        self.objective = objective

    def _text(self, named: bool) -> str:
        lines = ["(set-option :produce-unsat-cores true)"] if named else []
        lines += [f"(declare-const {name} Real)" for name in self.names]
        lines += [f"(declare-const {name} Bool)" for name in self.booleans]
        for k, row in enumerate(self.rows):
            atom = row.smt()
            if named and row.label:  # names must be unique: the label, then the row
                lines.append(f"(assert (! {atom} :named {row.label}@{k}))")
            else:
                lines.append(f"(assert {atom})")
        lines += [f"(assert {atom})" for atom in self.logic]
        return "\n".join(lines)

    def solve(self) -> dict[str, float] | None:
        """The optimum (every variable's value, 1 or 0 for a Boolean), or None when there
        is none or the solver ran out of work. Without an objective, any solution."""
        if not self.booleans:
            return _highs_optimum(self)
        if self.objective is not None:
            raise ValueError("an objective over Boolean choices is not supported")
        return _z3_solution(self._text(named=False), self.work)

    def solve_or_conflict(self) -> tuple[dict[str, float] | None, list[str] | None]:
        """Any solution of a program with Boolean choices (z3, exact; the real variables'
        values only), or else the labels
        of an unsatisfiable core (as ``conflict``) from the same check; (None, None) when
        z3 cannot tell within its work."""
        context = z3.Context()
        solver = z3.Solver(ctx=context)
        solver.set("rlimit", self.work)
        solver.from_string(self._text(named=True))
        outcome = solver.check()
        if outcome == z3.sat:
            return _real_values(solver.model(), self.names, context), None
        if outcome == z3.unsat:
            return None, sorted({str(name).split("@")[0] for name in solver.unsat_core()})
        return None, None

    def conflict(self) -> list[str] | None:
        """Labels of labelled constraints that cannot hold together with the unlabelled
        ones (an unsatisfiable core, exact: z3 over the rationals); None when they can, or
        z3 cannot tell."""
        context = z3.Context()
        solver = z3.Solver(ctx=context)
        solver.set("rlimit", self.work)
        solver.from_string(self._text(named=True))
        if solver.check() != z3.unsat:
            return None
        return sorted({str(name).split("@")[0] for name in solver.unsat_core()})


class _Row:
    """One constraint: ``low <= sum of terms <= high`` (a missing bound is no bound)."""

    __slots__ = ("high", "label", "low", "terms")

    def __init__(
        self,
        terms: dict[str, float],
        low: float | None,
        high: float | None,
        label: str | None,
    ) -> None:
        self.terms, self.low, self.high, self.label = terms, low, high, label

    def smt(self) -> str:
        body = Linear(self.terms).smt()
        if self.low is not None and self.high is not None and self.low == self.high:
            return f"(= {body} {_number(self.low)})"
        atoms = [f"(>= {body} {_number(self.low)})"] if self.low is not None else []
        atoms += [f"(<= {body} {_number(self.high)})"] if self.high is not None else []
        return atoms[0] if len(atoms) == 1 else f"(and {' '.join(atoms)})"


ITERATIONS = 200_000  # simplex iterations of one HiGHS solve at most (a count, not seconds)
_OPTIONS: dict[str, bool | int | str] = {
    "output_flag": False,
    "threads": 1,
    "solver": "simplex",
    "random_seed": 0,
    "simplex_iteration_limit": ITERATIONS,
}


def _highs_optimum(program: LinearProgram) -> dict[str, float] | None:
    """The optimum of a program without Booleans by HiGHS's simplex (any solution without
    an objective); None when it has none or the iteration limit was reached.

    The solver is HiGHS's core class: ``highspy.Highs`` enables its Python callbacks in
    its constructor, which prints HiGHS's banner to standard output before any option can
    be set (ERGO-Code/HiGHS#2749), and the command line's output is JSON."""
    index = {name: k for k, name in enumerate(program.names)}
    columns, values, starts = [], [], [0]
    lows, highs = [], []
    for row in program.rows:
        for name, coefficient in row.terms.items():
            if coefficient != 0:
                columns.append(index[name])
                values.append(coefficient)
        starts.append(len(columns))
        lows.append(-highspy.kHighsInf if row.low is None else row.low)
        highs.append(highspy.kHighsInf if row.high is None else row.high)
    lp = highspy.HighsLp()
    lp.num_col_, lp.num_row_ = len(program.names), len(program.rows)
    lp.col_lower_ = np.full(lp.num_col_, -highspy.kHighsInf)
    lp.col_upper_ = np.full(lp.num_col_, highspy.kHighsInf)
    cost = np.zeros(lp.num_col_)
    if program.objective is not None:
        for name, coefficient in program.objective.terms.items():
            cost[index[name]] += coefficient
    lp.col_cost_ = cost
    lp.row_lower_, lp.row_upper_ = np.array(lows), np.array(highs)
    lp.a_matrix_.format_ = highspy.MatrixFormat.kRowwise
    lp.a_matrix_.start_ = np.array(starts, dtype=np.int32)
    lp.a_matrix_.index_ = np.array(columns, dtype=np.int32)
    lp.a_matrix_.value_ = np.array(values)
    solver = _Highs()
    for option, value in _OPTIONS.items():
        solver.setOptionValue(option, value)
    solver.passModel(lp)
    solver.run()
    if solver.getModelStatus() != highspy.HighsModelStatus.kOptimal:
        return None
    found = solver.getSolution().col_value
    return {name: float(found[k]) for k, name in enumerate(program.names)}


def _z3_solution(text: str, work: int) -> dict[str, float] | None:
    """A solution of the SMT-LIB text (Booleans as 1 or 0), or None when there is none or
    z3 cannot tell within ``work``."""
    context = z3.Context()  # a fresh context: no history
    solver = z3.Solver(ctx=context)
    solver.set("rlimit", work)
    solver.from_string(text)
    if solver.check() != z3.sat:
        return None
    return _model_values(solver.model())


def _model_values(model: z3.ModelRef, names: set[str] | None = None) -> dict[str, float]:
    """The model's values of ``names`` (all by default), Booleans as 1 or 0."""
    found = {}
    for declaration in model.decls():
        if names is not None and declaration.name() not in names:
            continue
        value = model[declaration]
        found[declaration.name()] = (
            float(z3.is_true(value)) if z3.is_bool(value) else float(value.as_fraction())
        )
    return found


def _real_values(model: z3.ModelRef, names: Sequence[str], context: z3.Context) -> dict[str, float]:
    """The model's values of the real variables ``names`` (0 where z3 left one out); one
    lookup each, not a walk over every Boolean of the model."""
    found = {}
    for name in names:
        value = model.eval(z3.Real(name, context), model_completion=True)
        found[name] = float(value.as_fraction())
    return found


def value_of(term: Linear, solution: dict[str, float]) -> float:
    """The value of ``term`` at a solution (0 for a variable the solver left out)."""
    return term.constant + sum(c * solution.get(n, 0.0) for n, c in term.terms.items())


def combine(*pairs: tuple[float, Linear]) -> Linear:
    """The sum of coefficient times expression, in one pass (cheaper than operators)."""
    found: dict[str, float] = {}
    constant = 0.0
    for factor, term in pairs:
        for name, coefficient in term.terms.items():
            found[name] = found.get(name, 0.0) + factor * coefficient
        constant += factor * term.constant
    return Linear(found, constant)


def values(solution: dict[str, float], names: Iterable[str]) -> list[float]:
    """The values of ``names`` in a solution (0 for a variable the solver left out)."""
    return [solution.get(name, 0.0) for name in names]


def total(terms: Sequence[Linear]) -> Linear:
    """The sum of the terms (one pass, no copies)."""
    found: dict[str, float] = {}
    constant = 0.0
    for term in terms:
        for name, coefficient in term.terms.items():
            found[name] = found.get(name, 0.0) + coefficient
        constant += term.constant
    return Linear(found, constant)
