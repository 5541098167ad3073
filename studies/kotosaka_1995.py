"""Seed 003 (Kotosaka et al. 1995) reproduced with our reconstruction: writes out/kotosaka_1995/.

  tables.md          Tables 1-2 counterparts (ours beside the seed's genes and E), no-obstacle runs
  results.json       every number below
  types.png          the ten joint combinations (Fig. 4 counterpart)
  fig6_*.png         best arms at the task points (Fig. 6 counterpart)
  fig7_*.png         best E per batch of 200 designs (Fig. 7 counterpart)
  urdf/<task>/<type>.urdf   each type's best design
  exhaustive_*.json  the certificate: every distinct design of one type

  branches.md        rankings with one IK branch for the whole task (the seed's) vs per point

Usage: PYTHONPATH=$PWD MPLBACKEND=Agg python -m studies.kotosaka_1995 [--workers 2]
       [--branch task|point] [--compare-branch] [--skip-scaling]
       python -m studies.kotosaka_1995 --skip-search --exhaustive BP:task1_welding_plate [--ga-seeds 5]
       python -m studies.kotosaka_1995 --codesign

Per type the project's GA (seed 003's settings, search.SEED_GA); the exhaustive search over every
distinct design of one type certifies the GA's answer. --compare-branch also runs every task with
the other branch choice and writes branches.md.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from qmt_drake.design.arm_types import arm_type, forward, levels_from_gene, urdf_text
from qmt_drake.design.operability import direction_ease, operability
from qmt_drake.design.plots import meshcat_arm_at_task, plot_arm_at_task, plot_convergence, plot_types
from qmt_drake.design.problem import DesignProblem, genes_from_levels, lengths6
from qmt_drake.design.search import exhaustive, run_all_types
from qmt_drake.design.tasks import load_task
from qmt_drake.outputs import jsonable, write_text_atomic

OUT = Path("out/kotosaka_1995")
# Seed 003, Tables 1 and 2 (gene = L1..L6 levels in hex; E in the seed's unknown length unit).
SEED = {
    "task1_welding_plate": {"BP": ("0db000", 1.1884243932), "BB": ("276100", 0.5092444674),
                            "BF": ("903500", 1.1791690745), "BT": ("092101", 0.7302520625),
                            "PB": ("b05500", 1.2026586150), "PF": ("b08200", 1.2026586150),
                            "PT": ("b00a00", 1.2026586150), "FP": ("0d4700", 1.1884243932),
                            "FF": ("b98300", 1.1069054031), "FT": ("ab630d", 0.7145293031)},
    "task2_welding_opening": {"BP": ("041603", 1.9950999716), "BB": ("211703", 0.9834830242),
                              "BF": ("404403", 2.0107272289), "BT": ("255103", 1.1063682008),
                              "PB": ("401703", 1.9425050569), "PF": ("405303", 1.9425050569),
                              "PT": ("405303", 1.9425050569), "FP": ("283003", 1.9950999716),
                              "FF": ("729101", 0.9921550313), "FT": ("633302", 1.1497751207)},
}


def log(msg):
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def perf(out: dict):
    """Operability evaluations per second (batched), and unit-task evaluations per second of the
    whole chain (IK over every branch + collision + Jacobian + operability) in one process."""
    rng = np.random.default_rng(0)
    J = rng.normal(size=(200_000, 6, 6))
    t = time.perf_counter()
    mu = direction_ease(J)
    operability(mu, np.array([1, 1, 0, 0, 0, 0], bool), np.array([0, 0, 1, 1, 1, 0], bool), 0.5)
    dt = time.perf_counter() - t
    out["operability_per_s"] = J.shape[0] / dt
    task = load_task("task1_welding_plate")
    pr = DesignProblem(task, "BP")
    G = rng.integers(0, 16, (2000, 5)) * 0.1
    t = time.perf_counter()
    pr.fitness_E(G)
    dt = time.perf_counter() - t
    out["designs_per_s"] = G.shape[0] / dt
    out["unit_evaluations_per_s"] = G.shape[0] * len(task.units) / dt
    out["batch"] = (f"eq. 2-6: {J.shape[0]} random 6x6 Jacobians in one call; chain: {G.shape[0]} "
                    f"BP candidates x {len(task.units)} unit tasks of {task.name} in one fitness_E "
                    f"call (branch {pr.branch}), one process")
    out["loadavg_1min"] = os.getloadavg()[0]
    log(f"perf: {out['operability_per_s']:.3g} operability evaluations/s (from Jacobians), "
        f"{out['unit_evaluations_per_s']:.3g} unit-task evaluations/s with IK+collision")


TASK_VARIANTS = (("task1_welding_plate", False), ("task1_welding_plate", True),
                 ("task2_welding_opening", False), ("task2_welding_opening", True),
                 ("peg_in_hole", False))


def scaling(workers: int, gens: tuple, branch: str, restarts: int) -> dict:
    """The full 10-type design run of Task-1 (GA to convergence) on `workers` and on 1 worker,
    back to back (the machine is shared: the load is recorded before each run)."""
    task = load_task("task1_welding_plate")
    runs = []
    for w in dict.fromkeys((workers, 1)):
        load = os.getloadavg()[0]
        res, wall = run_all_types(task, workers=w, ga_generations=gens, branch=branch, restarts=restarts)
        runs.append({"workers": w, "wall_s": wall, "loadavg_1min_before": load,
                     "designs": sum(r.evaluations for r in res),
                     "best": max(res, key=lambda r: r.E_per_m).type_name})
        log(f"scaling: full 10-type run of {task.name} on {w} worker(s): {wall:.1f} s "
            f"(load {load:.1f} before)")
    return {"task": task.name, "ga_generations": gens, "branch": branch, "restarts": restarts,
            "cpu_count": os.cpu_count(), "runs": runs,
            "wall_s_by_workers": {str(r["workers"]): r["wall_s"] for r in runs}}


def first_generation_reaching(history, E, rel=1e-12):
    """Index of the first generation whose best E is within rel of E (None if never)."""
    for i, h in enumerate(history):
        if h >= E * (1 - rel):
            return i
    return None


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


def main(argv=None):
    global OUT
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=str(OUT), help="output folder (default out/kotosaka_1995)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--exhaustive", default=None, metavar="TYPE:TASK",
                    help="certificate: every distinct design of one type (e.g. BP:task1_welding_plate; "
                         "~4-10 min on a shared 2-core machine, so not part of the default run)")
    ap.add_argument("--ga-seeds", type=int, default=0,
                    help="with --exhaustive: also run the GA of that type with seeds 1..N and record "
                         "the generation each reaches the exhaustive optimum")
    ap.add_argument("--skip-search", action="store_true")
    ap.add_argument("--tasks", default=None,
                    help="only these task variants, comma-separated names as in results.json "
                         "(e.g. task1_welding_plate,task2_welding_opening-no-obstacles)")
    ap.add_argument("--skip-exhaustive", action="store_true")
    ap.add_argument("--skip-scaling", action="store_true",
                    help="skip the full Task-1 run on --workers and on 1 worker")
    ap.add_argument("--scaling-only", action="store_true", help="only that scaling measurement")
    ap.add_argument("--branch", default="task", choices=("task", "point"),
                    help="IK branch choice: one label for the whole task (the seed's) or per point")
    ap.add_argument("--restarts", type=int, default=1,
                    help="GA runs per type (seeds 0..N-1), the best kept (robustness of the ranking)")
    ap.add_argument("--compare-branch", action="store_true",
                    help="also run the other branch choice and write branches.md")
    ap.add_argument("--generations", default="400,100", help="GA max,stall generations")
    ap.add_argument("--codesign", action="store_true", help="only the co-design of the ch.4 arm")
    ap.add_argument("--layout-evaluations", type=int, default=60,
                    help="co-design: at most this many inner plans in the lengths + base search")
    ap.add_argument("--analyse", action="store_true", help="only the w/c breakdown of results.json")
    ap.add_argument("--letters", default=None, help="only: rerun both tasks under an alternative "
                                                     "letter assignment (T-column or B-normal)")
    a = ap.parse_args(argv)
    OUT = Path(a.out)
    OUT.mkdir(parents=True, exist_ok=True)
    if a.codesign:
        return codesign(a.layout_evaluations)
    if a.analyse:
        return analyse()
    if a.letters:
        return letters(a.letters, a.workers, tuple(int(x) for x in a.generations.split(",")))
    resfile = OUT / "results.json"
    results = json.loads(resfile.read_text()) if resfile.exists() else {}
    if a.scaling_only:
        a.skip_search, a.exhaustive = True, None
    if not a.skip_search:
        plot_types(OUT / "types.png")
        results["perf"] = {}
        perf(results["perf"])
        gens = tuple(int(x) for x in a.generations.split(","))
        other = {"task": "point", "point": "task"}[a.branch]
        md = ["# Seed 003 reproduced (qmt_drake.design)", "",
              f"The project GA per type (population 200, 30 mutants per generation, roulette + 1 "
              f"elite, single-point crossover, 4 bits/gene, max/stall generations {gens}), "
              f"{a.workers} worker processes; IK branch choice '{a.branch}' ("
              + ("one branch label for every unit task, the best over the whole task: the seed's"
                 if a.branch == "task" else "the best branch at each point") +
              "). E = mu_bar / sum(L) * P_k / k in 1/m.", ""]
        if a.tasks:   # a subset: keep the other variants' entries
            results.setdefault("search", {})
        else:
            results["search"] = {}
        results["branch"] = a.branch
        results["restarts"] = a.restarts
        cmp_rows = {}
        only = set(a.tasks.split(",")) if a.tasks else None
        for tname, noobs in TASK_VARIANTS:
            if only and (tname + ("-no-obstacles" if noobs else "")) not in only:
                continue
            task = load_task(tname)
            if noobs:
                task = task.without_obstacles()
            log(f"{task.name}: 10 types, branch {a.branch} ...")
            res, wall = run_all_types(task, workers=a.workers, ga_generations=gens, branch=a.branch,
                                      restarts=a.restarts)
            log(f"{task.name}: wall {wall:.1f} s, best {max(res, key=lambda r: r.E_per_m).type_name}")
            md.append(table(tname, res, SEED.get(tname) if not noobs else None,
                            f"{task.name} (wall {wall:.0f} s on {a.workers} workers)"))
            entry = {"wall_s": wall, "workers": a.workers, "branch": a.branch, "restarts": a.restarts,
                     "types": {}}
            for r in res:
                pr = DesignProblem(task, r.type_name, branch=a.branch)
                det = pr.details(r.genes)
                entry["types"][r.type_name] = {
                    "method": r.method, "extra": r.extra, "gene": r.gene_hex, "E_per_m": r.E_per_m,
                    "evaluations": r.evaluations, "wall_s": r.wall_s,
                    "history_best_E": r.history_best_E, "details": det}
                write_text_atomic(OUT / "urdf" / task.name / f"{r.type_name}.urdf",
                                  urdf_text(r.type_name, lengths6(r.genes)[0]))
            # the seed's own genes evaluated on our tasks (different length unit and tasks)
            entry["seed_genes_on_our_task"] = {}
            if not noobs and tname in SEED:
                for T, (g, _) in SEED[tname].items():
                    pr = DesignProblem(task, T, branch=a.branch)
                    entry["seed_genes_on_our_task"][T] = float(
                        pr.fitness_E(genes_from_levels(levels_from_gene(g))[None])[0])
            best = max(res, key=lambda r: r.E_per_m)
            pr = DesignProblem(task, best.type_name, branch=a.branch)
            conf = pr.confirm_report(best.genes)
            entry["winner_confirm"] = {k: conf[k] for k in ("ok", "E_drake_per_m", "E_numpy_per_m",
                                                             "pose_error", "min_env_distance_m")}
            log(f"{task.name}: winner {best.type_name} {best.gene_hex} E {best.E_per_m:.5f}, Drake "
                f"re-check ok={conf['ok']} E={conf['E_drake_per_m']:.5f}")
            if a.compare_branch:
                res_o, wall_o = run_all_types(task, workers=a.workers, ga_generations=gens, branch=other,
                                              restarts=a.restarts)
                log(f"{task.name}: branch {other}: wall {wall_o:.1f} s, best "
                    f"{max(res_o, key=lambda r: r.E_per_m).type_name}")
                entry["other_branch"] = {"branch": other, "wall_s": wall_o, "types": {
                    r.type_name: {"gene": r.gene_hex, "E_per_m": r.E_per_m,
                                  "generations": r.extra.get("generations")} for r in res_o}}
                cmp_rows[task.name] = (res, res_o)
            results["search"][task.name] = entry
            # Fig. 6: the winner, and the seed's winner type with our best lengths
            seed_winner = {"task1_welding_plate": "PB", "task2_welding_opening": "BF"}.get(tname, "BP")
            for T in dict.fromkeys([best.type_name, seed_winner, "BP"]):
                r = next(x for x in res if x.type_name == T)
                det = entry["types"][T]["details"]
                qs = [np.array(u["q_rad"]) if u["reachable"] else None for u in det["units"]]
                plot_arm_at_task(OUT / f"fig6_{task.name}_{T}.png", task, T, lengths6(r.genes)[0],
                                 qs, f"{task.name}: {T} {r.gene_hex} E = {r.E_per_m:.4f} 1/m "
                                     f"(lengths {np.round(lengths6(r.genes)[0], 2).tolist()} m)")
                if T == best.type_name:
                    meshcat_arm_at_task(OUT / f"fig6_{task.name}_{T}.html", task, T,
                                        lengths6(r.genes)[0], qs)
            plot_convergence(OUT / f"fig7_{task.name}.png",
                             {r.type_name: r.history_best_E for r in res},
                             xlabel="generation (population 200)",
                             title=f"{task.name}: best E per generation (GA, branch {a.branch})")
            write_text_atomic(resfile, json.dumps(jsonable(results), indent=1) + "\n")
        write_text_atomic(OUT / "tables.md", "\n".join(md) + "\n")
        analyse()
        if cmp_rows:
            write_text_atomic(OUT / "branches.md", branch_table(cmp_rows, a.branch, other))

    if a.scaling_only or (not a.skip_search and not a.skip_scaling):
        results["scaling"] = scaling(a.workers, tuple(int(x) for x in a.generations.split(",")),
                                     a.branch, a.restarts)
        write_text_atomic(resfile, json.dumps(jsonable(results), indent=1) + "\n")

    if a.exhaustive and not a.skip_exhaustive:
        T, tname = a.exhaustive.split(":")
        task = load_task(tname)
        pr = DesignProblem(task, T, branch=a.branch)
        log(f"exhaustive {T} on {tname} (branch {a.branch}) ...")
        ex = exhaustive(pr, batch=4000, progress=log)
        log(f"exhaustive {T}: best {ex.gene_hex} E {ex.E_per_m:.6f} in {ex.wall_s:.0f} s "
            f"({ex.unit_evaluations / ex.wall_s:.0f} unit evaluations/s)")
        conf = pr.confirm_report(ex.genes)
        exr = {"type": T, "task": tname, "branch": a.branch, "gene": ex.gene_hex, "E_per_m": ex.E_per_m,
               "designs": ex.evaluations, "unit_evaluations": ex.unit_evaluations, "wall_s": ex.wall_s,
               "top10": ex.extra["top10"], "confirm_ok": conf["ok"],
               "E_drake_per_m": conf["E_drake_per_m"]}
        sr = results.get("search", {}).get(tname, {}).get("types", {}).get(T)
        if sr and results.get("branch") == a.branch:
            exr["ga_gene"], exr["ga_E_per_m"] = sr["gene"], sr["E_per_m"]
            exr["ga_matches"] = abs(sr["E_per_m"] - ex.E_per_m) <= 1e-12 * ex.E_per_m
            exr["ga_generations"] = sr["extra"].get("generations")
            exr["ga_designs"] = sr["evaluations"]
            exr["ga_generation_of_best"] = first_generation_reaching(sr["history_best_E"], ex.E_per_m)
            log(f"certificate: GA {sr['gene']} E {sr['E_per_m']:.12f} vs exhaustive "
                f"{ex.E_per_m:.12f}: match {exr['ga_matches']}")
        if a.ga_seeds:
            from qmt_drake.design.search import search_type
            gens = tuple(int(x) for x in a.generations.split(","))
            exr["ga_seeds"] = []
            for sd in range(1, a.ga_seeds + 1):
                r = search_type(task, T, "ga", seed=sd, ga_generations=gens, branch=a.branch)
                row = {"seed": sd, "gene": r.gene_hex, "E_per_m": r.E_per_m, "designs": r.evaluations,
                       "generations": r.extra.get("generations"),
                       "generation_of_best": first_generation_reaching(r.history_best_E, ex.E_per_m),
                       "matches": abs(r.E_per_m - ex.E_per_m) <= 1e-12 * ex.E_per_m}
                exr["ga_seeds"].append(row)
                log(f"certificate GA seed {sd}: {row}")
        write_text_atomic(OUT / f"exhaustive_{T}_{tname}.json", json.dumps(jsonable(exr), indent=1) + "\n")
        # re-read: a search run in another process may have written results.json meanwhile
        results = json.loads(resfile.read_text()) if resfile.exists() else {}
        results.setdefault("exhaustive", {})[f"{T}:{tname}"] = exr
        write_text_atomic(resfile, json.dumps(jsonable(results), indent=1) + "\n")
    log("done")


def letters(name, workers, gens):
    """Sensitivity of the ranking to the reconstructed letter definitions."""
    from qmt_drake.design.arm_types import RELATIONS_ALTERNATIVES
    rel = RELATIONS_ALTERNATIVES[name]
    md = [f"# Letters '{name}': {rel} (ours: B second axis, F first axis, T common normal)", ""]
    out = {"relations": rel, "search": {}}
    for tname in ("task1_welding_plate", "task2_welding_opening"):
        for noobs in (False, True):
            task = load_task(tname)
            if noobs:
                task = task.without_obstacles()
            res, wall = run_all_types(task, method="auto", workers=workers, ga_generations=gens,
                                      relations=rel)
            log(f"letters {name} {task.name}: wall {wall:.0f} s, best "
                f"{max(res, key=lambda r: r.E_per_m).type_name}")
            md.append(table(tname, res, SEED[tname] if not noobs else None, f"{task.name}, letters {name}"))
            out["search"][task.name] = {r.type_name: {"gene": r.gene_hex, "E_per_m": r.E_per_m,
                                                      "method": r.method} for r in res}
            write_text_atomic(OUT / f"letters_{name}.json", json.dumps(jsonable(out), indent=1) + "\n")
            write_text_atomic(OUT / f"letters_{name}.md", "\n".join(md) + "\n")


def analyse():
    """Why the ranking is what it is: mean w (work mobility), c (constrained mobility), reach and
    sum of lengths of every type's best design, per task variant -> analysis.md."""
    results = json.loads((OUT / "results.json").read_text())
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
    write_text_atomic(OUT / "analysis.md", "\n".join(md) + "\n")
    log("analysis written")


