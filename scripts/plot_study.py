#!/usr/bin/python3
"""Plots and tables from `lambert study` output (study.csv).

  /usr/bin/python3 scripts/plot_study.py STUDY.csv --out DIR [--doc docs/accuracy.md] [--check]

--check   validate the CSV (columns, numbers, expected cases) and that errors fall as meshes are refined;
          exit 1 with the offending row otherwise (what CI runs on the quick study).
--out     write the PNG plots there (needs Debian's python3-matplotlib; hence /usr/bin/python3).
--doc     replace the block between <!-- study:begin --> and <!-- study:end --> in that Markdown file with
          the generated tables (Pareto fronts, convergence orders, hard cases, solver iterations, machine).
"""
import argparse
import csv
import math
import os
import platform
import subprocess
import sys
from collections import defaultdict
from datetime import date

COLUMNS = ("case,variant,level,h,patches,rho,rule,ff_tolerance,rays,method,solve_tolerance,threads,t_formfactors,"
           "t_visibility,t_solve,t_total,iterations,matvecs,residual,converged,rays_cast,row_sum_dev,max_rel_error,"
           "mean_rel_error,rms_rel_error,visibility").split(",")
NUMERIC = ["level", "h", "patches", "rho", "rays", "threads", "t_formfactors", "t_visibility", "t_solve", "t_total",
           "iterations", "matvecs", "residual", "converged", "rays_cast", "row_sum_dev", "max_rel_error",
           "mean_rel_error", "rms_rel_error"]
CASES = ["opposed_squares", "common_edge", "near_touching", "sliver", "sphere_linear", "sphere_uniform", "solver",
         "furnace", "visibility", "scale"]


class Bad(Exception):
    pass


def load(path):
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header != COLUMNS:
            raise Bad(f"{path}:1: header is {header}, expected {COLUMNS}")
        rows = []
        for lineno, values in enumerate(reader, start=2):
            if len(values) != len(COLUMNS):
                raise Bad(f"{path}:{lineno}: {len(values)} fields, expected {len(COLUMNS)}")
            row = dict(zip(COLUMNS, values))
            for k in NUMERIC:
                try:
                    row[k] = float(row[k])
                except ValueError:
                    raise Bad(f"{path}:{lineno}: column {k} is not a number: {row[k]!r}")
                if math.isnan(row[k]) or (math.isinf(row[k]) and row["converged"] != "0"):
                    raise Bad(f"{path}:{lineno}: column {k} is {row[k]} in a converged run")
                if row[k] < 0:
                    raise Bad(f"{path}:{lineno}: column {k} is negative: {row[k]}")
            row["line"] = lineno
            rows.append(row)
    return rows


def select(rows, **kw):
    return [r for r in rows if all(r[k] == v for k, v in kw.items())]


def check(rows, path):
    """Well-formedness beyond parsing, and errors falling under refinement."""
    present = {r["case"] for r in rows}
    missing = [c for c in CASES if c not in present]
    if missing:
        raise Bad(f"{path}: cases missing: {missing}")

    def falls(label, seq, strict=True):
        seq = sorted(seq, key=lambda r: r["level"])
        if len(seq) < 3:
            raise Bad(f"{path}: {label}: only {len(seq)} refinement levels")
        for a, b in zip(seq, seq[1:]):
            if not b["max_rel_error"] < a["max_rel_error"]:
                raise Bad(f"{path}:{b['line']}: {label}: error does not fall from level {a['level']:g} "
                          f"({a['max_rel_error']:.3e}) to {b['level']:g} ({b['max_rel_error']:.3e})")

    # Discretisation error on the continuum sphere: falls with K for every form-factor rule.
    for rule in sorted({r["rule"] for r in select(rows, case="sphere_linear")}):
        falls(f"sphere_linear {rule}", select(rows, case="sphere_linear", rule=rule))
    # Catalogue with a smooth kernel: the fixed rules converge as the patches shrink.
    for rule in ("point", "gauss1", "gauss2"):
        falls(f"opposed_squares {rule}", select(rows, case="opposed_squares", rule=rule))
    # The adaptive rule meets its tolerance on every catalogue case and on the closed sphere (exact answer).
    for r in rows:
        if r["rule"].startswith("adaptive") and r["case"] in ("opposed_squares", "common_edge", "near_touching",
                                                              "sliver", "sphere_uniform"):
            tol = float(r["ff_tolerance"])
            if r["case"] != "sphere_uniform":
                bound = 50 * tol  # catalogue F ~ 0.2, summed over up to 16^2 x 16^2 pairs whose errors mostly cancel
            else:
                # Each F_ij within tol, so each row sum within N tol; the error then follows from the row sums:
                # at most rho dev / (1 - rho (1 + dev)) (verify.hpp), plus the solver's 1e-12.
                dev = r["row_sum_dev"]
                if dev > r["patches"] * tol:
                    raise Bad(f"{path}:{r['line']}: sphere_uniform {r['variant']} {r['rule']}: row sums off by "
                              f"{dev:.2e} > patches x tolerance")
                bound = 1.01 * r["rho"] * dev / (1 - r["rho"] * (1 + dev)) + 1e-9
            if r["max_rel_error"] > bound:
                raise Bad(f"{path}:{r['line']}: {r['case']} {r['variant']} {r['rule']}: error "
                          f"{r['max_rel_error']:.3e} above {bound:.1e}")
    for r in select(rows, case="solver"):
        if r["converged"] != 1:
            raise Bad(f"{path}:{r['line']}: solver {r['method']} rho {r['rho']} tol {r['solve_tolerance']} "
                      "did not converge")


