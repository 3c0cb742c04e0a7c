"""Generator of :mod:`ancf.forces._tendon_generated` (run once; the output is committed).

The tendon length density at a quadrature point, in the *actuator frame* (e1 = base axis, e2 = reference
direction of θ, e3 = e1 × e2), is

    w(a, b) = | a + d · (∂g/∂a)(a) · b |,     g(a) = R(t) o,   t = a / |a|,

with a = r_x, b = r_xx, o = (0, cos θ, sin θ) the routing direction in the base section, and R(t) the
Rodrigues rotation taking e1 to t:  with v = e1 × t and c = e1 · t,

    R(t) o = c o + v × o + (v · o) v / (1 + c).

Vector form (``tendon_uJ``, ``tendon_u_value``).  u(a, b) = a + d (∂g/∂a) b (3) and ∂u/∂(a, b) (3×6),
differentiated symbolically: the slack tendons' paths (:func:`ancf.forces.tendon.slack_terms`) and the
friction model's guide directions.

Scalar form (``tendon_ab``, ``tendon_ab_grad``): the density's value, gradient and Hessian.  In the
*tendon frame* (e1, o, e1 × o) — the actuator frame turned by θ about e1, where o = e2 — g is
g = (−p, 1 − p²/(1 + c), −s p/(1 + c)) with t = (c, p, s).  The frame moves along the rod with angular
velocity ω = t × t' + τ t (t' = P b/|a|, P = I − t tᵀ; twist τ = ±(e1 × t)·t'/(1 + c) of the minimal
rotation), so (∂g/∂a) b = ω × g = −(t'·g) t + τ (t × g), and t ⊥ t × g are unit vectors:

    u = A t + B (t × g),       A = |a| − d (b·g)/|a|,       B = ±d (a1 b2 − a2 b1) / (|a| (|a| + a0)),
    b·g = −a1 b0/|a| + b1 − a1 (a1 b1 + a2 b2) / (|a| (|a| + a0)),        w = |u| = √(A² + B²).

A and B are short rational functions of (a, b, |a|): their gradients and Hessians (the bb blocks vanish: A
is affine, B linear in b) take ≈ 120 common subexpressions, against ≈ 720 for the second derivatives of the
vector u.  The generated code gets 1/|a| and 1/(1 + c) as arguments ``il``, ``ic`` (the caller computes them
and checks the divisors, :mod:`ancf.forces.tendon`): they enter as functions whose derivatives are
−a_j/|a|³ and −1/(1 + c)², so the code has no fractional powers.  w's own derivatives follow by the chain
rule in :mod:`ancf.forces.tendon`.  The two forms are checked against each other and against finite
differences of the vector form's value (tests/test_tendon_scalar_form.py, tests/test_derivatives.py).

Usage::

    python -m ancf.forces._tendon_codegen      # rewrites _tendon_generated.py
"""

from __future__ import annotations

import pathlib
import time


def _u_variants(sp):
    """(code of u and Ju, code of u): the vector form in the actuator frame."""
    a = sp.Matrix(sp.symbols("a0 a1 a2", real=True))
    b = sp.Matrix(sp.symbols("b0 b1 b2", real=True))
    d, co, so = sp.symbols("d co so", real=True)
    lam = sp.sqrt(a.dot(a))
    t = a / lam
    o = sp.Matrix([0, co, so])
    v = sp.Matrix([0, -t[2], t[1]])            # e1 x t
    c = t[0]
    g = c * o + v.cross(o) + (v.dot(o)) * v / (1 + c)
    dg = g.jacobian(a)                          # 3x3
    u = a + d * dg * b                          # 3
    x = list(a) + list(b)
    Ju = u.jacobian(x)                          # 3x6
    # gradient variant (u, Ju): slack tendons' paths, friction guide directions
    repl1, red1 = sp.cse(list(u) + list(Ju), optimizations="basic")
    lines1 = [f"    {s} = {sp.pycode(e)}" for s, e in repl1]
    lines1 += [f"    u[{i}] = {sp.pycode(red1[i])}" for i in range(3)]
    lines1 += [f"    Ju[{k // 6}, {k % 6}] = {sp.pycode(red1[3 + k])}" for k in range(18)]
    body1 = "\n".join(lines1).replace("math.", "")
    # value-only variant (u): tendon lengths of a result
    repl0, red0 = sp.cse(list(u), optimizations="basic")
    lines0 = [f"    {s} = {sp.pycode(e)}" for s, e in repl0]
    lines0 += [f"    u[{i}] = {sp.pycode(red0[i])}" for i in range(3)]
    body0 = "\n".join(lines0).replace("math.", "")
    return body1, body0


