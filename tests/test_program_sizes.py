"""Program-size budgets: the main programs, counted in lines of their lowered text.

A program's size drives its compile time (and, on a CPU, the time of one unbatched
call), and it is deterministic for a given JAX: a test can hold it without timing
anything. The budgets sit about 15 % above the sizes measured when they were set (in the
comments), so that growth is caught in review; a JAX release that lowers differently may
move them, and then they are set again, with the new measurements.

Contact is held structurally too: its program grows with the robot's bodies, not with
its spheres (every sphere of a tree is placed by one pass of its kinematics, their
velocities by one JVP and `Σ Jᵢᵀ Fᵢ` by one VJP).
"""

import contextlib
import glob
import importlib.util
import os
import sys

import jax
import jax.numpy as jnp
import pytest

import lagrax as lx
from lagrax._core.one_shot import one_shot
from lagrax.contact import ContactSystem


def lines(fn, *args) -> int:
    """The number of lines of `jax.jit(fn)`'s lowered program (StableHLO text)."""
    return len(jax.jit(fn).lower(*args).as_text().splitlines())


def ant_xml() -> str:
    """gymnasium's `ant.xml`, found without importing gymnasium."""
    spec = importlib.util.find_spec("gymnasium")
    if spec is None or not spec.submodule_search_locations:
        raise FileNotFoundError("gymnasium is not installed: pip install -e '.[dev]'")
    root = spec.submodule_search_locations[0]
    return os.path.join(root, "envs", "mujoco", "assets", "ant.xml")


def dm_control_suite_xml(name: str) -> str:
    """A model file of dm_control's suite, found without importing dm_control."""
    spec = importlib.util.find_spec("dm_control")
    if spec is None or not spec.submodule_search_locations:
        raise FileNotFoundError("dm_control is not installed: pip install -e '.[dev]'")
    return os.path.join(spec.submodule_search_locations[0], "suite", name)


def solo12_urdf() -> str:
    """solo12's URDF from example-robot-data (its cmeel prefix)."""
    found = glob.glob(f"{sys.prefix}/**/solo_description/robots/solo12.urdf", recursive=True)
    if not found:
        raise FileNotFoundError("example-robot-data's solo12 is not installed")
    return found[0]


@pytest.fixture(scope="module")
def ant():
    scene, params = lx.chains.from_mjcf(ant_xml(), contact=True)
    robot = scene.system
    q = jnp.zeros(robot.n_configuration).at[2].set(0.75).at[6].set(1.0)
    return scene, params, q, jnp.zeros(robot.n_dof)


def test_contact_grows_with_the_bodies_not_the_spheres(ant):
    """The ant with 1, 5 and all 25 of its spheres: one program size (measured 8,360,
    8,368 and 8,367 lines; 7,485, 14,485 and 43,221 when each sphere traced its own
    kinematics, velocities and Jacobian transpose)."""
    scene, params, q, v = ant
    sizes = []
    for k in (1, 5, len(scene.spheres)):
        part = ContactSystem(
            scene.system,
            scene.spheres[:k],
            scene.plane,
            friction=lambda p, k=k: p["contact_friction"][:k],
        )
        sizes.append(lines(lambda a, b, s=part: s.forward_dynamics(a, b, params), q, v))
    assert len(scene.spheres) == 25
    assert max(sizes) <= 1.02 * min(sizes), sizes


def test_the_contact_vector_field_is_a_small_multiple_of_the_robot(ant):
    """What a solve's loop traces per step: the ant's contact dynamics with its
    coefficients prepared (`AbstractSystem.prepared`, once per program) against the robot's
    own accelerations (measured 3,740 against 2,041 lines: 1.8x; 20.9x before)."""
    scene, params, q, v = ant
    fixed = ContactSystem(
        scene.system,
        scene.spheres,
        scene.plane,
        friction=lambda p: p["contact_friction"],
        stiffness=1e5,
        dissipation=1.0,
        stiction_velocity=1e-3,
    )
    robot = lines(lambda a, b: scene.system.accelerations(0.0, a, b, params, None), q, v)
    contact = lines(lambda a, b: fixed.accelerations(0.0, a, b, params, None), q, v)
    assert contact <= 2.2 * robot, (contact, robot)


