r"""A canonical form for trigonometric polynomials, found exactly and fast.

An expression that is a polynomial in `sin` and `cos` of angles that are integer
combinations of symbols (`θ₁`, `θ₁ + θ₂`, `2ψ`), with rational coefficients and any
other symbols (`m₁`, `θ̇₁`, a coordinate such as a spring's length), has one and only one
**Fourier form**

$$
A_0 + \sum_k \big(A_k \cos(k·θ) + B_k \sin(k·θ)\big),
$$

the sum over distinct frequency vectors `k` (first non-zero entry positive), with `A_k`,
`B_k` polynomials in the other symbols. It is found exactly: with `z_i = e^{iθ_i}`,
`cos(k·θ) = (z^k + z^{−k})/2` and `sin(k·θ) = (z^k − z^{−k})/(2i)` make the expression
a Laurent polynomial in the `z_i`, computed in SymPy's sparse polynomial rings (over the
Gaussian rationals, with `z_i z_i^{−1} = 1` applied as products are formed: far faster
than `expand` on expression trees), whose terms are collected by exponent and paired back
into cosines and sines. `sin² + cos² = 1`, `c₁c₁₂ + s₁s₁₂ = c₂` and every other identity
of such polynomials hold by construction, so two equal expressions have the same form and
`fourier(a − b)` is `0` exactly when `a = b`. This is the lecture's form for chains in
relative angles (`c₂`, `c₁₂`); for an expression in a single angle, `A₀ + A₂ cos 2θ` is
then written with `sin² θ` or `cos² θ` where that is shorter (`(1 − cos 2θ)/2 → sin² θ`).

The coefficients are expanded and their common factors pulled out (`factor_terms`), so
`2 l₁m₂r₂θ̇₁θ̇₂ + l₁m₂r₂θ̇₂²` multiplying `sin θ₂` prints as `l₁m₂r₂θ̇₂(2θ̇₁ + θ̇₂)`.
"""

from __future__ import annotations

from typing import Any

from .conversions import load_sympy, tree_size


class _NotPolynomial(Exception):
    """The expression is not a polynomial in the ring (a root, a division, an `exp`)."""


def _frequencies(arg: Any, angles: list[Any]) -> tuple[int, ...] | None:
    """`k` with `arg = k·angles` (`k` integers), or `None`."""
    sp = load_sympy()
    k = []
    rest = sp.expand(arg)
    for a in angles:
        coeff = rest.coeff(a, 1)
        if not (coeff.is_Integer or coeff == 0):
            return None
        k.append(int(coeff))
        rest = sp.expand(rest - coeff * a)
    return tuple(k) if rest == 0 else None


def _normalized(poly: Any, m: int) -> Any:
    """`poly` with `z_i w_i = 1` applied (`z_i` the first `m` generators, `w_i` the next
    `m`): every monomial keeps only the net power of each angle's `e^{±iθ}`."""
    out: dict[tuple[int, ...], Any] = {}
    for mon, coeff in poly.terms():
        net = [mon[i] - mon[m + i] for i in range(m)]
        key = (*(max(d, 0) for d in net), *(max(-d, 0) for d in net), *mon[2 * m :])
        out[key] = out.get(key, poly.ring.domain.zero) + coeff
    return poly.ring.from_dict({k: v for k, v in out.items() if v})


def _to_ring(expr: Any, table: dict[Any, Any], ring: Any, m: int) -> Any:
    """`expr` as an element of `ring`: atoms from `table`, rationals, sums, products and
    non-negative integer powers (normalized as they are formed); anything else raises
    `_NotPolynomial`."""
    if expr in table:
        return table[expr]
    if expr.is_Rational:
        return ring(ring.domain.convert(expr))
    if expr.is_Add:
        out = ring.zero
        for a in expr.args:
            out += _to_ring(a, table, ring, m)
        return out
    if expr.is_Mul:
        out = ring.one
        for a in expr.args:
            out = _normalized(out * _to_ring(a, table, ring, m), m)
        return out
    if expr.is_Pow and expr.exp.is_Integer and expr.exp >= 0:
        base, out = _to_ring(expr.base, table, ring, m), ring.one
        for _ in range(int(expr.exp)):
            out = _normalized(out * base, m)
        return out
    raise _NotPolynomial


