"""Integration methods: convergence orders, structure preservation, stiff and failure cases."""

import math

import diffrax as dfx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from lagrax.bench import precision as wp
from lagrax.bench import stability as st
from lagrax.integrators import Rodas4

ARM, P = lx.models.planar_2r()
Q0 = jnp.array([-math.pi / 2 + 0.6, 0.4])  # regular motion
QD0 = jnp.zeros(2)


# nominal order, horizon, and a step ladder inside the asymptotic range, above round-off.
# Dopri8's error at a fixed step is erratic step to step on this arm (local slopes 4-12),
# so its order is fitted over a wider ladder.
ORDERS = {
    "rk4": (4, 1.0, (0.02, 0.01, 0.005)),
    "tsit5": (5, 1.0, (0.05, 0.025, 0.0125)),
    "dopri5": (5, 1.0, (0.05, 0.025, 0.0125)),
    "dopri8": (8, 3.0, (0.3, 0.2, 0.15, 0.1, 0.075, 0.05)),
    "kvaerno5": (5, 1.0, (0.05, 0.025, 0.0125)),
    "rodas4": (4, 1.0, (0.05, 0.025, 0.0125)),
    "variational": (2, 1.0, (0.04, 0.02, 0.01)),
    "variational4": (4, 1.0, (0.04, 0.02, 0.01)),
}


@pytest.fixture(scope="module")
def references():
    return {
        t1: lx.simulate(ARM, Q0, QD0, P, t1=t1, solver="dopri8", rtol=1e-14, atol=1e-14)
        for t1 in (1.0, 3.0)
    }


@pytest.mark.parametrize("method", sorted(ORDERS))
def test_measured_convergence_order(method, references):
    order, t1, dts = ORDERS[method]
    errs = []
    for dt in dts:
        sol = lx.simulate(
            ARM,
            Q0,
            QD0,
            P,
            t1=t1,
            solver=method,
            dt=dt,
            rtol=1e-13,
            atol=1e-13,
            max_steps=4096,
            n_save=2,
        )
        errs.append(float(jnp.max(jnp.abs(sol.q_end - references[t1].q_end))))
    slope = np.polyfit(np.log(dts), np.log(errs), 1)[0]
    assert abs(slope - order) <= 0.3, (method, errs, slope)


def test_variational_energy_bounded_without_trend():
    t1 = 600.0
    sol = lx.simulate(ARM, Q0, QD0, P, t1=t1, solver="variational", dt=0.02, n_save=1201)
    slope, emax = st.energy_trend(sol.ts, sol.energy_error)
    assert emax < 1e-3
    assert abs(slope) * t1 < 0.05 * emax  # no secular drift: the trend is noise
    # the second half is no worse than the first (bounded, not growing)
    err = np.abs(np.asarray(sol.energy_error))
    assert err[600:].max() < 1.5 * err[:600].max()


def test_variational_conserves_momentum_of_a_cyclic_coordinate():
    # without gravity θ1 is cyclic: p1 = ∂L/∂θ̇1 (total angular momentum) is conserved
    p0 = {**P, "g": jnp.asarray(0.0)}
    q0, qd0 = jnp.array([0.3, 1.2]), jnp.array([2.0, -3.0])
    mom = jax.vmap(lambda q, qd: ARM.momentum(q, qd, p0))
    vi = lx.simulate(ARM, q0, qd0, p0, t1=20.0, solver="variational", dt=0.01, n_save=401)
    p_vi = np.asarray(mom(vi.q, vi.qd))[:, 0]
    assert np.max(np.abs(p_vi - p_vi[0])) < 1e-11 * abs(p_vi[0])
    # an explicit method at a loose tolerance does drift: the check above can fail
    rk = lx.simulate(ARM, q0, qd0, p0, t1=20.0, solver="tsit5", rtol=1e-5, atol=1e-5, n_save=401)
    p_rk = np.asarray(mom(rk.q, rk.qd))[:, 0]
    assert np.max(np.abs(p_rk - p_rk[0])) > 1e3 * np.max(np.abs(p_vi - p_vi[0]))


