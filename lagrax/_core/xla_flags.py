"""One XLA:CPU setting that makes small stepping loops several times faster, and the
options of a program that runs one trajectory (`one_shot_options`, at the end).

XLA:CPU runs a compiled program as a sequence of kernels ("thunks"), one per fused
operation, with a fixed cost each. An ODE step for a small mechanism is a few hundred
flops spread over dozens of such kernels, so that cost dominates: ≈ 3 µs a step for the
2R arm. XLA can instead compile a whole `while` loop into a single kernel, but only
loops whose memory traffic per iteration is below `xla_cpu_small_while_loop_byte_threshold`
(1 kB by default, too small for an ODE solver's state). Raising it to 1 MiB lets lagrax's
single-trajectory loops run as one kernel (≈ 0.5 µs a step), and leaves large batched
loops (sweeps) as they were: we measured no change there.

The option is an XLA flag, read once when JAX starts its CPU backend, so `import lagrax`
adds it to `XLA_FLAGS` if JAX has not started yet. It changes nothing if:

- `XLA_FLAGS` already sets `xla_backend_extra_options` (yours win);
- `LAGRAX_XLA_FLAGS=0` is set in the environment (opt out);
- JAX has already run a computation in this process: too late. lagrax then works as
  before, only slower, and says so once (a `UserWarning`, on CPU only).
"""

import os
import warnings

from jax._src import xla_bridge as _xb

_KEY = "xla_cpu_small_while_loop_byte_threshold"
THRESHOLD = 1 << 20


def _opted_out(name: str) -> bool:
    """Whether the environment variable `name` turns a setting off (`0`, `false`, ...)."""
    return os.environ.get(name, "1").strip().lower() in ("0", "false", "no", "off")


def configure() -> None:
    """Add the small-loop threshold to `XLA_FLAGS` when that can still take effect."""
    if _opted_out("LAGRAX_XLA_FLAGS"):
        return
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_backend_extra_options" in flags:
        return
    try:
        started = _xb.backends_are_initialized()
    except Exception:  # pragma: no cover - a JAX without this private helper
        return
    if not started:
        os.environ["XLA_FLAGS"] = f"{flags} --xla_backend_extra_options={_KEY}={THRESHOLD}".strip()
        return
    import jax

    if jax.default_backend() == "cpu":
        warnings.warn(
            "lagrax was imported after JAX had started, so XLA:CPU runs its solver loops "
            "kernel by kernel (same results, 2-5x slower for small systems). Import lagrax "
            "first, or set XLA_FLAGS='--xla_backend_extra_options="
            f"{_KEY}={THRESHOLD}' before starting Python; LAGRAX_XLA_FLAGS=0 silences this.",
            stacklevel=3,
        )


# The XLA options of a program that runs one trajectory on concrete inputs (`simulate`'s
# compiled call, `lagrax._solve.compiled`), on the CPU: XLA:CPU's older loop emitter
# instead of its fusion emitters, which take longer to compile the long chains of small
# scalar operations that lagrax's recursions are. Measured in one process, alternating
# (`benchmarks/bench_compile.py --one-shot-options`): the first call of the ant with
# contact 25.0 → 21.1 s, solo12 on four feet 18.3 → 15.1 s, humanoid_CMU 7.6 → 7.1 s;
# later calls unchanged within the machine's noise. Per program, so a user's own
# programs and the batched sweeps keep XLA's defaults; `LAGRAX_ONE_SHOT_XLA=0` keeps
# them for these too.
_ONE_SHOT = {"xla_cpu_use_fusion_emitters": False}


def one_shot_options() -> dict | None:
    """The `compiler_options` of `jax.jit` for a one-trajectory program: `_ONE_SHOT` on
    the CPU, `None` (XLA's defaults) elsewhere or where `LAGRAX_ONE_SHOT_XLA=0`."""
    if _opted_out("LAGRAX_ONE_SHOT_XLA"):
        return None
    import jax

    return dict(_ONE_SHOT) if jax.default_backend() == "cpu" else None