def codesign(max_layout_evaluations: int = 60):
    """Item 7: lengths (grid) and then lengths + base position (compass search from the grid's
    best) of the ch.4 two-link arm minimising the family-optimum QMT time under thesis-ch4's moment
    and motor limits; the thesis arm and both winners re-planned and carried in the co-simulation."""
    import yaml

    from qmt_drake.config.scenario import load_scenario
    from qmt_drake.design.codesign import LAYOUT_LOWER_M, LAYOUT_UPPER_M, ROOT, grid_search, pattern_search
    from qmt_drake.planners import plan_with
    from qmt_drake.sim import simulate_transfer
    t_start = time.perf_counter()
    folder = OUT / "codesign"
    l1s = np.round(np.arange(0.12, 0.201, 0.02), 3)
    l2s = np.round(np.arange(0.08, 0.161, 0.02), 3)
    rows = grid_search(l1s, l2s, folder, progress=log)
    best = min(rows, key=lambda r: r["motion_time_s"])
    # refine around the best at 10 mm
    fine = grid_search(np.round(best["l1_m"] + np.array([-0.01, 0.0, 0.01]), 3),
                       np.round(best["l2_m"] + np.array([-0.01, 0.0, 0.01]), 3), folder / "fine", progress=log)
    allr = rows + [r for r in fine if not (r["l1_m"] == best["l1_m"] and r["l2_m"] == best["l2_m"])]
    best = min(allr, key=lambda r: r["motion_time_s"])
    t_lengths = time.perf_counter() - t_start
    thesis = next(r for r in rows if abs(r["l1_m"] - 0.16) < 1e-9 and abs(r["l2_m"] - 0.12) < 1e-9)
    # joint layout: the base position joins the lengths; start from the lengths-only optimum
    t0 = time.perf_counter()
    lay = pattern_search([best["l1_m"], best["l2_m"], 0.0, 0.0], folder / "layout", step_m=0.02,
                         min_step_m=0.005, max_evaluations=max_layout_evaluations, progress=log)
    t_layout = time.perf_counter() - t0
    layout = lay["best"]
    log(f"codesign layout: l1 {layout['l1_m']:.3f} l2 {layout['l2_m']:.3f} base {layout['base_m']} m: "
        f"T0 {layout['motion_time_s']:.4f} s after {lay['evaluations']} plans ({t_layout:.0f} s)")
    sims = {}
    for tag, r in (("thesis_arm", thesis), ("codesigned_lengths", best), ("codesigned_layout", layout)):
        sc = load_scenario(r["scenario"])
        plan = plan_with("optimum", sc)     # re-planned from the written scenario: the re-check
        res = simulate_transfer(sc, plan, keep_series=False)
        sims[tag] = {"l1_m": r["l1_m"], "l2_m": r["l2_m"], "base_m": r.get("base_m", [0.0, 0.0]),
                     "motion_time_s": float(plan.motion_time_s),
                     "search_motion_time_s": float(r["motion_time_s"]),
                     "held": bool(res.held), "max_slip_m": float(res.max_slip_m),
                     "peak_motor_torque_ratio": float(res.peak_motor_torque_ratio),
                     "peak_moment_ratio_planned": float(res.peak_moment_ratio_planned)}
        log(f"codesign {tag}: T0 {plan.motion_time_s:.4f} s, co-simulation held={res.held}, "
            f"slip {res.max_slip_m * 1e3:.3f} mm, torque ratio {res.peak_motor_torque_ratio:.3f}, "
            f"planned moment ratio {res.peak_moment_ratio_planned:.4f}")
    out = {"grid": allr, "best": best, "thesis": thesis, "cosim": sims,
           "time_saved_s": thesis["motion_time_s"] - best["motion_time_s"],
           "layout": {"best": layout, "evaluations": lay["evaluations"], "steps": lay["steps"],
                      "rows": lay["rows"], "bounds_m": [LAYOUT_LOWER_M.tolist(), LAYOUT_UPPER_M.tolist()],
                      "wall_s": t_layout},
           "layout_time_saved_s": thesis["motion_time_s"] - layout["motion_time_s"],
           "wall_s": {"lengths_grid": t_lengths, "layout_search": t_layout,
                      "total": time.perf_counter() - t_start}}
    write_text_atomic(OUT / "codesign.json", json.dumps(jsonable(out), indent=1) + "\n")
    import matplotlib.pyplot as plt
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4.5))
    Z = np.array([[next(r["motion_time_s"] for r in rows if r["l1_m"] == l1 and r["l2_m"] == l2)
                   for l1 in l1s] for l2 in l2s])
    im = ax.pcolormesh(l1s, l2s, np.where(np.isfinite(Z), Z, np.nan), shading="nearest", cmap="viridis")
    fig.colorbar(im, ax=ax, label="family-optimum motion time T0 [s]")
    ax.plot(0.16, 0.12, "rs", label="thesis arm (Table 4.1)")
    ax.plot(best["l1_m"], best["l2_m"], "w*", ms=12, label="co-designed lengths")
    ax.set_xlabel("l1 [m]")
    ax.set_ylabel("l2 [m]")
    ax.legend(fontsize=8)
    ax.set_title("lengths, base at the thesis's (white: unreachable)", fontsize=9)
    # layout: the task points in the world, each arm's base and reach
    pts = np.array(yaml.safe_load((ROOT / "models" / "scenarios" / "thesis-ch4.yaml").read_text())
                   ["task"]["points_m"])
    ax2.plot(pts[:, 0], pts[:, 1], "ko", label="task points (start, vias, goal)")
    th = np.linspace(0, 2 * np.pi, 200)
    for tag, col, mk, ms in (("thesis_arm", "r", "s", 13), ("codesigned_lengths", "b", "o", 7),
                             ("codesigned_layout", "g", "D", 7)):
        sm = sims[tag]
        b = np.array(sm["base_m"])
        R = sm["l1_m"] + sm["l2_m"]
        ax2.plot(b[0] + R * np.cos(th), b[1] + R * np.sin(th), col + ":", lw=0.8)
        ax2.plot(*b, col + mk, ms=ms, mfc="none" if tag == "thesis_arm" else col,
                 label=f"{tag}: base ({b[0]:+.3f}, {b[1]:+.3f}), l1 {sm['l1_m']:.3f}, "
                       f"l2 {sm['l2_m']:.3f} m, T0 {sm['motion_time_s']:.3f} s")
    ax2.set_aspect("equal")
    ax2.set_xlim(-0.35, 0.35)
    ax2.set_ylim(-0.2, 0.35)
    ax2.set_xlabel("x [m]")
    ax2.set_ylabel("y [m]")
    ax2.legend(fontsize=7, loc="lower center")
    ax2.set_title("joint layout: base (marker) and reach l1 + l2 (dotted)", fontsize=9)
    fig.tight_layout()
    fig.savefig(OUT / "codesign.png", dpi=110)
    plt.close(fig)
    log(f"codesign done in {time.perf_counter() - t_start:.0f} s")


if __name__ == "__main__":
    main()
