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

The searches are here; the tables (and analysis.md) are in studies/kotosaka_1995_tables.py, the
co-design of the ch.4 arm (--codesign) in studies/kotosaka_1995_codesign.py.

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

from qmt_drake.design.arm_types import levels_from_gene, urdf_text
from qmt_drake.design.operability import direction_ease, operability
from qmt_drake.design.plots import meshcat_arm_at_task, plot_arm_at_task, plot_convergence, plot_types
from qmt_drake.design.problem import DesignProblem, genes_from_levels, lengths6
from qmt_drake.design.search import exhaustive, run_all_types
from qmt_drake.design.tasks import load_task
from qmt_drake.outputs import jsonable, write_text_atomic
from studies.kotosaka_1995_codesign import codesign
from studies.kotosaka_1995_tables import analyse, branch_table, table

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
        return codesign(OUT, log, a.layout_evaluations)
    if a.analyse:
        return analyse(OUT, log)
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
        analyse(OUT, log)
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


if __name__ == "__main__":
    main()
