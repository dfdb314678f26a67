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

TUP=[()]+[(k,) for k in range(3)]+[(0,0),(1,1),(2,2),(0,1),(0,2),(1,2)]+[(0,0,0),(1,1,1),(2,2,2),(0,0,1),(0,0,2),(0,1,1),(1,1,2),(0,2,2),(1,2,2),(0,1,2)]
ID={t:i for i,t in enumerate(TUP)}
def tid(t): return ID[tuple(sorted(t))]
def mult(t):
    c=Counter(t); m=factorial(len(t))
    for x in c.values(): m//=factorial(x)
    return m
def lin(terms):
    """terms: list of (coeff, [factors]) -> C++ sum, folding coefficient 1 / -1 and merging repeated terms."""
    merged={}
    order=[]
    for c,f in terms:
        key=tuple(f)
        if key not in merged: order.append(key); merged[key]=0
        merged[key]+=c
    terms=[(merged[k],list(k)) for k in order]
    out=[]
    for c,f in terms:
        if c==0: continue
        body=" * ".join(f)
        if c==1: s=body
        elif c==-1: s="-"+body
        else: s=f"{float(c)!r} * {body}" if body else repr(float(c))
        out.append(s)
    if not out: return "V{}"
    r=out[0]
    for s in out[1:]: r+= (" - "+s[1:]) if s.startswith("-") else (" + "+s)
    return r
def emit_C(L):
    # phi derivative tensor C[t] at u
    L.append("  const V c0 = ph[0];")
    for k in range(3): L.append(f"  const V c{tid((k,))} = 2.0 * ph[1] * u[{k}];")
    L.append("  const V p1x2 = 2.0 * ph[1], p2x4 = 4.0 * ph[2], p3x8 = 8.0 * ph[3];")
    for t in TUP[4:10]:
        k,l=t
        L.append(f"  const V c{tid(t)} = " + (f"p1x2 + p2x4 * u[{k}] * u[{l}];" if k==l else f"p2x4 * u[{k}] * u[{l}];"))
    for t in TUP[10:]:
        k,l,m=t
        lin_=Counter()
        if k==l: lin_[m]+=1
        if k==m: lin_[l]+=1
        if l==m: lin_[k]+=1
        s=" + ".join((f"{float(c)!r} * u[{i}]" if c!=1 else f"u[{i}]") for i,c in sorted(lin_.items()))
        expr=f"p3x8 * u[{k}] * u[{l}] * u[{m}]"
        if s: expr=f"p2x4 * ({s}) + "+expr
        L.append(f"  const V c{tid(t)} = {expr};")
def remove(t, js):
    return tuple(x for i,x in enumerate(t) if i not in js)
def D_terms(t, P, Q, E, F):
    """-(P Q C_t + sum_j E[t_j] C_{t-j} + sum_{j<k} F[t_j t_k] C_{t-jk}); P,Q,E,F: factor strings or None (zero)."""
    terms=[]
    if P and Q: terms.append((-1,[P,Q,f"c{tid(t)}"]) if P!="1" and Q!="1" else (-1,[x for x in (P,Q) if x!="1"]+[f"c{tid(t)}"]))
    for j in range(len(t)):
        e=E[t[j]]
        if e: terms.append((-1,([e] if e!="1" else [])+[f"c{tid(remove(t,{j}))}"]))
    for j in range(len(t)):
        for k in range(j+1,len(t)):
            f=F[tuple(sorted((t[j],t[k])))]
            if f: 
                if isinstance(f,int): terms.append((-f,[f"c{tid(remove(t,{j,k}))}"]))
                else: terms.append((-1,[f,f"c{tid(remove(t,{j,k}))}"]))
    return terms
def contraction_entries():
    """(A, t_D, B, coeff): L[A] += coeff D[t_D] m[B]."""
    ent=[]
    for A in TUP:
        for B in TUP:
            if len(A)+len(B)>3: continue
            ent.append((ID[A], tid(A+B), ID[B], mult(B)/factorial(len(B))))
    return ent
