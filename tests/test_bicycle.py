"""The benchmark bicycle (Meijaard, Papadopoulos, Ruina & Schwab 2007) built from lagrax's
spatial bodies and constraints, linearized about its upright steady motion: ``M, C1, K0,
K2`` against the paper's values, Table 2's eigenvalues, the weave and capsize speeds, and
perturbed parameter sets against the paper's Appendix A closed forms (which appear here
only, not in the model). Reference numbers: the paper's Table 1 and 2, as reproduced by
SymPy's ``test_kane3.py``, DynamicistToolKit and libbicycle."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from lagrax.models import benchmark_bicycle, bicycle_eigenvalues, bicycle_matrices

PAPER = {
    "M": [[80.81722, 2.31941332208709], [2.31941332208709, 0.29784188199686]],
    "C1": [[0.0, 33.86641391492494], [-0.85035641456978, 1.68540397397560]],
    "K0": [[-80.95, -2.59951685249872], [-2.59951685249872, -0.80329488458618]],
    "K2": [[0.0, 76.59734589573222], [0.0, 2.65431523794604]],
}
V_WEAVE, V_CAPSIZE = 4.29238253634111, 6.02426201538837
# Table 2: v -> (weave real part, ± imaginary part, capsize, castor)
TABLE2 = {
    1: (3.52696170990070, 0.8077402751993, -3.13423125066578, -7.11008014637442),
    2: (2.68234517512745, 1.68066296590675, -3.07158645641514, -8.67387984831735),
    3: (1.70675605663975, 2.31582447384325, -2.63366137253667, -10.35101467245920),
    4: (0.41325331521125, 3.07910818603206, -1.42944427361326, -12.15861426576450),
    5: (-0.77534188219585, 4.46486771378823, -0.32286642900409, -14.07838969279820),
    6: (-1.52644486584142, 5.87673060598709, -0.00406690076970, -16.08537123098030),
    7: (-2.13875644258362, 7.19525913329805, 0.10268170574766, -18.15788466125262),
    8: (-2.69348683581097, 8.46037971396931, 0.14327879765713, -20.27940894394569),
    9: (-3.21675402252485, 9.69377351531791, 0.15790184030917, -22.43788559040858),
    10: (-3.72016840437287, 10.90681139476287, 0.16105338653172, -24.62459635017404),
}
SPEEDS = np.arange(11.0)


@pytest.fixture(scope="module")
def bicycle():
    return benchmark_bicycle()


@pytest.fixture(scope="module")
def eigenvalues(bicycle):
    """One compiled `bicycle_eigenvalues` over 11 speeds (parameters as arguments)."""
    system, _ = bicycle
    return jax.jit(lambda p, v: bicycle_eigenvalues(system, p, v))


def _rel(a, b):
    return np.max(np.abs(np.asarray(a) - np.asarray(b))) / np.max(np.abs(np.asarray(b)))


def test_matrices_equal_the_paper(bicycle):
    system, params = bicycle
    for name, got in zip(("M", "C1", "K0", "K2"), bicycle_matrices(system, params), strict=True):
        assert _rel(got, PAPER[name]) < 1e-12, (name, np.asarray(got))


def test_table2_eigenvalues(bicycle, eigenvalues):
    _, params = bicycle
    eigs = np.asarray(eigenvalues(params, SPEEDS))
    assert eigs.shape == (11, 4) and np.iscomplexobj(eigs)
    expected = {0: [3.13164324790656, -3.13164324790656, 5.53094371765393, -5.53094371765393]}
    for v, (re, im, capsize, castor) in TABLE2.items():
        expected[v] = [re + 1j * im, re - 1j * im, capsize, castor]
    for k, v in enumerate(SPEEDS):
        for value in expected[int(v)]:
            assert np.min(np.abs(eigs[k] - value)) < 1e-10, (v, value, eigs[k])


def _section(f, lo, hi, evaluate):
    """The zero of `f(eigenvalues)` in `[lo, hi]` by 11-point sectioning (each step one
    call of the compiled eigenvalues at 11 speeds, shrinking the bracket tenfold)."""
    for _ in range(16):
        grid = np.linspace(lo, hi, 11)
        values = np.array([f(e) for e in evaluate(grid)])
        k = int(np.nonzero(np.sign(values[:-1]) != np.sign(values[1:]))[0][0])
        lo, hi = grid[k], grid[k + 1]
    return 0.5 * (lo + hi)


def test_weave_and_capsize_speeds(bicycle, eigenvalues):
    """The weave pair's real part crosses zero at `v_w`, the capsize root at `v_c`."""
    _, params = bicycle

    def evaluate(grid):
        return np.asarray(eigenvalues(params, grid))

    def weave(e):
        return np.max(e.real[np.abs(e.imag) > 1e-6])

    def capsize(e):
        return np.max(e.real[np.abs(e.imag) <= 1e-6])

    assert abs(_section(weave, 4.0, 5.0, evaluate) - V_WEAVE) < 1e-10
    assert abs(_section(capsize, 6.0, 7.0, evaluate) - V_CAPSIZE) < 1e-10


