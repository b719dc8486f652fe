"""Helpers shared by the tests: relative comparisons, random rotations, a central
difference against which gradients are checked, example-robot-data's folder, MJX's test
models, a missing reference that fails CI and the conservation checks of a free floating
motion."""

import os
import sys
from pathlib import Path
from typing import NoReturn

import jax
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
from _robots import robots_folder  # noqa: E402  (the benchmarks' finder)

# Python's cyclic collector in a process that traces many programs (the test workers, the
# notebooks' kernels): a young-generation collection after 100,000 net allocations instead
# of 700, once the imports' objects are frozen out of its scans (`gc.freeze()`). Tracing
# allocates and frees millions of small objects: about 5 % of the CPU of a compile-bound
# file (`test_periodic.py`: 80.5 → 76.5 s and 76.9 → 72.7 s, two pairs).
GC_THRESHOLD = (100_000, 50, 1000)


# CI (`.ci/run`, and GitHub Actions) sets CI=true: there a reference the suite relies on
# that is missing (a file of a declared dependency) fails the test instead of skipping it,
# so that a dependency's release cannot silently turn coverage off
IN_CI = os.environ.get("CI", "").lower() not in ("", "0", "false", "no")


def missing_reference(what: str) -> NoReturn:
    """Skip the calling test because the reference `what` (and how to get it) is missing
    on this machine; under CI (`IN_CI`), fail it instead. Only for references the suite
    relies on: what is optional by design (the `LAGRAX_ALL_ROBOTS=1` tier, a browser)
    skips everywhere."""
    import pytest

    if IN_CI:
        pytest.fail(f"CI: a reference the suite relies on is missing: {what}", pytrace=False)
    pytest.skip(what)


def mjx_test_data(path: str) -> Path:
    """A file of MuJoCo MJX's test models (`mujoco/mjx/test_data/<path>`: Barkour, the
    Shadow hand, the sensor model...), real MJCF files we did not write. MJX ships them:
    in the `mujoco-mjx` package since MuJoCo 3.17 split it out (a part of the `mujoco`
    namespace, a dev dependency), in the `mujoco` wheel before. `missing_reference`
    when neither has the file."""
    import importlib.util

    try:
        spec = importlib.util.find_spec("mujoco.mjx")  # imports mujoco, not mujoco.mjx
    except ModuleNotFoundError:  # no mujoco at all
        spec = None
    for folder in (spec.submodule_search_locations or []) if spec is not None else []:
        if (Path(folder) / "test_data" / path).is_file():
            return Path(folder) / "test_data" / path
    missing_reference(f"MJX's test model {path} (pip install mujoco-mjx: the dev extra)")


def rel_error(a, b) -> float:
    """`max |a − b|` relative to `max(|b|, 1)`."""
    a, b = np.asarray(a), np.asarray(b)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1.0))


def close(a, b, rtol=1e-12):
    """`a` equals `b` to `rtol` relative to `max(|b|, 1)`."""
    a, b = np.asarray(a), np.asarray(b)
    scale = max(np.max(np.abs(b)), 1.0)
    assert np.max(np.abs(a - b)) <= rtol * scale, (a, b)


def random_rotation(rng):
    """A random proper rotation matrix (`det = +1`), from the QR of a Gaussian matrix."""
    a, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return a * np.sign(np.linalg.det(a))


def central_difference(f, x, h):
    """`(f(x + h) − f(x − h)) / 2h`."""
    return (f(x + h) - f(x - h)) / (2 * h)


def check_grad_against_central_difference(f, x, h=1e-5, rtol=1e-6):
    """`jax.grad(f)(x)` of a scalar `f` of a scalar equals the central difference to
    `rtol` relative to `max(|fd|, 1)`."""
    grad = jax.grad(f)(x)
    fd = central_difference(f, x, h)
    assert abs(float(grad) - float(fd)) <= rtol * max(1.0, abs(float(fd)))


