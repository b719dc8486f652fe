r"""Several robots in one model: a [`Forest`][lagrax.chains.Forest] of floating trees
(and trees fixed to the world), and its system,
[`ForestSystem`][lagrax.chains.ForestSystem].

A MuJoCo model may hold several free bodies (a dog and its ball; stacked boxes), each
the root of its own subtree. Each becomes a [`FloatingTree`][lagrax.chains.FloatingTree]
in Pinocchio's free-flyer convention, and the joints hanging from the world a
[`Tree`][lagrax.chains.Tree]; the parts share no joint, so the mass matrix is
block-diagonal, `M = diag(M_1, M_2, …)`, and each part's equations are its own
recursions (the articulated-body algorithm of each floating tree). The parts couple only
through constraints (a [`ConstrainedSystem`][lagrax.ConstrainedSystem] over the whole
state: MuJoCo's equality constraints) or contact.

The state is the parts' states one after the other, in the order of the model (MuJoCo's
body order, so a forest read by [`lagrax.chains.from_mjcf`][] keeps MuJoCo's joint order):
`q = (q_1, q_2, …)` with a floating part's `(x, y, z, q_x, q_y, q_z, q_w, joints…)` and
a fixed part's joint angles, `v = (v_1, v_2, …)` likewise.
"""

from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._core.checks import configuration_size, coords, eager_only, traced
from ..._core.custom_types import Params
from ..._core.errors import ConfigurationError, NonFiniteError
from ..._systems.abstract import AbstractSystem
from ..articulated.trees import Tree
from .system import FloatingTree


class Forest(eqx.Module):
    r"""Several robots side by side, each a [`FloatingTree`][lagrax.chains.FloatingTree]
    (a free body with the joints below it) or a [`Tree`][lagrax.chains.Tree] fixed to
    the world, with one state: the parts' states one after the other.

    **Arguments:**

    - `parts`: the robots, in the order of the state (at least one; a fixed
      [`Tree`][lagrax.chains.Tree] with joints, or a
      [`FloatingTree`][lagrax.chains.FloatingTree]).
    - `names`: a label for each part (default `part0`, `part1`, …): a floating part's
      base names its configuration and velocity entries (`box1_x`, …).

    Params are a tuple of the parts' params, in order (each as the part's own
    `params(...)`).

    **Example:** a ball and a free box, in one state `q` of size 14 and `v` of size 12:

    ```python
    ball = lagrax.chains.FloatingTree(lagrax.chains.Tree("", ()), base_name="ball")
    box = lagrax.chains.FloatingTree(lagrax.chains.Tree("", ()), base_name="box")
    forest = lagrax.chains.Forest((ball, box))
    params = (ball.params(base_m=0.1), box.params(base_m=2.0))
    vdot = forest.system().forward_dynamics(q, v, params)
    ```

    **Raises:** `ConfigurationError` for no parts, a part that is not a `Tree` or a
    `FloatingTree`, a fixed `Tree` with no joints, or names of the wrong number.
    """

    parts: tuple[Any, ...]
    names: tuple[str, ...] = eqx.field(static=True)

    def __init__(self, parts: Any, names: Any = None):
        parts = tuple(parts)
        if not parts:
            raise ConfigurationError("a Forest needs at least one part, got none")
        for i, part in enumerate(parts):
            if isinstance(part, Tree):
                if part.n_bodies == 0:
                    raise ConfigurationError(
                        f"Forest part {i} is a Tree with no joints: fixed to the world it "
                        "cannot move (put a single rigid body on a FloatingTree)"
                    )
            elif not isinstance(part, FloatingTree):
                raise ConfigurationError(
                    f"Forest part {i} must be a Tree or a FloatingTree, got {type(part).__name__}"
                )
        names = tuple(f"part{i}" for i in range(len(parts))) if names is None else tuple(names)
        if len(names) != len(parts):
            raise ConfigurationError(f"{len(parts)} parts need {len(parts)} names, got {names}")
        self.parts, self.names = parts, tuple(str(n) for n in names)

    @property
    def n(self) -> int:
        """The number of velocities, all parts together."""
        return sum(_sizes(p)[1] for p in self.parts)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Every part's joint names, in order."""
        return tuple(name for p in self.parts for name in p.joint_names)

    def system(self) -> "ForestSystem":
        """The [`ForestSystem`][lagrax.chains.ForestSystem] of the parts."""
        return ForestSystem(self)


