"""A trace-time switch for programs that run one trajectory once.

`simulate` on concrete inputs compiles one program, runs it and is done: its first result
is mostly compile time. Within `one_shot()`, code that has two forms of the same
computation (the tree recursions: vectorized lanes, fast to run under `vmap`, or one scan
over the bodies, fast to compile; see `recursions.ONE_SHOT_MAX_PHASES`) traces the one
that compiles fastest. A batch (`vmap`, `sweep`) and a user's own `jit` are traced outside
it. Trace-time only: a function traced under it and cached across calls must carry
`one_shot_on()` in its cache key (`vector_field._evaluate` takes it as a static argument).
"""

import contextlib
from collections.abc import Iterator

_SWITCH = {"on": False}


@contextlib.contextmanager
def one_shot() -> Iterator[None]:
    """Within this context, `one_shot_on()` is true."""
    before = _SWITCH["on"]
    _SWITCH["on"] = True
    try:
        yield
    finally:
        _SWITCH["on"] = before


def one_shot_on() -> bool:
    """Whether `one_shot` is in effect (the program being traced runs once)."""
    return bool(_SWITCH["on"])