def pin_state(pin, model, tree, q, qd):
    """lagrax's coordinates as Pinocchio's (joints matched by name; a continuous joint is
    `(cos q, sin q)` in Pinocchio's configuration, its tangent the angle). A mimic joint
    of lagrax's tree is an independent joint of Pinocchio's model (built without mimic
    support) set to `a q_master + b`. Returns Pinocchio's `(q, v)` and the index in
    Pinocchio's `v` of each of lagrax's coordinates."""
    qp, vp = pin.neutral(model), np.zeros(model.nv)
    index, a, b = tree.coupling()
    for body, name in enumerate(tree.joint_names):
        joint = model.joints[model.getJointId(name)]
        angle = a[body] * q[index[body]] + b[body]
        if joint.nq == 2:
            qp[joint.idx_q : joint.idx_q + 2] = np.cos(angle), np.sin(angle)
        else:
            qp[joint.idx_q] = angle
        vp[joint.idx_v] = a[body] * qd[index[body]]
    order = [model.joints[model.getJointId(tree.joint_names[i])].idx_v for i in tree.coordinates]
    return qp, vp, np.asarray(order)


def pin_coupling(pin, model, tree):
    """`J = ∂v_pin/∂q̇`, shape `(model.nv, tree.n)`: Pinocchio's velocity of every joint
    from lagrax's coordinate rates (a permutation without mimic joints; a mimic joint's
    row holds its multiplier in its master's column). Pinocchio's equations of the
    independent joints, reduced by it (`Jᵀ M J`, `Jᵀ τ`), are lagrax's."""
    out = np.zeros((model.nv, tree.n))
    index, a, _ = tree.coupling()
    for body, name in enumerate(tree.joint_names):
        out[model.joints[model.getJointId(name)].idx_v, index[body]] = a[body]
    return out


def example_robot_data() -> Path | None:
    """example-robot-data's folder (``…/share/example-robot-data``, holding ``robots``),
    or ``None`` when it is not installed (found as the benchmarks find it)."""
    folder = robots_folder()
    return None if folder is None else Path(folder).parent


def robots_or_skip() -> Path:
    """example-robot-data's `robots` folder, or skip the calling test module when the
    package is not installed."""
    share = example_robot_data()
    if share is None:
        import pytest

        pytest.skip(
            "example-robot-data is not installed (pip install example-robot-data)",
            allow_module_level=True,
        )
    return share / "robots"


def assert_free_motion_conserved(system, params, sol, tol=1e-10):
    """A floating base's free motion (zero gravity, no inputs) in `sol`: the spatial
    momentum (angular about the world origin, and linear) and the energy constant to
    `tol` relative over the saves, the quaternion on the unit sphere at the saves (to
    1e-12) and at the end (projected each step, to 1e-14)."""
    h = np.asarray(jax.vmap(lambda q, v: system.momentum(q, v, params))(sol.q, sol.qd))
    for part in (slice(0, 3), slice(3, 6)):  # angular (about the world origin), linear
        drift = np.max(np.abs(h[:, part] - h[:1, part])) / np.linalg.norm(h[0, part])
        assert drift < tol, (part, drift)
    assert np.max(np.abs(sol.energy_error)) < tol
    assert sol.constraint_violation is not None
    assert np.max(np.abs(sol.constraint_violation)) < 1e-12  # |q_quat| − 1 at the saves
    assert abs(float(np.linalg.norm(np.asarray(sol.q_end[3:7]))) - 1.0) < 1e-14


def lqr_model(n_bodies: int, n_actuators: int):
    """The model dm_control's ``lqr`` domain builds from ``lqr.xml`` (a scene without
    bodies, refused alone): a chain of ``n_bodies`` slide joints with random springs, the
    first ``n_actuators`` driven by motors, and spatial tendons between them (limits only)."""
    import warnings

    import mujoco
    import pytest

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # dm_control's renderer looks for a display
        lqr = pytest.importorskip("dm_control.suite.lqr")
    xml, assets = lqr.get_model_and_assets(n_bodies, n_actuators, np.random.RandomState(0))
    return mujoco.MjModel.from_xml_string(xml, assets)


ALL_ROBOTS = os.environ.get("LAGRAX_ALL_ROBOTS", "") not in ("", "0")


def every_robot(reason: str):
    """A mark: the test runs with `LAGRAX_ALL_ROBOTS=1` set (the tier that holds every
    robot and the largest models, too slow to compile for the suite), where a cheaper
    test in the suite covers the same claim (`reason` names it)."""
    import pytest

    return pytest.mark.skipif(not ALL_ROBOTS, reason=f"LAGRAX_ALL_ROBOTS=1 runs it: {reason}")