def _sizes(part: Any) -> tuple[int, int]:
    """`(size of q, size of v)` of a part."""
    if isinstance(part, FloatingTree):
        return 7 + part.n, 6 + part.n
    return part.n, part.n


class ForestSystem(AbstractSystem):
    r"""The equations of motion of a [`Forest`][lagrax.chains.Forest]: each part's own,

    $$
    M_k(q_k) v̇_k + b_k(q_k, v_k) = τ_k − ∂D_k/∂v_k, \qquad q̇_k = N_k(q_k) v_k,
    $$

    side by side: `M = diag(M_1, M_2, …)` is block-diagonal, `v̇` the parts' `v̇_k`
    one after the other (each by its articulated-body algorithm), the energy the sum of
    theirs. A floating part's `q_k`, `v_k` are Pinocchio's free-flyer coordinates (see
    [`FloatingBaseSystem`][lagrax.chains.FloatingBaseSystem]), and `simulate` keeps its
    quaternion on the unit sphere; `Solution.constraint_violation` reports each floating
    part's `|q_quat| − 1`. A constraint between parts (MuJoCo's equality constraints)
    wraps this system in a [`ConstrainedSystem`][lagrax.ConstrainedSystem].

    Params: a tuple of the parts' params, in order. Build it with
    [`Forest.system`][lagrax.chains.Forest.system].
    """

    forest: Forest
    systems: tuple[Any, ...]
    name: str = eqx.field(static=True)

    def __init__(self, forest: Forest, name: str = "forest"):
        self.forest, self.name = forest, name
        self.systems = tuple(p.system() for p in forest.parts)  # built once

    def _systems(self) -> tuple[Any, ...]:
        return self.systems

    def _slices(self) -> list[tuple[slice, slice]]:
        """Each part's `(q slice, v slice)`."""
        out, qa, va = [], 0, 0
        for part in self.forest.parts:
            nq, nv = _sizes(part)
            out.append((slice(qa, qa + nq), slice(va, va + nv)))
            qa, va = qa + nq, va + nv
        return out

    @property
    def n_dof(self) -> int:
        """The number of velocities, all parts together."""
        return self.forest.n

    @property
    def n_configuration(self) -> int:
        """The size of `q`, all parts together."""
        return sum(_sizes(p)[0] for p in self.forest.parts)

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        """The velocities' names, part after part (a floating part's base velocities
        prefixed by the part's name: `ball_vx`, …)."""
        return self._names("coordinate_names")

    @property
    def configuration_names(self) -> tuple[str, ...]:
        """The configuration's names, part after part (`ball_x … ball_qw`, joints)."""
        return self._names("configuration_names")

    def _names(self, which: str) -> tuple[str, ...]:
        out: list[str] = []
        for name, part, system in zip(
            self.forest.names, self.forest.parts, self._systems(), strict=True
        ):
            names = tuple(getattr(system, which))
            if isinstance(part, FloatingTree):
                base = 7 if which == "configuration_names" else 6
                names = (
                    tuple(f"{name}_{n.removeprefix('base_')}" for n in names[:base]) + names[base:]
                )
            out += names
        return tuple(out)

    @property
    def final_maxima(self) -> tuple[str, ...]:
        """`constraint_violation` (each floating part's quaternion norm drift) where a
        part floats."""
        floats = any(isinstance(p, FloatingTree) for p in self.forest.parts)
        return ("constraint_violation",) if floats else ()

    # ------------------------------------------------------------------ per part
    def _each(self, method: str, q: Any, v: Any, *args: Any) -> list[Any]:
        """`system_k.method(q_k, v_k, *args_k)` for every part (`v` `None`: left out;
        an arg that is a tuple of the parts' values is split, `tau` by the velocity
        slices)."""
        out = []
        for k, (system, (sq, sv)) in enumerate(zip(self._systems(), self._slices(), strict=True)):
            parts = [q[sq]] + ([] if v is None else [v[sv]])
            rest = [a[k] if isinstance(a, tuple) else a for a in args]
            out.append(getattr(system, method)(*parts, *rest))
        return out

    def _inputs(self, q: Any, **velocities: Any) -> list[Any]:
        """`q` and the velocity-sized arrays as arrays of one dtype (`None` kept)."""
        size = configuration_size(self.n_configuration, self.n_dof)
        out = [coords(q, "q", self.n_configuration, self.name, size=size)]
        for key, value in velocities.items():
            out.append(None if value is None else coords(value, key, self.n_dof, self.name))
        dtype = jnp.result_type(*(x for x in out if x is not None))
        return [None if x is None else x.astype(dtype) for x in out]

    def _split(self, tau: Any) -> Any:
        """A velocity-sized vector as a tuple of the parts' pieces (`None` kept)."""
        if tau is None:
            return None
        return tuple(tau[sv] for _, sv in self._slices())

    # ------------------------------------------------------------------ configuration
    def configuration_rate(self, q: Any, v: Any) -> jnp.ndarray:
        """`q̇ = N(q) v`, part by part (a floating part's `ṗ = R v_b`, `q̇_quat = ½
        q_quat ⊗ (ω_b, 0)`; a fixed part's joint rates)."""
        return jnp.concatenate(self._each("configuration_rate", q, v))

    def project_configuration(self, q: Any) -> jnp.ndarray:
        """`q` with every floating part's quaternion divided by its norm."""
        return jnp.concatenate(self._each("project_configuration", q, None))

    def initial_state(self, q: Any, qd: Any, params: Params) -> tuple[Any, Any, Any]:
        """The initial state with every quaternion normalized (`ok` false for a zero
        quaternion)."""
        ok = jnp.asarray(True)
        for part, (sq, _) in zip(self.forest.parts, self._slices(), strict=True):
            if isinstance(part, FloatingTree):
                ok = ok & (jnp.linalg.norm(q[sq][3:7]) > 0)
        return self.project_configuration(q), qd, ok

    def observables(self, t: Any, q: Any, qd: Any, params: Params, tau: Any) -> dict[str, Any]:
        """`constraint_violation`: each floating part's `|q_quat| − 1`, in order."""
        drift = [
            jnp.linalg.norm(q[sq][3:7])[None] - 1.0
            for part, (sq, _) in zip(self.forest.parts, self._slices(), strict=True)
            if isinstance(part, FloatingTree)
        ]
        return {"constraint_violation": jnp.concatenate(drift)} if drift else {}

    # ------------------------------------------------------------------ dynamics
    def mass_matrix(self, q: Any, params: Params, qd: Any = None, *, t: Any = 0.0) -> jnp.ndarray:
        """`M(q) = diag(M_1, M_2, …)`, shape `(n, n)`."""
        (q,) = self._inputs(q)
        blocks = self._each("mass_matrix", q, None, tuple(params))
        return _block_diagonal(blocks)

    def inverse_dynamics(
        self, q: Any, qd: Any, qdd: Any, params: Params, t: Any = 0.0
    ) -> jnp.ndarray:
        """`τ = M v̇ + b + ∂D/∂v`, part by part. **Arguments:** `q` (size
        `n_configuration`), `qd` = `v` and `qdd` = `v̇` (size `n`), `params`."""
        q, v, vdot = self._inputs(q, qd=qd, qdd=qdd)
        return jnp.concatenate(self._each("inverse_dynamics", q, v, self._split(vdot), params))

    def accelerations(self, t: Any, q: Any, qd: Any, params: Params, tau: Any) -> jnp.ndarray:
        """`v̇` of checked arrays, part by part, never raising."""
        out = []
        for k, (system, (sq, sv)) in enumerate(zip(self._systems(), self._slices(), strict=True)):
            part_tau = None if tau is None else tau[sv]
            out.append(system.accelerations(t, q[sq], qd[sv], params[k], part_tau))
        return jnp.concatenate(out)

    def forward_dynamics(
        self, q: Any, qd: Any, params: Params, tau: Any = None, t: Any = 0.0
    ) -> jnp.ndarray:
        """`v̇ = M⁻¹ (τ − b − ∂D/∂v)`, part by part, shape `(n,)`.

        **Arguments:** `q` (size `n_configuration`), `qd` = `v` (size `n`), `params` (a
        tuple of the parts' params), `tau` (size `n`, default zero).

        **Raises:** `ShapeError` for wrong sizes; `NonFiniteError` for non-finite
        accelerations (eagerly after the parts' `check_state` names the cause); under
        `jit` through `equinox.error_if`.
        """
        q, v, tau = self._inputs(q, qd=qd, tau=tau)
        vdot = self.accelerations(t, q, v, params, tau)
        if not traced(self, q, v, tau, params):
            if not np.all(np.isfinite(np.asarray(vdot))):
                self.check_state(q, v, params)
                raise NonFiniteError(
                    f"forward_dynamics of {self.name} gave non-finite accelerations "
                    f"{np.asarray(vdot)}: check q, qd, tau and params"
                )
            return vdot
        return eqx.error_if(
            vdot,
            ~(jnp.all(jnp.isfinite(vdot)) & jnp.all(jnp.isfinite(q))),
            f"forward_dynamics of {self.name} produced non-finite accelerations",
        )

    # ------------------------------------------------------------------ energies
    def kinetic_energy(self, q: Any, v: Any, params: Params) -> jnp.ndarray:
        """`T = Σ_k ½ v_kᵀ M_k v_k`."""
        q, v = self._inputs(q, qd=v)
        return sum(self._each("kinetic_energy", q, v, tuple(params)))  # type: ignore[return-value]

    def energy(self, q: Any, qd: Any, params: Params, *, t: Any = 0.0) -> jnp.ndarray:
        """The mechanical energy `T + V`, summed over the parts."""
        q, v = self._inputs(q, qd=qd)
        return sum(self._each("energy", q, v, tuple(params)))  # type: ignore[return-value]

    def _summed(self, method: str, t: Any, q: Any, qd: Any, params: Params, *rest: Any) -> Any:
        out = []
        for k, (system, (sq, sv)) in enumerate(zip(self._systems(), self._slices(), strict=True)):
            extra = [None if r is None else r[sv] for r in rest]
            out.append(getattr(system, method)(t, q[sq], qd[sv], params[k], *extra))
        return out

    def jacobi_integral(self, t: Any, q: Any, qd: Any, params: Params) -> jnp.ndarray:
        """`T + V`, summed over the parts."""
        return sum(self._summed("jacobi_integral", t, q, qd, params))  # type: ignore[return-value]

    def explicit_power(self, t: Any, q: Any, qd: Any, params: Params) -> None:
        """`None`: the energies do not depend on time."""
        return None

    def input_power(self, t: Any, q: Any, qd: Any, params: Params, tau: Any) -> Any:
        """`v·(τ − ∂D/∂v)`, summed over the parts (`None` where no part has any)."""
        powers = [p for p in self._summed("input_power", t, q, qd, params, tau) if p is not None]
        return sum(powers) if powers else None

    def energy_and_magnitude(self, t: Any, q: Any, qd: Any, params: Params) -> Any:
        """`(T + V, |T| + |V|)`, summed over the parts."""
        pairs = self._summed("energy_and_magnitude", t, q, qd, params)
        return sum(e for e, _ in pairs), sum(m for _, m in pairs)

    def components(self, t: Any, q: Any, qd: Any, params: Params) -> dict[str, Any]:
        """Each part's components, named by the part."""
        out = {}
        for name, comps in zip(
            self.forest.names, self._summed("components", t, q, qd, params), strict=True
        ):
            out.update({f"{name}: {key}": value for key, value in comps.items()})
        return out

    def check_state(self, q: Any, qd: Any, params: Params, *, t: Any = 0.0) -> None:
        """Validate a state eagerly, part by part (sizes, finite values, quaternions,
        `M` positive-definite), each part's error naming the part.

        **Raises:** as the parts' `check_state`; `ConfigurationError` for traced
        values.
        """
        eager_only(f"check_state of {self.name}", self, q, qd, params, t)
        q, v = self._inputs(q, qd=qd)
        if not isinstance(params, tuple | list) or len(params) != len(self.forest.parts):
            raise ConfigurationError(
                f"the params of a forest of {len(self.forest.parts)} parts are a tuple of "
                f"the parts' params, got {type(params).__name__}"
            )
        for name, system, (sq, sv), p in zip(
            self.forest.names, self._systems(), self._slices(), params, strict=True
        ):
            try:
                system.check_state(q[sq], v[sv], p)
            except Exception as err:
                raise type(err)(f"part {name!r}: {err}") from None


def _block_diagonal(blocks: list[jnp.ndarray]) -> jnp.ndarray:
    n = sum(b.shape[0] for b in blocks)
    out = jnp.zeros((n, n), blocks[0].dtype)
    a = 0
    for b in blocks:
        k = b.shape[0]
        out = out.at[a : a + k, a : a + k].set(b)
        a += k
    return out