def _ab_exprs(sp):
    """A, B (scalar form, tendon frame) with 1/|a|, 1/(1 + c) as differentiable functions; the symbols."""

    class IL(sp.Function):
        nargs = 3

        def fdiff(self, argindex=1):               # ∂(1/|a|)/∂a_j = −a_j/|a|³
            return -self.args[argindex - 1] * IL(*self.args) ** 3

    class IC(sp.Function):
        nargs = 1

        def fdiff(self, argindex=1):               # ∂(1/(1 + c))/∂c = −1/(1 + c)²
            return -IC(self.args[0]) ** 2

    a = sp.symbols("a0 a1 a2", real=True)
    b = sp.symbols("b0 b1 b2", real=True)
    d, il, ic = sp.symbols("d il ic", real=True)
    IL_a = IL(*a)
    IC_a = IC(a[0] * IL_a)                          # c = a0/|a|
    m = IL_a ** 2 * IC_a                            # 1/(|a| (|a| + a0))
    bg = -a[1] * b[0] * IL_a + b[1] - a[1] * (a[1] * b[1] + a[2] * b[2]) * m
    A = 1 / IL_a - d * bg * IL_a
    B = d * (a[1] * b[2] - a[2] * b[1]) * m
    return (A, B), list(a) + list(b), {IC_a: ic, IL_a: il}


def _ab_variants(sp):
    """(code of A, B with gradients and Hessians, code of A, B with gradients): the scalar form."""
    (A, B), x, rep = _ab_exprs(sp)
    vals = [A.xreplace(rep), B.xreplace(rep)]
    grads = [sp.diff(f, xi).xreplace(rep) for f in (A, B) for xi in x]
    upper = [(i, j) for i in range(6) for j in range(i, 6) if i < 3]          # bb blocks vanish
    hess = [sp.diff(f, x[i], x[j]).xreplace(rep) for f in (A, B) for i, j in upper]
    bodies = []
    for outs in (vals + grads + hess, vals + grads):
        repl, red = sp.cse(outs, optimizations="basic")
        lines = [f"    {s} = {sp.pycode(e)}" for s, e in repl]
        lines += [f"    g[{k // 6}, {k % 6}] = {sp.pycode(red[2 + k])}" for k in range(12)]
        if len(red) > 14:
            lines += ["    for k in range(2):", "        for i in range(3, 6):", "            for j in range(3, 6):",
                      "                H[k, i, j] = 0.0"]
            for n, (f, (i, j)) in enumerate([(f, ij) for f in range(2) for ij in upper]):
                lines.append(f"    H[{f}, {i}, {j}] = {sp.pycode(red[14 + n])}")
                if i != j:
                    lines.append(f"    H[{f}, {j}, {i}] = H[{f}, {i}, {j}]")
        lines.append(f"    return {sp.pycode(red[0])}, {sp.pycode(red[1])}")
        bodies.append(("\n".join(lines).replace("math.", ""), len(repl)))
    return bodies


def build() -> str:
    import sympy as sp   # a development tool (the 'dev' extra): the product itself never imports it

    t0 = time.time()
    body1, body0 = _u_variants(sp)
    (body_h, n_h), (body_g, _) = _ab_variants(sp)
    header = f'''"""GENERATED by ancf/forces/_tendon_codegen.py ({n_h} common subexpressions in ``tendon_ab``, took
{time.time() - t0:.1f} s). Do not edit: rerun ``python -m ancf.forces._tendon_codegen``.

``tendon_ab(a0, a1, a2, b0, b1, b2, d, il, ic, g, H)`` returns (A, B) of the scalar form in the tendon frame
(w = √(A² + B²)) and fills g (2, 6) = their gradients and H (2, 6, 6) = their Hessians w.r.t. (a, b), given
il = 1/|a| and ic = 1/(1 + a0 il); ``tendon_ab_grad`` only the gradients.  ``tendon_uJ(a0, a1, a2, b0, b1,
b2, d, co, so, u, Ju)`` fills, in the actuator frame, u = a + d (∂g/∂a) b (3,) and Ju = ∂u/∂(a, b) (3, 6);
``tendon_u_value`` only u.  See the generator's docstring for the definitions.
"""
from math import sqrt  # noqa: F401

from numba import njit


@njit(cache=True, fastmath=False)
def tendon_ab(a0, a1, a2, b0, b1, b2, d, il, ic, g, H):  # pragma: no cover - compiled
'''
    second = """


@njit(cache=True, fastmath=False)
def tendon_ab_grad(a0, a1, a2, b0, b1, b2, d, il, ic, g):  # pragma: no cover - compiled
    \"\"\"Like ``tendon_ab`` without the Hessians.\"\"\"
"""
    third = """


@njit(cache=True, fastmath=False)
def tendon_uJ(a0, a1, a2, b0, b1, b2, d, co, so, u, Ju):  # pragma: no cover - compiled
    \"\"\"u = a + d (∂g/∂a) b (3,) and Ju = ∂u/∂(a, b) (3, 6), actuator frame.\"\"\"
"""
    fourth = """


@njit(cache=True, fastmath=False)
def tendon_u_value(a0, a1, a2, b0, b1, b2, d, co, so, u):  # pragma: no cover - compiled
    \"\"\"Only u = a + d (∂g/∂a) b (3,).\"\"\"
"""
    return header + body_h + second + body_g + third + body1 + fourth + body0 + "\n"


if __name__ == "__main__":
    t0 = time.time()
    src = build()
    out = pathlib.Path(__file__).with_name("_tendon_generated.py")
    out.write_text(src)
    print(f"wrote {out} ({len(src.splitlines())} lines) in {time.time() - t0:.1f} s")
