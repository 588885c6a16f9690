"""Linear programs for z3, written as SMT-LIB text.

Step 3 solves many small linear programs. Building them through z3's Python objects costs
more than solving them, so they are built here as plain sums of rational terms and handed
to z3 as one SMT-LIB string. Numbers are rationals with small denominators (a float's exact
value has 2^52 in its denominator, which slows z3's exact simplex down by orders of
magnitude). Every check is limited by z3's resource count (``rlimit``), never by a clock.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable, Sequence
from fractions import Fraction

import z3

GRID = 10**6  # floats enter as multiples of a millionth


def rational(x: float | Fraction | int) -> Fraction:
    """``x`` as a rational with a small denominator."""
    if isinstance(x, Fraction | int):
        return Fraction(x)
    return Fraction(round(x * GRID), GRID)


@functools.lru_cache(maxsize=4096)
def _number(value: Fraction) -> str:
    text = (
        str(abs(value.numerator))
        if value.denominator == 1
        else f"(/ {abs(value.numerator)} {value.denominator})"
    )
    return f"(- {text})" if value < 0 else text


class Linear:
    """A linear expression: rational coefficients of variables, plus a constant."""

    __slots__ = ("constant", "terms")

    def __init__(self, terms: dict[str, Fraction] | None = None, constant: Fraction = Fraction(0)):
        self.terms = terms or {}
        self.constant = constant

    @staticmethod
    def of(value: Linear | float | Fraction | int) -> Linear:
        return value if isinstance(value, Linear) else Linear(constant=rational(value))

    def __add__(self, other: Linear | float | Fraction | int) -> Linear:
        other = Linear.of(other)
        terms = dict(self.terms)
        for name, coefficient in other.terms.items():
            terms[name] = terms.get(name, Fraction(0)) + coefficient
        return Linear(terms, self.constant + other.constant)

    __radd__ = __add__

    def __neg__(self) -> Linear:
        return self * -1

    def __sub__(self, other: Linear | float | Fraction | int) -> Linear:
        return self + (-Linear.of(other))

    def __rsub__(self, other: Linear | float | Fraction | int) -> Linear:
        return Linear.of(other) - self

    def __mul__(self, factor: float | Fraction | int) -> Linear:
        scale = rational(factor)
        return Linear({n: c * scale for n, c in self.terms.items()}, self.constant * scale)

    __rmul__ = __mul__

    def smt(self) -> str:
        parts = [f"(* {_number(c)} {n})" for n, c in self.terms.items() if c != 0]
        if self.constant != 0 or not parts:
            parts.append(_number(self.constant))
        return parts[0] if len(parts) == 1 else f"(+ {' '.join(parts)})"


Operand = Linear | float | Fraction | int


class LinearProgram:
    """Variables, constraints and an objective; solved by z3 under a work limit. Boolean
    choices may switch constraints on (a mixed-integer program, still exact)."""

    def __init__(self, work: int) -> None:
        self.work = work
        self.names: list[str] = []
        self.booleans: list[str] = []
        self.constraints: list[tuple[str, str | None]] = []  # (SMT-LIB atom, label)
        self.objective: Linear | None = None

    def copy(self) -> LinearProgram:
        """The same variables, constraints and objective, to add more to."""
        twin = LinearProgram(self.work)
        twin.names, twin.booleans = list(self.names), list(self.booleans)
        twin.constraints, twin.objective = list(self.constraints), self.objective
        return twin

    def choice(self, prefix: str, count: int) -> list[str]:
        """``count`` new Booleans of which exactly one holds."""
        names = [f"{prefix}_{k}" for k in range(count)]
        self.booleans += names
        ones = " ".join("1" for _ in names)
        self.constraints.append((f"((_ pbeq 1 {ones}) {' '.join(names)})", None))
        return names

    def when(
        self,
        condition: Sequence[str],
        low: float | Fraction | None,
        term: Linear,
        high: float | Fraction | None,
    ) -> None:
        """``low <= term <= high`` whenever every Boolean of ``condition`` holds (a missing
        bound is no bound); with neither bound, the condition itself is ruled out."""
        premise = condition[0] if len(condition) == 1 else f"(and {' '.join(condition)})"
        body = Linear(term.terms)
        atoms = []
        if low is not None:
            atoms.append(f"(>= {body.smt()} {_number(rational(low) - term.constant)})")
        if high is not None:
            atoms.append(f"(<= {body.smt()} {_number(rational(high) - term.constant)})")
        if not atoms:
            self.constraints.append((f"(not {premise})", None))
            return
        conclusion = atoms[0] if len(atoms) == 1 else f"(and {' '.join(atoms)})"
        self.constraints.append((f"(=> {premise} {conclusion})", None))

    def variable(
        self, name: str, low: Operand | None = None, high: Operand | None = None
    ) -> Linear:
        self.names.append(name)
        term = Linear({name: Fraction(1)})
        if low is not None:
            self.at_least(term, low)
        if high is not None:
            self.at_most(term, high)
        return term

    def magnitude(self, expression: Operand) -> Linear:
        """A new variable at least as large as |expression| (minimised, it equals it)."""
        size = self.variable(f"abs{len(self.names)}")
        self.at_least(size, expression)
        self.at_least(size, -Linear.of(expression))
        return size

    def _add(self, relation: str, left: Operand, right: Operand, label: str | None) -> None:
        left, right = Linear.of(left), Linear.of(right)
        if right.terms:
            left, right = left - right, Linear()
        body = Linear(left.terms)
        bound = right.constant - left.constant
        self.constraints.append((f"({relation} {body.smt()} {_number(bound)})", label))

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
        for k, (atom, label) in enumerate(self.constraints):
            if named and label:  # names must be unique: the label, then the row
                lines.append(f"(assert (! {atom} :named {label}@{k}))")
            else:
                lines.append(f"(assert {atom})")
        return "\n".join(lines)

    def solve(self) -> dict[str, Fraction] | None:
        """The optimum (every variable's value, 1 or 0 for a Boolean), or None when there
        is none or z3 ran out of work. Without an objective, any solution.

        z3's optimiser (and its default arithmetic solver) sometimes takes thousands of
        pivots on one of these programs where z3's older simplex (``smt.arith.solver=2``)
        takes a few dozen. When the optimiser runs out of its share of the work
        (1 / OPTIMISER_SHARE), the optimum is found again by bisection on the objective
        with that simplex (``_bisect``)."""
        text = self._text(named=False)
        if self.objective is not None:
            text += f"\n(minimize {self.objective.smt()})"
        try:
            work = self.work // OPTIMISER_SHARE if self.objective is not None else self.work
            return _check(text, work, optimise=self.objective is not None)
        except _OutOfWork:
            return self._bisect() if self.objective is not None else None

    def _bisect(self) -> dict[str, Fraction] | None:
        """The optimum within OPTIMUM_GAP by bisection (the objective is non-negative, a
        sum of magnitudes): each check asks for a solution at most halfway between the best
        found and the best bound shown, ``work`` per check, at most BISECTIONS checks. A
        check that runs out of work ends it with the best solution found."""
        assert self.objective is not None
        constraints = self._text(named=False)
        try:
            found = _check(constraints, self.work, old_simplex=True)
        except _OutOfWork:
            return None
        if found is None:
            return None
        objective = self.objective.smt()
        best, value = found, value_of(self.objective, found)
        if value < 0:
            raise ValueError(f"the objective must be non-negative, it is {float(value):g} here")
        low = Fraction(0)
        for _ in range(BISECTIONS):
            if value - low <= OPTIMUM_GAP * max(Fraction(1), value):
                break
            middle = (low + value) / 2
            bounded = f"{constraints}\n(assert (<= {objective} {_number(middle)}))"
            try:
                better = _check(bounded, self.work, old_simplex=True)
            except _OutOfWork:
                break
            if better is None:
                low = middle
            else:
                best, value = better, value_of(self.objective, better)
        return best

    def conflict(self) -> list[str] | None:
        """Labels of labelled constraints that cannot hold together with the unlabelled
        ones (an unsatisfiable core); None when they can, or z3 cannot tell."""
        context = z3.Context()
        solver = z3.Solver(ctx=context)
        solver.set("rlimit", self.work)
        solver.from_string(self._text(named=True))
        if solver.check() != z3.unsat:
            return None
        return sorted({str(name).split("@")[0] for name in solver.unsat_core()})


OPTIMISER_SHARE = 8  # the optimiser's share of the work is 1 / 8; then bisection
OPTIMUM_GAP = Fraction(1, 100)  # a solution this close to the optimum (a share) is taken
BISECTIONS = 24  # checks at most in one optimisation (then the best found)


class _OutOfWork(Exception):
    """z3 neither found a solution nor showed there is none within its work limit."""


def _check(
    text: str, work: int, optimise: bool = False, old_simplex: bool = False
) -> dict[str, Fraction] | None:
    """A solution of the SMT-LIB text (the optimum, with ``optimise``), or None when there
    is none; _OutOfWork when z3 cannot tell within ``work``."""
    context = z3.Context()  # a fresh context: no history
    solver = z3.Optimize(ctx=context) if optimise else z3.Solver(ctx=context)
    solver.set("rlimit", work)
    if old_simplex:
        solver.set("smt.arith.solver", 2)
    solver.from_string(text)
    outcome = solver.check()
    if outcome == z3.unknown:
        raise _OutOfWork
    if outcome != z3.sat:
        return None
    model = solver.model()
    found = {}
    for declaration in model.decls():
        value = model[declaration]
        found[declaration.name()] = (
            Fraction(int(z3.is_true(value))) if z3.is_bool(value) else value.as_fraction()
        )
    return found


def value_of(term: Linear, solution: dict[str, Fraction]) -> Fraction:
    """The value of ``term`` at a solution (0 for a variable z3 left out)."""
    return term.constant + sum(
        (c * solution.get(n, Fraction(0)) for n, c in term.terms.items()), Fraction(0)
    )


def combine(*pairs: tuple[Fraction, Linear]) -> Linear:
    """The sum of coefficient times expression, in one pass (cheaper than operators)."""
    found: dict[str, Fraction] = {}
    constant = Fraction(0)
    for factor, term in pairs:
        for name, coefficient in term.terms.items():
            found[name] = found.get(name, Fraction(0)) + factor * coefficient
        constant += factor * term.constant
    return Linear(found, constant)


def values(solution: dict[str, Fraction], names: Iterable[str]) -> list[float]:
    """The values of ``names`` in a solution (0 for a variable z3 left out)."""
    return [float(solution.get(name, Fraction(0))) for name in names]


def total(terms: Sequence[Linear]) -> Linear:
    """The sum of the terms (one pass, no copies)."""
    found: dict[str, Fraction] = {}
    constant = Fraction(0)
    for term in terms:
        for name, coefficient in term.terms.items():
            found[name] = found.get(name, Fraction(0)) + coefficient
        constant += term.constant
    return Linear(found, constant)