def pareto(points):
    """Indices of points not dominated in (time, error): no other point is both faster and more accurate."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def fit_order(seq):
    """Convergence order in h from error ~ N^(-p/2) (N patches ~ h^-2), least squares over the last 3 levels."""
    seq = sorted(seq, key=lambda r: r["patches"])[-3:]
    if len(seq) < 2:
        return math.nan
    xs = [math.log(r["patches"]) for r in seq]
    ys = [math.log(max(r["max_rel_error"], 1e-300)) for r in seq]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx
    return -2 * slope


def order_text(seq):
    # An adaptive rule whose errors stay within 1000 x its tolerance is limited by the tolerance (errors of
    # many entries add up), not by the mesh: there is no discretisation order to fit.
    tol = float(seq[0]["ff_tolerance"]) if seq[0]["ff_tolerance"] else 0.0
    p = fit_order(seq)
    if not p > 0.5 and max(r["max_rel_error"] for r in seq) < max(1e3 * tol, 1e-12):
        return "at its tolerance"
    return f"order {p:.2f}"


# Panels of the error-against-time plot: (title, filter, curve key).
def panels():
    return [
        ("sphere, varying emission (continuum answer)", dict(case="sphere_linear"), "rule"),
        ("sphere, uniform, rho 0.99 (exact discrete answer)", dict(case="sphere_uniform", rho=0.99), "rule"),
        ("furnace with occluder, rho 0.9", dict(case="furnace", rho=0.9), "rays"),
        ("catalogue: touching squares (C-14)", dict(case="common_edge"), "rule"),
        ("catalogue: gap 1e-4", dict(case="near_touching", variant="gap=0.0001"), "rule"),
        ("catalogue: sliver triangles", dict(case="sliver"), "rule"),
        ("visibility: furnace rho 0.99, exact vs rays", dict(case="visibility", rho=0.99), "visibility"),
        ("visibility: room with block rho 0.9, exact vs rays", dict(case="visibility", rho=0.9), "visibility"),
    ]


def curve_label(key, value):
    return f"{value:g} rays" if key == "rays" else str(value)


def finish_axes(ax, title, xlabel, ylabel="max relative error"):
    ax.set_title(title, fontsize=10)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)


def save(plt, fig, out, name, title=None):
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(os.path.join(out, name), dpi=90)
    plt.close(fig)


def plot(rows, out):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(out, exist_ok=True)
    floor = 1e-16

    # 1. error against total time, one curve per knob, Pareto front.
    ps = panels()
    fig, axes = plt.subplots(3, 3, figsize=(16, 14))
    for ax in list(axes.flat)[len(ps):]:
        ax.set_visible(False)
    for ax, (title, flt, key) in zip(axes.flat, ps):
        sel = select(rows, **flt)
        if key == "rays":
            sel = [r for r in sel if r["rule"] == "adaptive 1e-08"]
        groups = defaultdict(list)
        for r in sel:
            groups[r[key]].append(r)
        for value in sorted(groups, key=lambda v: (isinstance(v, str), v)):
            g = sorted(groups[value], key=lambda r: r["patches"])
            ax.loglog([max(r["t_total"], 1e-5) for r in g], [max(r["max_rel_error"], floor) for r in g], "o-",
                      ms=4, label=curve_label(key, value))
        pts = [(max(r["t_total"], 1e-5), max(r["max_rel_error"], floor)) for r in sel]
        if pts:
            front = sorted((pts[i] for i in pareto(pts)))
            ax.step([p[0] for p in front], [p[1] for p in front], where="post", color="k", lw=1, alpha=0.6)
            ax.plot([p[0] for p in front], [p[1] for p in front], "s", mfc="none", mec="k", ms=9,
                    label="Pareto front")
        finish_axes(ax, title, "total time (form factors + solve) [s]")
    save(plt, fig, out, "error_vs_time.png", "lambert: error against cost (each curve: one setting over mesh levels)")

    # 2. error against patch count with fitted orders.
    fig, axes = plt.subplots(1, 3, figsize=(16, 5))
    for ax, (case, title) in zip(axes, [("sphere_linear", "sphere, varying emission"),
                                         ("opposed_squares", "catalogue: opposed squares (C-11)"),
                                         ("common_edge", "catalogue: touching squares (C-14)")]):
        groups = defaultdict(list)
        for r in select(rows, case=case):
            groups[r["rule"]].append(r)
        for rule in sorted(groups):
            g = sorted(groups[rule], key=lambda r: r["patches"])
            ax.loglog([r["patches"] for r in g], [max(r["max_rel_error"], floor) for r in g], "o-", ms=4,
                      label=f"{rule} ({order_text(g)})")
        finish_axes(ax, title, "patches")
    save(plt, fig, out, "error_vs_patches.png",
         "error against patch count; order p in h from error ~ N^(-p/2), last three levels")

    # 3. iterations against rho per method (solver tolerance 1e-8).
    sel = [r for r in select(rows, case="solver") if r["solve_tolerance"] == "1e-08"]
    fig, ax = plt.subplots(figsize=(7, 5))
    for method in ("jacobi", "gauss-seidel", "bicgstab", "gmres"):
        g = sorted(select(sel, method=method), key=lambda r: r["rho"])
        if g:
            ax.semilogy([1 / (1 - r["rho"]) for r in g], [products(r) for r in g], "o-", label=method)
    ax.set_xscale("log")
    finish_axes(ax, "solver cost against reflectance (room lit by its ceiling)", "1 / (1 - rho)",
                "products F x or sweeps (to relative residual 1e-8)")
    save(plt, fig, out, "iterations_vs_rho.png")


def products(r):
    # Jacobi and Gauss-Seidel: one sweep costs one product F x; Krylov methods count their products.
    return r["iterations"] if r["method"] in ("jacobi", "gauss-seidel") else r["matvecs"]


def fmt_e(x):
    return "inf" if math.isinf(x) else f"{x:.2e}"


def setting(r):
    s = r["rule"]
    if r["case"] in ("furnace", "scale"):
        s += f", {r['rays']:g} rays"
    if r["case"] == "visibility":
        s = f"exact, tol {r['ff_tolerance']}" if r["visibility"] == "exact" else f"{s}, {r['rays']:g} rays"
    if r["case"] == "solver":
        s = f"{r['method']}, tol {r['solve_tolerance']}"
    return s


def tables(rows):
    out = []
    # Pareto fronts.
    out.append("### Pareto-optimal settings\n")
    out.append("For each case, the runs that no other run beats in both time and max relative error "
               "(fastest first).\n")
    for title, flt, key in panels():
        sel = select(rows, **flt)
        if key == "rays":
            sel = [r for r in sel if r["rule"] == "adaptive 1e-08"]
        pts = [(r["t_total"], r["max_rel_error"]) for r in sel]
        front = sorted((sel[i] for i in pareto(pts)), key=lambda r: r["t_total"])
        out.append(f"\n**{title}**\n\n| setting | patches | time [s] | max rel. error | RMS rel. error |\n"
                   "|---|---:|---:|---:|---:|")
        for r in front:
            out.append(f"| {setting(r)} | {r['patches']:.0f} | {r['t_total']:.3g} | {fmt_e(r['max_rel_error'])} | "
                       f"{fmt_e(r['rms_rel_error'])} |")
    # Convergence orders.
    out.append("\n### Measured convergence orders\n")
    out.append("Order p in the patch size h, from error ~ N^(-p/2) fitted over the last three levels.\n")
    out.append("| case | rule | patches (last level) | max rel. error (last level) | order p |\n|---|---|---:|---:|---:|")
    for case in ("sphere_linear", "opposed_squares", "common_edge"):
        groups = defaultdict(list)
        for r in select(rows, case=case):
            groups[r["rule"]].append(r)
        for rule in sorted(groups):
            g = sorted(groups[rule], key=lambda r: r["patches"])
            out.append(f"| {case} | {rule} | {g[-1]['patches']:.0f} | {fmt_e(g[-1]['max_rel_error'])} | "
                       f"{order_text(g).replace('order ', '')} |")
    # Hard cases.
    out.append("\n### Hard cases\n")
    out.append("| case | variant | setting | rho | patches | time [s] | max rel. error | converged |\n"
               "|---|---|---|---:|---:|---:|---:|---|")
    hard = [r for r in rows if r["case"] in ("near_touching", "sliver") and r["level"] == max(
        x["level"] for x in select(rows, case=r["case"], variant=r["variant"]))]
    hard += [r for r in rows if r["case"] == "scale"]
    hard += [r for r in select(rows, case="sphere_uniform") if r["rho"] >= 0.99 and
             r["level"] == max(x["level"] for x in select(rows, case="sphere_uniform"))]
    hard += [r for r in select(rows, case="furnace", rho=0.99) if r["rule"] == "adaptive 1e-08" and
             r["level"] == max(x["level"] for x in select(rows, case="furnace"))]
    hard += [r for r in select(rows, case="solver") if r["rho"] >= 0.99 and r["solve_tolerance"] == "1e-08"]
    for r in hard:
        out.append(f"| {r['case']} | {r['variant']} | {setting(r)} | {r['rho']:g} | {r['patches']:.0f} | "
                   f"{r['t_total']:.3g} | {fmt_e(r['max_rel_error'])} | {'yes' if r['converged'] == 1 else 'NO'} |")
    # Solver.
    out.append("\n### Solver: products F x and error against rho (relative residual 1e-8)\n")
    sel = [r for r in select(rows, case="solver") if r["solve_tolerance"] == "1e-08"]
    rhos = sorted({r["rho"] for r in sel})
    out.append("| method | " + " | ".join(f"rho {x:g}" for x in rhos) + " |\n|---|" + "---:|" * len(rhos))
    for m in ("jacobi", "gauss-seidel", "bicgstab", "gmres"):
        cells = []
        for x in rhos:
            g = select(sel, method=m, rho=x)
            cells.append(f"{products(g[0]):.0f} ({fmt_e(g[0]['max_rel_error'])}, {g[0]['t_solve']:.3g} s)" if g
                         else "-")
        out.append(f"| {m} | " + " | ".join(cells) + " |")
    out.append("\nCells: products F x, or sweeps for Jacobi and Gauss-Seidel (max relative error against the "
               "1e-13 solution, solve time).")
    return "\n".join(out)


def machine():
    cpu = "unknown CPU"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return f"{os.cpu_count()} cores (`nproc`), {cpu}, {platform.system()} {platform.release()}"


def update_doc(doc, rows, csv_path, out):
    with open(doc) as f:
        text = f.read()
    begin, end = "<!-- study:begin -->", "<!-- study:end -->"
    if begin not in text or end not in text:
        raise Bad(f"{doc}: markers {begin} / {end} not found")
    runs = len(rows)
    total = sum(r["t_total"] for r in rows)
    block = (f"{begin}\n_Generated by `scripts/plot_study.py` from `{csv_path}` ({runs} runs) on {date.today()}; "
             f"machine: {machine()}._\n\n{tables(rows)}\n{end}")
    text = text[:text.index(begin)] + block + text[text.index(end) + len(end):]
    tmp = doc + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, doc)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("csv")
    ap.add_argument("--out", help="directory for the PNG plots")
    ap.add_argument("--doc", help="Markdown file whose study block is regenerated")
    ap.add_argument("--check", action="store_true", help="validate the CSV and the convergence")
    a = ap.parse_args()
    try:
        rows = load(a.csv)
        if a.check:
            check(rows, a.csv)
            print(f"plot_study: {a.csv}: {len(rows)} rows well formed; errors fall under refinement")
        if a.out:
            plot(rows, a.out)
            print(f"plot_study: plots in {a.out}")
        if a.doc:
            update_doc(a.doc, rows, a.csv, a.out)
            print(f"plot_study: tables in {a.doc}")
    except Bad as e:
        print(f"plot_study: error: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
