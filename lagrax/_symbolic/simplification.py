"""Simplification within a budget: a size limit checked before SymPy starts, and a time
limit that interrupts it.

Simplification (for the trigonometric polynomials of mechanisms, their Fourier form; for
anything else `sympy.simplify`) is what turns the derivatives of `T` into the lecture's
`c2`, `s2` and `c12`; it costs a time that grows steeply with the size of the expression.
So every expression is measured first (nodes of its expression tree, `tree_size`) and
refused past `max_size`, and the whole derivation runs under a deadline: past `timeout`
seconds an `ExpressionSizeError` names the expression SymPy was working on and the budget,
instead of a silent minute.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import signal
import threading
import time
from collections.abc import Iterator
from typing import Any

from .. import _symbolic as _symbolic_package
from .conversions import load_sympy, tree_size
from .errors import ExpressionSizeError
from .trigonometry import fourier

DEFAULT_MAX_SIZE = 50_000
DEFAULT_TIMEOUT = 30.0


@dataclasses.dataclass(frozen=True)
class Budget:
    """How large an expression may grow and how long a derivation may take.

    - `max_size`: the largest expression (nodes of its tree, `tree_size`) that is
      simplified; a larger one raises `ExpressionSizeError` before SymPy starts.
    - `timeout`: seconds for the whole derivation (interpretation, differentiation and
      simplification); `None` for no limit.
    """

    max_size: int = DEFAULT_MAX_SIZE
    timeout: float | None = DEFAULT_TIMEOUT


class _Expired(BaseException):
    """Raised by the alarm inside SymPy. A `BaseException`, so that SymPy's own
    `except Exception` (it tries one method, then another) does not swallow it."""


def _package_folder(module: Any) -> str:
    return os.path.dirname(os.path.abspath(module.__file__)) + os.sep


def _interruptible_folders() -> tuple[str, ...]:
    """Where the alarm may raise: SymPy's code and lagrax.symbolic's."""
    return (_package_folder(load_sympy()), _package_folder(_symbolic_package))


class Deadline:
    """The time budget of one derivation: `check` raises past it; inside `running`, an
    alarm interrupts SymPy itself where the platform allows (POSIX, main thread)."""

    def __init__(self, budget: Budget):
        self.budget = budget
        self.start = time.perf_counter()
        self.current = "the expressions"

    def elapsed(self) -> float:
        return time.perf_counter() - self.start

    def error(self) -> ExpressionSizeError:
        return ExpressionSizeError(
            f"lagrax.symbolic ran past its time budget (timeout={self.budget.timeout} s) "
            f"while working on {self.current}: SymPy cannot simplify it within the budget. "
            "Pass a larger timeout= (or timeout=None), simplify=False for the unsimplified "
            "expressions, or use the numeric equations (system.mass_matrix, ...)"
        )

    def check(self) -> None:
        timeout = self.budget.timeout
        if timeout is not None and self.elapsed() > timeout:
            raise self.error()

    @contextlib.contextmanager
    def running(self) -> Iterator[None]:
        timeout = self.budget.timeout
        alarm = (
            timeout is not None
            and os.name == "posix"
            and threading.current_thread() is threading.main_thread()
        )
        if not alarm:
            yield
            return
        assert timeout is not None

        caught = []
        folders = _interruptible_folders()

        def expire(signum, frame):
            # Raise only where the interrupted code is SymPy's or this package's: an
            # exception raised inside a callback the interpreter runs in between (a garbage
            # collector callback, a `__del__`) is printed and dropped rather than
            # propagated. Elsewhere, the timer fires again 0.1 s later.
            if (
                not caught
                and frame is not None
                and os.path.abspath(frame.f_code.co_filename).startswith(folders)
            ):
                raise _Expired

        previous = signal.signal(signal.SIGALRM, expire)
        # fire at the deadline, then every 0.1 s until the exception gets out of SymPy
        signal.setitimer(signal.ITIMER_REAL, max(timeout - self.elapsed(), 1e-3), 0.1)
        try:
            yield
        except _Expired:
            caught.append(True)
            raise self.error() from None
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0.0)
            signal.signal(signal.SIGALRM, previous)


def check_size(expr: Any, budget: Budget, what: str) -> int:
    """`tree_size(expr)`, or `ExpressionSizeError` naming `what` past `budget.max_size`."""
    size = tree_size(expr)
    if size > budget.max_size:
        raise ExpressionSizeError(
            f"{what} has {size:,} nodes, past the size budget max_size={budget.max_size:,}: "
            "symbolic equations of this size take minutes to simplify and pages to read. "
            "Use the numeric equations (system.mass_matrix, system.inverse_dynamics, ...), "
            "keep some parameters as numbers (numeric=...), or raise max_size"
        )
    return size


def simplify(expr: Any, budget: Budget, deadline: Deadline, what: str) -> Any:
    """`expr` simplified (see `canonical`), after checking its size and the time spent so
    far."""
    size = check_size(expr, budget, what)
    deadline.check()
    deadline.current = f"{what} ({size:,} nodes)"
    return canonical(expr)


def canonical(expr: Any) -> Any:
    """A SymPy expression simplified as [`equations`][lagrax.symbolic.equations] simplifies.

    - A polynomial in `sin` and `cos` of integer combinations of angles (the
      mechanisms of lagrax's models, chains and scenes) is written in its Fourier form
      `A₀ + Σ_k A_k cos(k·θ) + B_k sin(k·θ)`: exact, the same for every equal
      expression (so `simplify(a − b) == 0` exactly when `a = b`), and fast.
    - Another polynomial is expanded; anything else goes to `sympy.simplify`.

    Common factors are then pulled out (`factor_terms`): `2 l₁m₂r₂θ̇₁θ̇₂ sin θ₂ +
    l₁m₂r₂θ̇₂² sin θ₂` becomes `l₁m₂r₂θ̇₂(2θ̇₁ + θ̇₂) sin θ₂`.

    **Arguments:** `expr`, a SymPy expression.

    **Returns:** the simplified expression.
    """
    sp = load_sympy()
    if not expr.free_symbols:
        return sp.nsimplify(expr) if expr.has(sp.Float) else expr
    out = fourier(expr)
    if out is None:
        out = sp.expand(expr) if expr.is_polynomial() else sp.simplify(expr)
    return sp.factor_terms(out)
