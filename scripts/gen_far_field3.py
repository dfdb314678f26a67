#!/usr/bin/env python3
"""Writes formfactor/src/isa/far_field3.inc: the third-order far-field expansion of the hierarchy's far links.

The hierarchical operator (formfactor/src/hierarchy_apply.cpp) sums, for a receiver point at offset a from its
cluster's centre and source points at offsets b from theirs (u = c_B - c_A between the centres),
    h(a) = sum_b K(u + b - a) v_b,   K(r) = -r r^T phi(|r|^2),   phi(s) = 1 / (pi s^2),   v_b = A_b x_b n_b,
expanded in b and a to total order 3: h(a) = sum_p L_p[(-a)^p] / p!, with
    L_p[A] = sum_{q <= 3 - p} sum_B D[A + B] m_q[B] / q!   (B over all index tuples of length q),
D the derivatives of the kernel at u and m_q the source's moments (sum v b^q). Symmetric index tuples are stored
once, in TUP's order (0: (); 1-3: x y z; 4-9: xx yy zz xy xz yz; 10-19: xxx yyy zzz xxy xxz xyy yyz xzz yzz xyz),
so a sum over B takes each stored tuple times its multiplicity.

Two kernels:
  far_flat3:   both clusters flat (receiver normal n, source normal w): the scalar kernel -(n.r)(w.r) phi, scalar
               moments s[t] = sum A x b^t, scalar outputs o[t] (20 each);
  far_vector3: any clusters: the 3 x 3 kernel, vector moments m[3 t + i] = sum A x n_i b^t and outputs o[3 t + r]
               (60 each).
The derivatives of -(P Q) phi with P = n.r, Q = w.r linear, by Leibniz:
    D_t = -(P Q C_t + sum_j E[t_j] C[t - j] + sum_{j<k} F[t_j t_k] C[t - j - k]),
    E_k = n_k Q + P w_k,   F_kl = n_k w_l + n_l w_k,
with C the derivatives of phi(|u|^2) (ph[m] = the m-th derivative of phi at |u|^2):
    C_k = 2 ph1 u_k,   C_kl = 2 ph1 delta_kl + 4 ph2 u_k u_l,
    C_klm = 4 ph2 (delta_kl u_m + delta_km u_l + delta_lm u_k) + 8 ph3 u_k u_l u_m;
the vector kernel's entry (r, i) is the scalar one with n = e_r, w = e_i. This script writes that as straight-line
code over a vector type (tests/test_hierarchy_gather.cpp checks it against the kernel summed directly).
Usage: python3 scripts/gen_far_field3.py > formfactor/src/isa/far_field3.inc
"""
import sys
from collections import Counter
from math import factorial

# The symmetric index tuples up to length 3, in the order of formfactor/src/batch.hpp (kPairs, kTriples).
TUP = ([()] + [(k,) for k in range(3)] + [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)] +
       [(0, 0, 0), (1, 1, 1), (2, 2, 2), (0, 0, 1), (0, 0, 2), (0, 1, 1), (1, 1, 2), (0, 2, 2), (1, 2, 2), (0, 1, 2)])
ID = {t: i for i, t in enumerate(TUP)}
PAIRS = TUP[4:10]
TRIPLES = TUP[10:]


def tid(t):
    """The index of a tuple in any order."""
    return ID[tuple(sorted(t))]


def mult(t):
    """How many index sequences a sorted tuple stands for."""
    m = factorial(len(t))
    for count in Counter(t).values():
        m //= factorial(count)
    return m


def weight(t):
    """The weight of a moment tuple in the contraction: mult(B) / |B|!."""
    return mult(t) / factorial(len(t))


def without(t, positions):
    """t without the indices at the given positions."""
    return tuple(x for i, x in enumerate(t) if i not in positions)


def linear(terms):
    """C++ for a sum of products: terms are (coefficient, [factor strings]); repeated products merged, 1 and -1
    folded into the sign."""
    merged = {}
    for c, factors in terms:
        merged[tuple(factors)] = merged.get(tuple(factors), 0) + c
    out = []
    for factors, c in merged.items():
        if c == 0:
            continue
        body = " * ".join(factors)
        out.append(body if c == 1 else "-" + body if c == -1 else f"{float(c)!r} * {body}")
    if not out:
        return "V{}"
    expr = out[0]
    for term in out[1:]:
        expr += " - " + term[1:] if term.startswith("-") else " + " + term
    return expr


def emit_phi_derivatives(lines):
    """c{t}: the derivatives of phi(|u|^2) along the tuple t (docstring above: C_t)."""
    lines.append("  const V c0 = ph[0];")
    for k in range(3):
        lines.append(f"  const V c{tid((k,))} = 2.0 * ph[1] * u[{k}];")
    lines.append("  const V p1x2 = 2.0 * ph[1], p2x4 = 4.0 * ph[2], p3x8 = 8.0 * ph[3];")
    for k, l in PAIRS:
        expr = f"p1x2 + p2x4 * u[{k}] * u[{l}]" if k == l else f"p2x4 * u[{k}] * u[{l}]"
        lines.append(f"  const V c{tid((k, l))} = {expr};")
    for k, l, m in TRIPLES:
        delta = Counter()  # delta_kl u_m + delta_km u_l + delta_lm u_k
        if k == l:
            delta[m] += 1
        if k == m:
            delta[l] += 1
        if l == m:
            delta[k] += 1
        first = " + ".join(f"u[{i}]" if c == 1 else f"{float(c)!r} * u[{i}]" for i, c in sorted(delta.items()))
        expr = f"p3x8 * u[{k}] * u[{l}] * u[{m}]"
        if first:
            expr = f"p2x4 * ({first}) + " + expr
        lines.append(f"  const V c{tid((k, l, m))} = {expr};")