def _appendix_a(p):
    """The paper's Appendix A: `M, C1, K0, K2` in closed form from Table 1's names."""
    w, c, lam, rr, rf = p["w"], p["c"], p["lam"], p["rR"], p["rF"]
    mt = p["mR"] + p["mB"] + p["mH"] + p["mF"]
    xt = (p["xB"] * p["mB"] + p["xH"] * p["mH"] + w * p["mF"]) / mt
    zt = (-rr * p["mR"] + p["zB"] * p["mB"] + p["zH"] * p["mH"] - rf * p["mF"]) / mt
    itxx = p["IRxx"] + p["IBxx"] + p["IHxx"] + p["IFxx"] + p["mR"] * rr**2
    itxx += p["mB"] * p["zB"] ** 2 + p["mH"] * p["zH"] ** 2 + p["mF"] * rf**2
    itxz = p["IBxz"] + p["IHxz"] - p["mB"] * p["xB"] * p["zB"] - p["mH"] * p["xH"] * p["zH"]
    itxz += p["mF"] * w * rf
    itzz = p["IRxx"] + p["IBzz"] + p["IHzz"] + p["IFxx"]
    itzz += p["mB"] * p["xB"] ** 2 + p["mH"] * p["xH"] ** 2 + p["mF"] * w**2
    ma = p["mH"] + p["mF"]
    xa = (p["xH"] * p["mH"] + w * p["mF"]) / ma
    za = (p["zH"] * p["mH"] - rf * p["mF"]) / ma
    iaxx = p["IHxx"] + p["IFxx"] + p["mH"] * (p["zH"] - za) ** 2 + p["mF"] * (rf + za) ** 2
    iaxz = p["IHxz"] - p["mH"] * (p["xH"] - xa) * (p["zH"] - za)
    iaxz += p["mF"] * (w - xa) * (rf + za)
    iazz = p["IHzz"] + p["IFxx"] + p["mH"] * (p["xH"] - xa) ** 2 + p["mF"] * (w - xa) ** 2
    ua = (xa - w - c) * np.cos(lam) - za * np.sin(lam)
    s, co = np.sin(lam), np.cos(lam)
    ial = ma * ua**2 + iaxx * s**2 + 2 * iaxz * s * co + iazz * co**2
    ialx = -ma * ua * za + iaxx * s + iaxz * co
    ialz = ma * ua * xa + iaxz * s + iazz * co
    mu = c / w * co
    sr, sf = p["IRyy"] / rr, p["IFyy"] / rf
    st = sr + sf
    sa = ma * ua + mu * mt * xt
    m = [[itxx, ialx + mu * itxz], [ialx + mu * itxz, ial + 2 * mu * ialz + mu**2 * itzz]]
    k0 = [[mt * zt, -sa], [-sa, -sa * s]]
    k2 = [[0.0, (st - mt * zt) / w * co], [0.0, (sa + sf * s) / w * co]]
    c1 = [
        [0.0, mu * st + sf * co + itxz / w * co - mu * mt * zt],
        [-(mu * st + sf * co), ialz / w * co + mu * (sa + itzz / w * co)],
    ]
    return m, c1, k0, k2


def test_appendix_a_reproduces_the_paper(bicycle):
    """The closed forms (as transcribed here) give the paper's numbers."""
    _, params = bicycle
    p = {k: float(v) for k, v in params.items()}
    for name, value in zip(("M", "C1", "K0", "K2"), _appendix_a(p), strict=True):
        assert _rel(value, PAPER[name]) < 1e-12, name


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_perturbed_parameters_against_appendix_a(bicycle, seed):
    """Every Table 1 parameter moved by up to ±15 %: the linearization of the built model
    equals Appendix A's closed forms."""
    system, params = bicycle
    rng = np.random.default_rng(seed)
    p = {k: float(v) * (1.0 + 0.15 * rng.uniform(-1, 1)) for k, v in params.items()}
    got = bicycle_matrices(system, {k: jnp.asarray(v, dtype=float) for k, v in p.items()})
    for name, g, expected in zip(("M", "C1", "K0", "K2"), got, _appendix_a(p), strict=True):
        assert _rel(g, expected) < 1e-12, (seed, name)


def test_overrides_and_bad_input(bicycle):
    system, params = bicycle
    _, changed = benchmark_bicycle(mB=60.0, c=0.1)
    assert float(changed["mB"]) == 60.0 and float(changed["c"]) == 0.1
    assert float(changed["w"]) == float(params["w"])
    with pytest.raises(lx.ArgumentTypeError, match="unknown parameters"):
        benchmark_bicycle(trail=0.1)