def test_variational_with_damping_dissipates_like_the_continuous_system():
    # Lagrange–d'Alembert forcing: damped arm loses energy; agrees with an adaptive solve
    system, params = st.stiff_arm(1.0)  # soft spring/damper at joint 2: not stiff
    ref = lx.simulate(
        system, Q0, QD0, params, t1=2.0, solver="dopri8", rtol=1e-12, atol=1e-12, n_save=2
    )
    vi = lx.simulate(system, Q0, QD0, params, t1=2.0, solver="variational", dt=0.002, n_save=2)
    assert float(jnp.max(jnp.abs(vi.q_end - ref.q_end))) < 1e-4
    assert float(vi.energy[-1]) < float(vi.energy[0])


def test_variational_refuses_an_adaptive_step():
    with pytest.raises(ValueError, match="fixed step"):
        lx.simulate(ARM, Q0, QD0, P, t1=1.0, solver="variational")
    with pytest.raises(ValueError, match="fixed step"):
        lx.simulate(ARM, Q0, QD0, P, t1=1.0, solver=lx.integrators.RK4())


def test_variational_refuses_an_unknown_order():
    with pytest.raises(lx.ConfigurationError, match="order_=3"):
        lx.integrators.Variational(order_=3)


def test_unknown_method_is_named():
    with pytest.raises(ValueError, match="unknown method 'rk45'"):
        lx.simulate(ARM, Q0, QD0, P, t1=1.0, solver="rk45")


