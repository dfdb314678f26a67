#!/usr/bin/env python3
"""Writes formfactor/src/isa/far_field3.inc: the third-order far-field expansion of the hierarchy's far links.

The hierarchical operator (formfactor/src/hierarchy_apply.cpp) sums, for a receiver point at offset a from its
cluster's centre and the source points at offsets b from theirs (u = c_B - c_A between the centres),
    h(a) = sum_b K(u + b - a) v_b,   K(r) = -r r^T / (pi |r|^4),   v_b = A_b x_b n_b,
expanded in b and a to total order 3. With d = b - a, s = |u|^2 and phi_m the m-th derivative of
phi(s) = 1 / (pi s^2), the kernel is -(u + d) ((u + d).v) phi(s + 2 u.d + d.d), whose terms of order k in d are
    h_k = -[u (u.v) Phi_k + (u (d.v) + d (u.v)) Phi_{k-1} + d (d.v) Phi_{k-2}],
    Phi_0 = phi_0, Phi_1 = 2 phi_1 (u.d), Phi_2 = phi_1 |d|^2 + 2 phi_2 (u.d)^2,
    Phi_3 = 2 phi_2 (u.d) |d|^2 + 4/3 phi_3 (u.d)^3.
Summed over the source points, the powers of b become the source's moments
    V = sum v, W(:, k) = sum v b_k, T(:, kl) = sum v b_k b_l, U(:, klm) = sum v b_k b_l b_m,
and the powers of a the receiver's local expansion h(a) = sum_p L_p[(-a)^p] / p!:
    g = L_0 (3), J = L_1 (3 x 3), H = L_2 (3 x 6: xx yy zz xy xz yz), C = L_3 (3 x 10, kTriples' order).
The expressions are simplified by common subexpressions (sympy's cse) and written as straight-line code over a
vector type. Needs python3-sympy (Debian); the project builds from the generated file, which is committed.
Usage: python3 scripts/gen_far_field3.py > formfactor/src/isa/far_field3.inc
"""
import sys
from collections import Counter
from math import factorial

import sympy as sp

PAIRS = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]
TRIPLES = [(0, 0, 0), (1, 1, 1), (2, 2, 2), (0, 0, 1), (0, 0, 2), (0, 1, 1), (1, 1, 2), (0, 2, 2), (1, 2, 2), (0, 1, 2)]
TUPLES = [[()], [(0,), (1,), (2,)], PAIRS, TRIPLES]
OFFSET = [0, 3, 12, 30]  # where each order starts in the moments m[] and in the outputs o[]
ORDER = 3


def mult(t):
    c = Counter(t)
    m = factorial(len(t))
    for x in c.values():
        m //= factorial(x)
    return m


u = sp.symbols("u0:3")
a = sp.symbols("a0:3")
b = sp.symbols("b0:3")
v = sp.symbols("v0:3")
ph = sp.symbols("ph0:4")
m = sp.symbols("m0:60")


def moment(i, bt):
    q = len(bt)
    return m[OFFSET[q] + 3 * TUPLES[q].index(bt) + i]


def expansion():
    d = [b[k] - a[k] for k in range(3)]
    ud = sum(u[k] * d[k] for k in range(3))
    dd = sum(x * x for x in d)
    uv = sum(u[k] * v[k] for k in range(3))
    dv = sum(d[k] * v[k] for k in range(3))
    Phi = [ph[0], 2 * ph[1] * ud, ph[1] * dd + 2 * ph[2] * ud**2,
           2 * ph[2] * ud * dd + sp.Rational(4, 3) * ph[3] * ud**3]
    h = []
    for row in range(3):
        t = 0
        for k in range(ORDER + 1):
            t += u[row] * uv * Phi[k]
            if k >= 1:
                t += (u[row] * dv + d[row] * uv) * Phi[k - 1]
            if k >= 2:
                t += d[row] * dv * Phi[k - 2]
        h.append(sp.Poly(sp.expand(-t), *a))
    outs = []
    for p in range(ORDER + 1):
        for at in TUPLES[p]:
            for row in range(3):
                alpha = tuple(at.count(k) for k in range(3))
                c = h[row].as_dict().get(alpha, 0)
                L = sp.expand(c * factorial(p) * (-1) ** p / mult(at))  # h's monomial a^alpha has L_p's entry x this
                acc = 0
                if L != 0:
                    P = sp.Poly(L, *b, *v)
                    for mon, co in zip(P.monoms(), P.coeffs()):
                        bt = tuple(sorted(sum([[k] * mon[k] for k in range(3)], [])))
                        acc += co * moment(mon[3:].index(1), bt)
                outs.append(acc)
    return outs


def c_expr(e, names):
    """C++ for a sympy expression over the vector type: integer powers as products, rationals as doubles."""
    if e in names:
        return names[e]
    if e.is_Number:
        return repr(float(e))
    if e.is_Add:
        terms = [c_expr(t, names) for t in e.args]
        s = terms[0]
        for t in terms[1:]:
            s += " - " + t[1:] if t.startswith("-") else " + " + t
        return "(" + s + ")"
    if e.is_Mul:
        coeff, rest = e.as_coeff_Mul()
        factors = [c_expr(f, names) for f in sp.Mul.make_args(rest)]
        body = " * ".join(factors)
        if coeff == 1:
            return body
        if coeff == -1:
            return "-" + body if len(factors) > 1 or not body.startswith("(") else "-" + body
        return repr(float(coeff)) + " * " + body
    if e.is_Pow and e.exp.is_Integer and e.exp > 0:
        base = c_expr(e.base, names)
        return " * ".join([base] * int(e.exp))
    raise ValueError(f"cannot print {e}")


def main():
    outs = expansion()
    repl, red = sp.cse(outs, symbols=sp.numbered_symbols("t"))
    names = {}
    for k in range(3):
        names[u[k]] = f"u[{k}]"
    for k in range(4):
        names[ph[k]] = f"ph[{k}]"
    for k in range(60):
        names[m[k]] = f"m[{k}]"
    lines = []
    for sym, expr in repl:
        lines.append(f"  const V {sym} = {c_expr(expr, names)};")
        names[sym] = str(sym)
    for k, expr in enumerate(red):
        lines.append(f"  o[{k}] = {c_expr(expr, names) if expr != 0 else 'V{}'};")
    w = sys.stdout.write
    w("// Generated by scripts/gen_far_field3.py: do not edit. The third-order far-field expansion of one far link\n")
    w("// (see the script's header): from u = c_B - c_A, ph[m] = the m-th derivative of 1 / (pi s^2) at s = |u|^2 and\n")
    w("// the source's moments m[0..59] (V 3, W 3 x 3, T 3 x 6, U 3 x 10, column-major: W(i, k) = m[3 + 3 k + i]),\n")
    w("// the receiver's local expansion o[0..59] (g 3, J 3 x 3, H 3 x 6, C 3 x 10, column-major likewise).\n")
    w("template <class V>\n")
    w("inline void far_expansion3(const V* u, const V* ph, const V* m, V* o) {\n")
    w("\n".join(lines) + "\n}\n")


if __name__ == "__main__":
    main()