def contraction_entries():
    """(A, D's tuple, B, weight): L[A] += weight(B) D[A + B] m[B] for |A| + |B| <= 3."""
    return [(ID[A], tid(A + B), ID[B], weight(B)) for A in TUP for B in TUP if len(A) + len(B) <= 3]


def flat_kernel():
    """Both clusters flat: the scalar kernel -(n.u)(w.u) phi, scalar moments s[t], outputs o[t]."""
    lines = ["template <class V>",
             "inline void far_flat3(const V* u, const V* ph, const V* n, const V* w, const V* s, V* o) {"]
    emit_phi_derivatives(lines)
    lines.append("  const V P = n[0] * u[0] + n[1] * u[1] + n[2] * u[2], Q = w[0] * u[0] + w[1] * u[1] + w[2] * u[2];")
    lines.append("  const V PQ = P * Q;")
    for k in range(3):
        lines.append(f"  const V e{k} = n[{k}] * Q + P * w[{k}];")
    for k, l in PAIRS:
        expr = f"2.0 * n[{k}] * w[{k}]" if k == l else f"n[{k}] * w[{l}] + n[{l}] * w[{k}]"
        lines.append(f"  const V f{k}{l} = {expr};")
    # D_t = -(P Q C_t + sum_j E[t_j] C[t - j] + sum_{j<k} F[t_j t_k] C[t - j - k])
    for t in TUP:
        terms = [(-1, ["PQ", f"c{tid(t)}"])]
        terms += [(-1, [f"e{t[j]}", f"c{tid(without(t, {j}))}"]) for j in range(len(t))]
        terms += [(-1, ["f{}{}".format(*sorted((t[j], t[k]))), f"c{tid(without(t, {j, k}))}"])
                  for j in range(len(t)) for k in range(j + 1, len(t))]
        lines.append(f"  const V d{ID[t]} = {linear(terms)};")
    # The moments times their weight (once per link, where it is not 1), then one FMA per term.
    for B in TUP:
        if weight(B) != 1:
            lines.append(f"  const V s{ID[B]} = {weight(B)!r} * s[{ID[B]}];")
    acc = {}
    for A, d, B, c in contraction_entries():
        acc.setdefault(A, []).append((1, [f"d{d}", f"s{B}" if c != 1 else f"s[{B}]"]))
    for A in range(len(TUP)):
        lines.append(f"  o[{A}] = {linear(acc[A])};")
    lines.append("}")
    return lines


def vector_kernel():
    """Any clusters: the 3 x 3 kernel, vector moments m[3 t + i], outputs o[3 t + r]. Entry (r, i) is the scalar
    kernel with n = e_r, w = e_i: P = u_r, Q = u_i, E_k = delta_rk u_i + u_r delta_ik, F_kl = delta_rk delta_il +
    delta_rl delta_ik."""
    lines = ["template <class V>", "inline void far_vector3(const V* u, const V* ph, const V* m, V* o) {"]
    emit_phi_derivatives(lines)
    for r in range(3):
        for i in range(r, 3):
            for t in TUP:
                terms = [(-1, [f"u[{r}]", f"u[{i}]", f"c{tid(t)}"])]
                for j in range(len(t)):
                    rest = f"c{tid(without(t, {j}))}"
                    if t[j] == r:
                        terms.append((-1, [f"u[{i}]", rest]))
                    if t[j] == i:
                        terms.append((-1, [f"u[{r}]", rest]))
                for j in range(len(t)):
                    for k in range(j + 1, len(t)):
                        count = (t[j] == r and t[k] == i) + (t[j] == i and t[k] == r)
                        if count:
                            terms.append((-count, [f"c{tid(without(t, {j, k}))}"]))
                lines.append(f"  const V d{r}{i}_{ID[t]} = {linear(terms)};")
    for B in TUP:
        if weight(B) != 1:
            for i in range(3):
                lines.append(f"  const V m{3 * ID[B] + i} = {weight(B)!r} * m[{3 * ID[B] + i}];")
    acc = {}
    for A, d, B, c in contraction_entries():
        for r in range(3):
            for i in range(3):
                a, b = min(r, i), max(r, i)
                acc.setdefault((A, r), []).append(
                    (1, [f"d{a}{b}_{d}", f"m{3 * B + i}" if c != 1 else f"m[{3 * B + i}]"]))
    for A in range(len(TUP)):
        for r in range(3):
            lines.append(f"  o[{3 * A + r}] = {linear(acc[(A, r)])};")
    lines.append("}")
    return lines


def main():
    w = sys.stdout.write
    w("// Generated by scripts/gen_far_field3.py: do not edit. The third-order far-field expansion of one far link (see\n")
    w("// the script's header): u = c_B - c_A, ph[m] = the m-th derivative of 1 / (pi s^2) at s = |u|^2.\n")
    w("\n".join(flat_kernel()) + "\n\n" + "\n".join(vector_kernel()) + "\n")


if __name__ == "__main__":
    main()