def _laurent(expr: Any) -> tuple[dict, list[Any], list[Any]] | None:
    """The Laurent coefficients of `expr` in `z_i = e^{iθ_i}`: `{k: {monomial of the
    other symbols: Gaussian rational}}`, with the angles and the other symbols (a `sin`
    or `cos` of anything but an integer combination of symbols, `sin(ν t)`, counts as one
    more symbol: the result is exact, but identities between such terms are not applied);
    `None` when `expr` is not a polynomial in these."""
    sp = load_sympy()
    from sympy.polys.domains import QQ_I
    from sympy.polys.orderings import lex
    from sympy.polys.rings import ring as make_ring

    trig = expr.atoms(sp.sin, sp.cos)
    own = {a: _frequencies(a.args[0], sorted(a.args[0].free_symbols, key=str)) for a in trig}
    opaque = sorted((a for a, k in own.items() if k is None), key=str)  # sin(ν t), cos(q + π/2)
    linear = [a for a, k in own.items() if k is not None]
    angles = sorted(set().union(*(a.args[0].free_symbols for a in linear)), key=str)
    freqs = {atom: _frequencies(atom.args[0], angles) for atom in linear}
    marker = sp.Dummy("trig")
    hidden = expr.xreplace(dict.fromkeys(trig, marker)).free_symbols & set(angles)
    others = sorted(expr.free_symbols - set(angles), key=str) + sorted(hidden, key=str) + opaque
    m = len(angles)
    dummies = [sp.Dummy(f"z{i}") for i in range(m)] + [sp.Dummy(f"w{i}") for i in range(m)]
    ring, *gens = make_ring([*dummies, *others], QQ_I, lex)
    z, w = gens[:m], gens[m : 2 * m]
    table = dict(zip(others, gens[2 * m :], strict=True))
    i_unit = ring(QQ_I.from_sympy(sp.I))
    for atom, k in freqs.items():
        e, e_inv = ring.one, ring.one
        for ki, zi, wi in zip(k, z, w, strict=True):  # type: ignore[arg-type]
            e, e_inv = (
                e * (zi if ki > 0 else wi) ** abs(ki),
                e_inv * (wi if ki > 0 else zi) ** abs(ki),
            )
        table[atom] = (e + e_inv) / 2 if isinstance(atom, sp.cos) else (e - e_inv) / (2 * i_unit)
    try:
        poly = _to_ring(expr, table, ring, m)
    except _NotPolynomial:
        return None
    coeffs: dict[tuple[int, ...], dict[tuple[int, ...], Any]] = {}
    for mon, coeff in poly.terms():
        k = tuple(mon[i] - mon[m + i] for i in range(m))
        coeffs.setdefault(k, {})[mon[2 * m :]] = coeff
    return coeffs, angles, others


def _real_part(terms: dict[tuple[int, ...], Any], others: list[Any], imaginary: bool) -> Any:
    """`Σ Re(c) x^e` (or `Im`) of Gaussian-rational coefficients `c` as SymPy."""
    sp = load_sympy()
    out = []
    for mon, c in terms.items():
        part = c.y if imaginary else c.x
        if part:
            out.append(
                sp.QQ.to_sympy(part) * sp.Mul(*(x**e for x, e in zip(others, mon, strict=True)))
            )
    return sp.Add(*out)


def _half_angle(constant: Any, pairs: list[tuple[Any, Any]]) -> tuple[Any, list[tuple[Any, Any]]]:
    """`A₀ + A₂ cos 2θ` as `(A₀ + A₂) − 2A₂ sin²θ` or `(A₀ − A₂) + 2A₂ cos²θ` where that
    is shorter (for an expression in one angle `θ`, where no other term changes)."""
    sp = load_sympy()
    for index, (coeff, func) in enumerate(pairs):
        base = func.args[0] / 2
        if not (isinstance(func, sp.cos) and base.is_Symbol):
            continue
        options = [
            (constant, coeff * func),
            (sp.expand(constant + coeff), -2 * coeff * sp.sin(base) ** 2),
            (sp.expand(constant - coeff), 2 * coeff * sp.cos(base) ** 2),
        ]
        best = min(options, key=lambda o: tree_size(o[0]) + tree_size(o[1]))
        if best is not options[0]:
            return best[0], [*pairs[:index], (best[1], sp.Integer(1)), *pairs[index + 1 :]]
    return constant, pairs


def fourier(expr: Any) -> Any | None:
    """`expr` in the canonical form of the module docstring, or `None` when it is not a
    polynomial in `sin` and `cos` of integer combinations of angles (a `tan`, a
    trigonometric function in a denominator or under a root, `sin(q/2)`)."""
    sp = load_sympy()
    from sympy.polys.domains import QQ_I

    if not expr.atoms(sp.sin, sp.cos) or expr.atoms(sp.tan, sp.cot, sp.sec, sp.csc):
        return None
    found = _laurent(expr)
    if found is None:
        return None
    coeffs, angles, others = found
    constant, pairs = sp.Integer(0), []
    for k in sorted(coeffs, key=lambda k: (sum(map(abs, k)), k)):
        if k not in coeffs:
            continue  # already paired with -k
        plus = coeffs.pop(k)
        minus_k = tuple(-ki for ki in k)
        minus = coeffs.pop(minus_k, {}) if minus_k != k else {}
        if not any(k):
            if _real_part(plus, others, imaginary=True) != 0:
                return None  # a complex expression
            constant = _real_part(plus, others, imaginary=False)
            continue
        if next(ki for ki in k if ki) < 0:
            k, plus, minus = minus_k, minus, plus
        zero = QQ_I.zero
        both = set(plus) | set(minus)
        a_k = {e: plus.get(e, zero) + minus.get(e, zero) for e in both}
        b_k = {e: plus.get(e, zero) - minus.get(e, zero) for e in both}  # times i
        if _real_part(a_k, others, True) != 0 or _real_part(b_k, others, False) != 0:
            return None
        angle = sum((ki * a for ki, a in zip(k, angles, strict=True)), sp.Integer(0))
        pairs.append((_real_part(a_k, others, False), sp.cos(angle)))
        pairs.append((-_real_part(b_k, others, True), sp.sin(angle)))
    pairs = [(a, f) for a, f in pairs if a != 0]
    if len(set().union(*(f.free_symbols for _, f in pairs))) == 1:
        constant, pairs = _half_angle(constant, pairs)
    return sp.factor_terms(constant) + sp.Add(*(sp.factor_terms(a) * f for a, f in pairs))
