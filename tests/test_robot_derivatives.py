r"""The derivatives of robots as example-robot-data ships them, against Pinocchio.

`test_derivatives.py` holds `forward_dynamics_derivatives` and
`inverse_dynamics_derivatives` to Pinocchio on the project's own URDF models, and
`test_floating_base.py` on two free-flyer robots. Here the reference is Pinocchio on
shipped robots with what those two lack: a quadruped, mimic joints (the Panda's finger,
PR2's grippers, TALOS' grippers whose mimic joints come before their masters), continuous
and prismatic joints, and mass matrices with condition numbers up to 5·10⁶.

The reference is Pinocchio's `computeRNEADerivatives` at lagrax's accelerations,
reduced to lagrax's coordinates by the mimic map `J = ∂v_pin/∂q̇`
(`_helpers.pin_coupling`; a permutation without mimic joints, `blockdiag(I_6, ·)` on a
floating base). With `τ_θ` Pinocchio's inverse dynamics of its independent joints, lagrax's
equations are `Jᵀ τ_θ(θ(q), J q̇, J q̈) = τ`, so

$$
M = Jᵀ M_θ J, \qquad
\frac{∂q̈}{∂q} = −M⁻¹ Jᵀ \frac{∂τ_θ}{∂θ} J, \qquad
\frac{∂q̈}{∂q̇} = −M⁻¹ Jᵀ \frac{∂τ_θ}{∂θ̇} J, \qquad
\frac{∂q̈}{∂τ} = M⁻¹,
$$

and lagrax's `q̈` must solve Pinocchio's equations (the backward error
`|Jᵀ τ_θ − τ|` against the size of the terms). Errors grow with the condition number
`κ(M)`, so the bound is `1e-10 · max(1, κ / 10⁴)` (measured: 1e-12 or less, slack
included).

`LAGRAX_ALL_ROBOTS=1 python -m pytest tests/test_robot_derivatives.py` adds every URDF
file of the package on both bases (about 10 minutes on 2 cores: 2–12 s of compile a
robot, too slow for the suite).
"""

import os
import warnings

import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import pin_coupling, pin_state, rel_error, robots_or_skip

pin = pytest.importorskip("pinocchio", reason="Pinocchio (pip install pin) is the reference")
ROBOTS = robots_or_skip()
RTOL = 1e-10

CASES = [
    pytest.param("go2_description/urdf/go2.urdf", False, id="go2-fixed"),  # a quadruped
    pytest.param("panda_description/urdf/panda.urdf", False, id="panda-fixed"),  # mimic
    # mimic grippers, continuous joints, κ(M) ≈ 10⁶
    pytest.param("pr2_description/urdf/pr2.urdf", False, id="pr2-fixed"),
    # mimic joints before their masters, 32 coordinates
    pytest.param("talos_data/robots/talos_full_v2_box.urdf", False, id="talos-fixed"),
    # a prismatic torso, κ(M) ≈ 5·10⁶
    pytest.param("tiago_description/robots/tiago_no_hand.urdf", False, id="tiago-fixed"),
    pytest.param("g1_description/urdf/g1_29dof_rev_1_0.urdf", True, id="g1-floating"),
    pytest.param("panda_description/urdf/panda.urdf", True, id="panda-floating"),
]
if os.environ.get("LAGRAX_ALL_ROBOTS", "") not in ("", "0"):  # every file, both bases
    CASES += [
        pytest.param(str(path.relative_to(ROBOTS)), floating, id=f"{path.stem}-{base}")
        for path in sorted(ROBOTS.rglob("*.urdf"))
        for floating, base in ((False, "fixed"), (True, "floating"))
    ]


def _reference(model, tree, floating, q, qd, qdd):
    """Pinocchio's `(τ, ∂τ/∂q, ∂τ/∂q̇, M)` at lagrax's state and accelerations, reduced
    to lagrax's coordinates by the mimic map (see the module docstring)."""
    nb = 6 if floating else 0
    jac = np.hstack([np.eye(model.nv)[:, :nb], pin_coupling(pin, model, tree)])
    qp, vp, _ = pin_state(pin, model, tree, q[7 * floating :], qd[nb:])
    qp[: 7 * floating], vp[:nb] = q[: 7 * floating], qd[:nb]
    data = model.createData()
    d_q, d_v, mass = pin.computeRNEADerivatives(model, data, qp, vp, jac @ qdd)
    tau = pin.rnea(model, data, qp, vp, jac @ qdd)
    mass = np.triu(mass) + np.triu(mass, 1).T
    return jac.T @ tau, jac.T @ d_q @ jac, jac.T @ d_v @ jac, jac.T @ mass @ jac


@pytest.mark.parametrize("rel, floating", CASES)
def test_shipped_robot_derivatives_match_pinocchio(rel, floating):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lx.URDFWarning)
        try:
            robot, params = lx.chains.from_urdf(ROBOTS / rel, floating_base=floating)
        except lx.URDFError as error:  # the few files test_robot_zoo.py holds to a refusal
            pytest.skip(f"refused: {error}")
    tree = robot.tree if floating else robot
    params = {**params, "damping": jnp.zeros_like(params["damping"])}  # Pinocchio has none
    root = pin.JointModelFreeFlyer() if floating else None
    model = pin.buildModelFromUrdf(str(ROBOTS / rel), *([root] if floating else []))
    system = robot.system()
    nv = 6 * floating + tree.n
    assert model.nv == 6 * floating + tree.n_bodies
    rng = np.random.default_rng(len(rel))
    worst: dict[str, float] = {}
    for _ in range(2):
        joints, qd, tau = (rng.uniform(-1.0, 1.0, n) for n in (tree.n, nv, nv))
        if floating:
            quat = rng.normal(size=4)
            q = np.concatenate([rng.normal(size=3), quat / np.linalg.norm(quat), joints])
        else:
            q = joints
        fwd = system.forward_dynamics_derivatives(q, qd, params, tau)
        qdd = np.asarray(fwd.qdd)
        inv = system.inverse_dynamics_derivatives(q, qd, qdd, params)
        tau_ref, dq_ref, dqd_ref, mass = _reference(model, tree, floating, q, qd, qdd)
        m_inv = np.linalg.inv(mass)
        slack = max(1.0, np.linalg.cond(mass) / 1e4)
        terms = np.abs(mass) @ np.abs(qdd) + np.abs(tau_ref) + np.abs(tau)
        errors = {
            "backward": float(np.max(np.abs(tau_ref - tau) / terms)),
            "dq": rel_error(fwd.dq, -m_inv @ dq_ref),
            "dqd": rel_error(fwd.dqd, -m_inv @ dqd_ref),
            "dtau": rel_error(fwd.dtau, m_inv),
            "inverse tau": rel_error(inv.tau, tau_ref),
            "inverse dq": rel_error(inv.dq, dq_ref),
            "inverse dqd": rel_error(inv.dqd, dqd_ref),
            "inverse M": rel_error(inv.dqdd, mass),
        }
        worst = {k: max(worst.get(k, 0.0), e / slack) for k, e in errors.items()}
    assert max(worst.values()) <= RTOL, worst