@pytest.mark.parametrize(
    "name, budget",
    [
        ("arm7 forward_dynamics", 1_450),  # measured 1,252
        ("solo12 forward_dynamics", 2_350),  # measured 2,027
        ("ant forward_dynamics", 2_400),  # measured 2,072
        ("ant scene forward_dynamics", 9_700),  # measured 8,367 (43,209 before)
        ("2R arm simulate", 3_000),  # measured 2,588
        # the work carried as state: the vector field traced once (4,259, 19,529 and
        # 25,679 lines when the work at the saves traced it again, with the power's JVP)
        ("arm7 simulate", 3_300),  # measured 2,867
        ("ant scene simulate, tsit5", 19_800),  # measured 17,234
        # a contact scene's default method, the linearly implicit rodas4: its stages
        # trace the vector field once, its Jacobian (a batched JVP, 10k lines) once
        # (kvaerno5's Newton iterations, the default before: 27,495 lines)
        ("ant scene simulate", 36_500),  # measured 31,782
        ("humanoid_CMU simulate", 18_500),  # measured 16,090
        # as simulate traces it on concrete inputs: its recursions as one scan over the
        # bodies, not in its five phases of lanes
        ("humanoid_CMU simulate, one shot", 8_000),  # measured 6,958
    ],
)
def test_program_size_budget(ant, name, budget):
    scene, params, q, v = ant
    if name.startswith("arm7"):
        tree, p7 = lx.chains.from_urdf(lx.models.urdf_path("arm7"))
        arm7 = tree.system()
        q7, v7 = jnp.full(arm7.n_dof, 0.2), jnp.zeros(arm7.n_dof)
        if name.endswith("simulate"):
            size = lines(lambda a, b, p: lx.simulate(arm7, a, b, p, t1=1.0).q, q7, v7, p7)
        else:
            size = lines(lambda a, b: arm7.forward_dynamics(a, b, p7), q7, v7)
    elif name.startswith("humanoid_CMU"):
        model, ph = lx.chains.from_mjcf(dm_control_suite_xml("humanoid_CMU.xml"))
        body = model.system()
        qh = jnp.zeros(body.n_configuration).at[2].set(1.0).at[3].set(1.0)
        with one_shot() if name.endswith("one shot") else contextlib.nullcontext():
            size = lines(
                lambda a, b, p: lx.simulate(body, a, b, p, t1=1.0).q, qh, jnp.zeros(body.n_dof), ph
            )
    elif name.startswith("solo12"):
        tree, ps = lx.chains.from_urdf(solo12_urdf(), floating_base=True)
        solo = tree.system()
        qs = jnp.zeros(solo.n_configuration).at[6].set(1.0)
        size = lines(lambda a, b: solo.forward_dynamics(a, b, ps), qs, jnp.zeros(solo.n_dof))
    elif name.startswith("2R"):
        arm, p2 = lx.models.planar_2r()
        q2, v2 = jnp.array([0.3, 0.8]), jnp.zeros(2)
        size = lines(lambda a, b, p: lx.simulate(arm, a, b, p, t1=1.0).q, q2, v2, p2)
    elif name == "ant forward_dynamics":
        size = lines(lambda a, b: scene.system.forward_dynamics(a, b, params), q, v)
    elif name == "ant scene forward_dynamics":
        size = lines(lambda a, b: scene.forward_dynamics(a, b, params), q, v)
    else:
        method = {"solver": "tsit5"} if name.endswith("tsit5") else {}
        size = lines(lambda a, b, p: lx.simulate(scene, a, b, p, t1=1.0, **method).q, q, v, params)
    assert size <= budget, f"{name}: {size:,} lines, over its budget of {budget:,}"


def test_one_shot_programs_take_the_compile_lean_form():
    """A tree of three phases (a body with two branches, one of which branches again):
    traced within `one_shot` (as `simulate` on concrete inputs traces its program) its
    recursions run as one scan over the bodies, a smaller program than the lanes, with
    the same accelerations to round-off; `simulate`'s eager result (the one-shot program)
    equals its result under `jax.jit` (the lanes)."""
    import numpy as np

    tree = lx.chains.Tree(
        "RRRRRR",
        parents=(-1, 0, 0, 1, 1, 3),
        axes=[(0, 0, 1), (0, 1, 0), (1, 0, 0), (0, 1, 0), (1, 0, 0), (0, 1, 0)],
    )
    offsets = [
        (0, 0, 0.3),
        (0, 0.2, 0.4),
        (0, -0.2, 0.4),
        (0.1, 0, 0.3),
        (0, 0.1, 0.3),
        (0, 0, 0.2),
    ]
    params = tree.params(offset=offsets, com=[(0.05, 0.02, 0.1)] * 6)
    system = tree.system()
    rng = np.random.default_rng(3)
    q, v = jnp.asarray(rng.normal(size=6)), jnp.asarray(rng.normal(size=6))

    def accel(a, b):
        return system.accelerations(0.0, a, b, params, None)

    lanes, lanes_value = lines(accel, q, v), jax.jit(accel)(q, v)
    with one_shot():
        lean = lines(lambda a, b: accel(a, b), q, v)
        lean_value = jax.jit(lambda a, b: accel(a, b))(q, v)
    assert lean < 0.8 * lanes, (lean, lanes)
    np.testing.assert_allclose(lean_value, lanes_value, rtol=1e-12, atol=1e-12)

    kw = dict(t1=0.5, rtol=1e-10, atol=1e-10)
    eager = lx.simulate(system, q, v, params, **kw)
    traced = jax.jit(lambda a, b, p: lx.simulate(system, a, b, p, **kw).q)(q, v, params)
    np.testing.assert_allclose(eager.q, traced, rtol=0, atol=1e-8)