def test_implicit_matches_explicit_on_a_non_stiff_problem(references):
    sol = lx.simulate(ARM, Q0, QD0, P, t1=1.0, solver="kvaerno5", rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(sol.q, references[1.0].q, atol=1e-7)


# ------------------------------------------------------------------ Rodas4
# Prothero–Robinson: y' = λ (y − g(t)) + g'(t), y(0) = g(0), whose solution is g(t) for
# every λ: a closed form that is stiff for λ ≪ 0 and needs the method's ∂f/∂t term
def _prothero_robinson(lam):
    def field(t, y, args):
        del args
        return lam * (y - jnp.sin(t)) + jnp.cos(t)

    return dfx.ODETerm(field)


def test_rodas4_is_fourth_order_on_a_time_dependent_field():
    errs, dts = [], (0.1, 0.05, 0.025)
    for dt in dts:
        sol = dfx.diffeqsolve(
            _prothero_robinson(-1.0), Rodas4(), 0.0, 2.0, dt, jnp.zeros(1),
            stepsize_controller=dfx.ConstantStepSize(), max_steps=200,
        )  # fmt: skip
        errs.append(abs(float(sol.ys[-1, 0]) - math.sin(2.0)))
    slope = np.polyfit(np.log(dts), np.log(errs), 1)[0]
    assert 3.7 < slope < 4.6, (errs, slope)


def test_rodas4_is_l_stable_a_stiff_mode_is_damped_in_one_step():
    # h λ = −1e6: an explicit method blows up; an L-stable, stiffly accurate one damps
    # the stiff mode in one step and lands on the slow solution g(t1), up to the method's
    # own error on g at this step (8.8e-6)
    y0 = jnp.array([1.0])  # off the slow solution sin(0) = 0 by 1
    y1, _, _, _, _ = Rodas4().step(_prothero_robinson(-1e7), 0.0, 0.1, y0, None, None, False)
    assert abs(float(y1[0]) - math.sin(0.1)) < 2e-5


def test_rodas4_dense_output_is_third_order():
    term, s = _prothero_robinson(-1.0), Rodas4()
    errs, hs = [], (0.2, 0.1, 0.05)
    for h in hs:
        y0 = jnp.array([0.3])  # off sin(0): the solution is sin t + 0.3 e^{−t}
        _, _, dense, _, _ = s.step(term, 0.0, h, y0, None, None, False)
        path = s.interpolation_cls(t0=0.0, t1=h, **dense)
        t = np.array([0.25, 0.5, 0.75]) * h
        exact = np.sin(t) + 0.3 * np.exp(-t)
        pairs = zip(t, exact, strict=True)
        errs.append(max(abs(float(path.evaluate(ti)[0]) - e) for ti, e in pairs))
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert slope > 3.7, (errs, slope)  # a local error O(h⁴) of a third-order interpolant


def test_rodas4_derivatives_agree_in_both_modes_and_with_differences():
    system, params = st.stiff_arm(1e4)
    q0 = jnp.array([-math.pi / 2 + 1.0, 0.5])

    def final(speed):
        qd0 = jnp.array([speed, 0.0])
        sol = lx.simulate(system, q0, qd0, params, t1=0.2, solver="rodas4", rtol=1e-11,
                          atol=1e-11)  # fmt: skip
        return sol.q_end[0]

    grad, fwd = jax.grad(final)(0.5), jax.jacfwd(final)(0.5)
    e = 1e-4
    central = (final(0.5 + e) - final(0.5 - e)) / (2 * e)
    central_half = (final(0.5 + e / 2) - final(0.5 - e / 2)) / e
    assert abs(central - central_half) < 1e-7 * abs(central)  # the differences converged
    np.testing.assert_allclose([grad, fwd], [central, central], rtol=1e-6)


@pytest.mark.parametrize("tangents", [False, True], ids=["one tangent", "three tangents"])
def test_rodas4_on_sensitivities_equals_its_step_on_the_full_state(tangents):
    """The structured step (the augmented system's Jacobian formed along the state only,
    one LU of the state's block) against the same step on the augmented field seen as
    an opaque function (its Jacobian formed in full): the same numbers to round-off,
    on a pytree state, a time-dependent field and a perturbed argument."""
    from lagrax._solve.sensitivities import Sensitivities

    def field(t, y, a):
        return {"q": y["v"], "v": -a * jnp.sin(y["q"]) * (1.0 + t) - y["v"] ** 3}

    y = {"q": jnp.array([0.3, 1.0]), "v": jnp.array([0.2, -0.5])}
    rng = np.random.default_rng(3)
    shape = (3, 2) if tangents else (2,)
    s = {"q": jnp.asarray(rng.normal(size=shape)), "v": jnp.asarray(rng.normal(size=shape))}
    da = jnp.array([0.0, 1.0, -1.0]) if tangents else jnp.array(1.0)
    aug = Sensitivities(field, tangents)
    args = (jnp.array(2.0), da)
    structured = Rodas4().step(dfx.ODETerm(aug), 0.1, 0.35, (y, s), args, None, False)
    opaque = dfx.ODETerm(lambda t, ys, a: aug(t, ys, a))
    full = Rodas4().step(opaque, 0.1, 0.35, (y, s), args, None, False)
    for a, b in zip(jax.tree.leaves(structured[:3]), jax.tree.leaves(full[:3]), strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-13)
    assert float(jnp.max(jnp.abs(structured[0][1]["v"] - s["v"]))) > 1e-2  # it moved


def test_new_step_size_does_not_recompile():
    traces = []

    def kinetic(q, qd, p):
        if isinstance(q, jax.core.Tracer):
            traces.append(1)
        return lx.models._planar_2r.kinetic(q, qd, p)

    system = lx.LagrangianSystem(kinetic, lx.models._planar_2r.potential, n_dof=2)
    lx.simulate(system, Q0, QD0, P, t1=1.0, solver="variational", dt=0.01, max_steps=256)
    n = len(traces)
    lx.simulate(system, Q0, QD0, P, t1=1.5, solver="variational", dt=0.007, max_steps=256)
    assert len(traces) == n


# ------------------------------------------------------------------ atlas failures
@pytest.mark.parametrize("implicit", ["kvaerno5", "rodas4"])
def test_stiff_scene_explicit_fails_implicit_completes(implicit):
    system, params = st.stiff_arm(1e6)
    q0 = jnp.array([-math.pi / 2 + 1.0, 0.5])
    with pytest.raises(lx.SimulationError, match="solver='rodas4' or 'kvaerno5'"):
        lx.simulate(system, q0, QD0, params, t1=0.5, rtol=1e-6, atol=1e-6, max_steps=2000)
    sol = lx.simulate(system, q0, QD0, params, t1=0.5, solver=implicit, rtol=1e-6, atol=1e-6)
    assert int(sol.stats["num_steps"]) < 500
    # the stiff spring holds joint 2 at its rest angle (0.3 rad) once the transient decays
    assert abs(float(sol.q_end[1]) - 0.3) < 1e-3


def test_fixed_step_past_stability_limit_is_reported_not_nan():
    system, params = st.stiff_arm(1e6)
    q0 = jnp.array([-math.pi / 2 + 1.0, 0.5])
    with pytest.raises(lx.SimulationError, match="blew up"):
        lx.simulate(system, q0, QD0, params, t1=0.1, solver="rk4", dt=1e-3)
    sol = lx.simulate(system, q0, QD0, params, t1=0.1, solver="rk4", dt=1e-3, throw=False)
    assert not bool(sol.ok)
    assert sol.result == lx.RESULTS.non_finite_state


def test_singular_coordinates_detected_with_remedy():
    sph, p = st.spherical_pendulum("spherical")
    with pytest.raises(lx.MassMatrixError, match="change coordinates") as info:
        lx.simulate(sph, [0.0, 0.0], [0.5, 0.0], p, t1=1.0)
    assert "q=[0. 0.]" in str(info.value)
    xy, _ = st.spherical_pendulum("xy")  # the remedy: regular at the bottom
    sol = lx.simulate(xy, [0.0, 0.0], [0.5, 0.0], p, t1=1.0, rtol=1e-10, atol=1e-10)
    assert float(jnp.max(jnp.abs(sol.energy_error))) < 1e-8


def test_chaos_horizon_grows_with_tolerance():
    rows, curves = st.chaos(t1=20.0, tolerances=(1e-5, 1e-9))
    horizons = []
    for tol in (1e-5, 1e-9):
        ts, dq = curves[tol]
        over = np.nonzero(dq > 0.1)[0]
        horizons.append(ts[over[0]] if over.size else np.inf)
    assert horizons[0] < 20.0  # the loose solution does lose the trajectory
    assert horizons[1] > horizons[0] + 2.0
    assert f"{horizons[0]:.1f} s" in rows[0].detail


# ------------------------------------------------------------------ work-precision
def test_work_precision_csv_error_monotone_in_tolerance(tmp_path):
    ladders = {"tsit5": ("rtol", (1e-4, 1e-6, 1e-8, 1e-10)), "rk4": ("dt", (0.02, 0.01))}
    points, ref_err = wp.work_precision(ARM, Q0, QD0, P, t1=2.0, ladders=ladders, repeats=1)
    assert ref_err < 1e-9
    path = wp.write_csv(points, tmp_path / "wp.csv")
    import csv

    with path.open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 6
    errs = [float(r["final_error"]) for r in rows if r["method"] == "tsit5"]
    assert all(a > b for a, b in zip(errs, errs[1:], strict=False)), errs
    assert all(r["ok"] == "True" for r in rows)
    rk4 = [r for r in rows if r["method"] == "rk4"]
    assert float(rk4[0]["rhs_evals"]) == 4 * int(rk4[0]["steps"])
    fig = wp.plot_work_precision(points, reference_error=ref_err)
    fig.savefig(tmp_path / "wp.png")
