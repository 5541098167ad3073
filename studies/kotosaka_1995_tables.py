"""Seed 003 study (studies/kotosaka_1995.py): its tables. Tables 1-2 counterparts (our genes and E
beside the seed's), the ranking under both IK-branch choices (branches.md), and the breakdown of each
type's best design (analysis.md, from results.json)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from qmt_drake.design.arm_types import arm_type, forward, levels_from_gene
from qmt_drake.design.problem import DesignProblem, genes_from_levels, lengths6
from qmt_drake.design.tasks import load_task
from qmt_drake.outputs import write_text_atomic


def branch_table(rows: dict, branch: str, other: str) -> str:
    """Rankings under both branch choices, per task variant."""
    md = [f"# Branch choice: '{branch}' vs '{other}'", "",
          "task = one IK branch label (ik.branch_label) for every unit task, the best label over "
          "the whole task (seed 003 sec. 4.1); point = the best branch at each unit task (an upper "
          "bound). E in 1/m, GA best per type.", ""]
    for name, (ra, rb) in rows.items():
        eb = {r.type_name: r for r in rb}
        md += [f"## {name}", "", f"| type | {branch} gene | {branch} E | rank | {other} gene | "
               f"{other} E | rank |", "|---|---|---|---|---|---|---|"]
        rka = {r.type_name: i + 1 for i, r in enumerate(sorted(ra, key=lambda r: -r.E_per_m))}
        rkb = {r.type_name: i + 1 for i, r in enumerate(sorted(rb, key=lambda r: -r.E_per_m))}
        for r in sorted(ra, key=lambda r: -r.E_per_m):
            o = eb[r.type_name]
            md.append(f"| {r.type_name} | {r.gene_hex} | {r.E_per_m:.4f} | {rka[r.type_name]} | "
                      f"{o.gene_hex} | {o.E_per_m:.4f} | {rkb[r.type_name]} |")
        md.append("")
    return "\n".join(md) + "\n"


def table(task_name, res, seed_rows, title):
    best = max(r.E_per_m for r in res)
    lines = [f"### {title}", "",
             "| type | our gene (L1..L6, 0.1 m/level) | our E [1/m] | seed gene | seed E | our rank | seed rank |",
             "|---|---|---|---|---|---|---|"]
    ours = sorted(res, key=lambda r: -r.E_per_m)
    rank = {r.type_name: i + 1 for i, r in enumerate(ours)}
    srank = ({t: i + 1 for i, t in enumerate(sorted(seed_rows, key=lambda t: -seed_rows[t][1]))}
             if seed_rows else {})
    for r in ours:
        sg, se = seed_rows.get(r.type_name, ("", float("nan"))) if seed_rows else ("", float("nan"))
        star = "*" if r.E_per_m >= best - 1e-12 else ""
        lines.append(f"| {star}{r.type_name} | {r.gene_hex} | {r.E_per_m:.6f} | {sg} | "
                     f"{se:.10g} | {rank[r.type_name]} | {srank.get(r.type_name, '')} |")
    return "\n".join(lines) + "\n"


def analyse(out: Path, log) -> None:
    """Why the ranking is what it is: mean w (work mobility), c (constrained mobility), reach and
    sum of lengths of every type's best design, per task variant -> out/analysis.md."""
    results = json.loads((out / "results.json").read_text())
    md = ["# Breakdown of each type's best design", "",
          "w, c: means over the reachable unit tasks of eq. 4 and 5; mu_bar: eq. 7; E = mu_bar / "
          "sum L * P_k / k. mu_x.. : mean direction ease (eq. 3) per task axis.", ""]
    for name, entry in results.get("search", {}).items():
        base = name.replace("-no-obstacles", "")
        task = load_task(base)
        if name.endswith("-no-obstacles"):
            task = task.without_obstacles()
        md += [f"## {name}", "", "| type | gene | E | P_k | sum L [m] | max lateral joint abs(y) [m] | "
               "mean w | mean c | mu_bar | mu_x | mu_y | mu_z | mu_alpha | mu_beta | mu_gamma |",
               "|" + "---|" * 15]
        for T, r in sorted(entry["types"].items(), key=lambda kv: -kv[1]["E_per_m"]):
            pr = DesignProblem(task, T, branch=results.get("branch", "task"))
            g = genes_from_levels(levels_from_gene(r["gene"]))
            b = [x for x in pr.breakdown(g) if x is not None]
            if not b:
                md.append(f"| {T} | {r['gene']} | 0 | 0 | | | | | | | | | | | |")
                continue
            md_dir = np.mean([x["mu_dir"] for x in b], axis=0)
            at = arm_type(T)
            o = at.origins(lengths6(g)[0])
            ymax = max(float(np.abs(forward(at, o, np.array(u["q_rad"])[None]).points[0, :5, 1]).max())
                       for u in pr.details(g)["units"] if u["reachable"])
            mub = sum(x["mu"] for x in b) / len(task.units)
            md.append(f"| {T} | {r['gene']} | {r['E_per_m']:.4f} | {len(b)} | {lengths6(g)[0].sum():.1f} | "
                      f"{ymax:.2f} | "
                      f"{np.mean([x['w'] for x in b]):.3f} | {np.mean([x['c'] for x in b]):.3f} | {mub:.3f} | "
                      + " | ".join(f"{v:.3f}" for v in md_dir) + " |")
        md.append("")
    write_text_atomic(out / "analysis.md", "\n".join(md) + "\n")
    log("analysis written")