def flat_kernel():
    L=["template <class V>","inline void far_flat3(const V* u, const V* ph, const V* n, const V* w, const V* s, V* o) {"]
    emit_C(L)
    L.append("  const V P = n[0] * u[0] + n[1] * u[1] + n[2] * u[2], Q = w[0] * u[0] + w[1] * u[1] + w[2] * u[2];")
    L.append("  const V PQ = P * Q;")
    for k in range(3): L.append(f"  const V e{k} = n[{k}] * Q + P * w[{k}];")
    for (k,l) in TUP[4:10]:
        L.append(f"  const V f{k}{l} = " + (f"2.0 * n[{k}] * w[{k}];" if k==l else f"n[{k}] * w[{l}] + n[{l}] * w[{k}];"))
    E={k:f"e{k}" for k in range(3)}; F={p:f"f{p[0]}{p[1]}" for p in TUP[4:10]}
    for t in TUP:
        terms=[(-1,["PQ",f"c{tid(t)}"])]+D_terms(t,None,None,E,F)
        L.append(f"  const V d{ID[t]} = {lin(terms)};")
    # The moments times their weight mult(B) / |B|! (once per link, where it is not 1), then one FMA per term.
    for B in TUP:
        c=mult(B)/factorial(len(B))
        if c!=1: L.append(f"  const V s{ID[B]} = {c!r} * s[{ID[B]}];")
    acc={}
    for A,td,B,c in contraction_entries():
        acc.setdefault(A,[]).append((1,[f"d{td}",f"s{B}" if c!=1 else f"s[{B}]"]))
    for A in range(20): L.append(f"  o[{A}] = {lin(acc[A])};")
    L.append("}")
    return L
def vector_kernel():
    L=["template <class V>","inline void far_vector3(const V* u, const V* ph, const V* m, V* o) {"]
    emit_C(L)
    for r in range(3):
        for i in range(r,3):
            # n = e_r, w = e_i: P = u_r, Q = u_i, E_k = delta_rk u_i + u_r delta_ik, F_kl = d_rk d_il + d_rl d_ik
            for t in TUP:
                terms=[(-1,[f"u[{r}]",f"u[{i}]",f"c{tid(t)}"])]
                for j in range(len(t)):
                    kk=t[j]; rest=f"c{tid(remove(t,{j}))}"
                    if kk==r: terms.append((-1,[f"u[{i}]",rest]))
                    if kk==i: terms.append((-1,[f"u[{r}]",rest]))
                for j in range(len(t)):
                    for k in range(j+1,len(t)):
                        a,b=t[j],t[k]
                        cnt=(a==r and b==i)+(a==i and b==r)
                        if cnt: terms.append((-cnt,[f"c{tid(remove(t,{j,k}))}"]))
                L.append(f"  const V d{r}{i}_{ID[t]} = {lin(terms)};")
    for B in TUP:
        c=mult(B)/factorial(len(B))
        if c!=1:
            for i in range(3): L.append(f"  const V m{3*ID[B]+i} = {c!r} * m[{3*ID[B]+i}];")
    acc={}
    for A,td,B,c in contraction_entries():
        for r in range(3):
            for i in range(3):
                a,b=min(r,i),max(r,i)
                acc.setdefault((A,r),[]).append((1,[f"d{a}{b}_{td}",f"m{3*B+i}" if c!=1 else f"m[{3*B+i}]"]))
    for A in range(20):
        for r in range(3): L.append(f"  o[{3*A+r}] = {lin(acc[(A,r)])};")
    L.append("}")
    return L


def main():
    w = sys.stdout.write
    w("// Generated by scripts/gen_far_field3.py: do not edit. The third-order far-field expansion of one far link (see\n")
    w("// the script's header): u = c_B - c_A, ph[m] = the m-th derivative of 1 / (pi s^2) at s = |u|^2.\n")
    w("\n".join(flat_kernel()) + "\n\n" + "\n".join(vector_kernel()) + "\n")


if __name__ == "__main__":
    main()