def test_leaning_bicycle_is_not_steady(bicycle):
    """Leaning 0.1 rad while running straight: not a steady motion; the error names the
    lean's reduced acceleration. With the lean rate dependent, the speed block is
    singular (the constraints do not involve the lean rate at the upright)."""
    system, params = bicycle
    independent = ((0, 1, 2, 3, 5, 6, 7), (3, 5, 6))
    q0 = jnp.zeros(8).at[3].set(0.1)
    qd0 = jnp.zeros(8).at[0].set(5.0).at[6].set(-5.0 / 0.3).at[7].set(-5.0 / 0.35)
    q, qd = system.project(q0, qd0, params)
    with pytest.raises(lx.LagraxError, match=r"not a steady motion.*lean \(q\[3\]\) = "):
        system.linearize(q, qd, params, independent=independent)
    q_up = jnp.zeros(8)
    qd_up = jnp.zeros(8).at[0].set(5.0).at[6].set(-5.0 / 0.3).at[7].set(-5.0 / 0.35)
    with pytest.raises(lx.ConstraintError, match=r"dependent speeds.*q\[3\]"):
        system.linearize(q_up, qd_up, params, independent=(independent[0], (5, 6, 7)))


@pytest.mark.slow
def test_nonlinear_motion_follows_the_linearization(bicycle):
    """The nonlinear constrained bicycle at 5 m/s, kicked by a lean rate of 1e-4 rad/s,
    leans as `exp(A t) δx₀` of the steady-motion linearization predicts (the weave and
    capsize modes decaying), to 1e-7 relative (measured 4e-9: the nonlinear terms and
    the integrator's tolerance). Such a kick excites all modes, and after the weave has
    died out the slower capsize mode (−0.32/s against the weave's −0.78/s) is what is
    left; started along the weave's eigenvector, the motion decays at the weave's rate,
    to 1e-3 relative (the issue's target)."""
    scipy_linalg = pytest.importorskip("scipy.linalg")
    system, params = bicycle
    q = jnp.zeros(8)
    qd = jnp.zeros(8).at[0].set(5.0).at[6].set(-5.0 / 0.3).at[7].set(-5.0 / 0.35)
    a_mat, _ = system.linearize(q, qd, params, independent=((0, 1, 2, 3, 5, 6, 7), (3, 5, 6)))
    kick = 1e-4
    sol = lx.simulate(
        system, q, qd.at[3].set(kick), params, t1=4.0, n_save=41, rtol=1e-11, atol=1e-13
    )
    x0 = np.zeros(10)
    x0[7] = kick  # the lean rate in the state (q_i, u_i)
    lean = [(scipy_linalg.expm(np.asarray(a_mat) * t) @ x0)[3] for t in np.asarray(sol.ts)]
    assert _rel(sol.q[:, 3], lean) < 1e-7

    # along the weave's eigenvector (lean 1e-4 rad, its steer and rates; the pitch and
    # the dependent speeds projected onto the constraints), the nonlinear motion decays at
    # the weave's rate: its modal coordinate `wᴴ x(t)` (`w` the left eigenvector) shrinks
    # as `exp(Re λ_w t)` (notebook 10 measures 1e-7 relative)
    block = np.array([3, 4, 7, 8])  # lean, steer and their rates in (q_i, u_i)
    a4 = np.asarray(a_mat)[np.ix_(block, block)]
    eigs, right = np.linalg.eig(a4)
    left = np.linalg.inv(right)  # rows: left eigenvectors, normalized against right
    k = int(np.argmax(eigs.imag))
    x0 = 1e-4 * np.real(right[:, k] / right[0, k])
    q0 = q.at[3].set(x0[0]).at[5].set(x0[1])
    q0, qd0 = system.project(q0, qd.at[3].set(x0[2]).at[5].set(x0[3]), params)
    sol = lx.simulate(system, q0, qd0, params, t1=4.0, n_save=41, rtol=1e-11, atol=1e-13)
    x = np.asarray(jnp.stack([sol.q[:, 3], sol.q[:, 5], sol.qd[:, 3], sol.qd[:, 5]], axis=-1))
    modes = x @ left.T
    rate = np.polyfit(np.asarray(sol.ts), np.log(np.abs(modes[:, k])), 1)[0]
    assert abs(rate - eigs[k].real) < 1e-3 * abs(eigs[k].real), (rate, eigs[k])


def test_benchmark_baseline_is_sympys_published_linearization():
    """`benchmarks/bench_bicycle.py --quick` checks lagrax against the `A(v)` SymPy's
    test_kane3 hard-codes: as transcribed there, its eigenvalues are Table 2's."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_bicycle.py"
    spec = importlib.util.spec_from_file_location("bench_bicycle", path)
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    speeds = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    expected = [[re + 1j * im, re - 1j * im, cap, cas] for re, im, cap, cas in
                (TABLE2[int(v)] for v in speeds)]  # fmt: skip
    assert bench.largest_difference(bench.published_eigenvalues(speeds), expected) < 1e-10
