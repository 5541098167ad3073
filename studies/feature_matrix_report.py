"""The verdicts of the refusals (JUDGEMENTS: physics, missing feature, no data) and docs/features.md."""

from __future__ import annotations

import re

from studies.feature_matrix_cells import BASE_METHOD, ENERGY_SMALL, FEATURES, KINDS

# (feature regex, kind regex, message regex) -> (verdict, why). Verdicts: "physics" (the combination is
# meaningless for this arm) or "missing feature" (it could exist; the code does not offer it).
MISSING, PHYSICS, NO_DATA = "missing feature", "physics", "no data"
JUDGEMENTS: list = [
    (r"--method collocation", r"^(?!energy)", r"collocation needs the time at which the family passes",
     MISSING, "energy/collocation_kinds pins each task pose at a knot; a family that does not say when it passes its "
     "task's via points (neither two points nor a via cubic) gives it no time to seed them with"),
    (r"--method (ga|optimum|toppra|toppra-drake|ruckig|trajopt|family_optimum)$|GA --checkpoint|^retime$", "energy",
     r"needs the joints' torque limits",
     PHYSICS, "an energy-time scenario without limits.joint_torque_Nm (ohsaka-fig2: the paper states none) has ideal "
     "torque sources and no other limit: the arm could move arbitrarily fast, so a minimum time has no meaning "
     "(the message asks for the limits)"),
    (r"--method family_optimum", "planar|tray", r"plans spatial scenarios",
     MISSING, "a name only: the transfer planners call the same thing `optimum` (the spatial ones take both)"),
    (r"--method toppra-drake", "UR5|Panda", r"does not plan spatial",
     MISSING, "Drake's TOPP-RA on a spatial path is meaningful; only the planar variant is wired to it"),
    (r"--method thesis", ".", r"plans transfer scenarios|does not plan spatial|plans planar \(kind: transfer\) scenarios, not",
     NO_DATA, "`thesis` replays a published plan's genes; this scenario has no published transfer plan (neither "
     "physics nor a missing feature)"),
    (r"--method trajopt", "tray", r"not available for the tray",
     MISSING, "the tray's level and friction-cone terms are missing from the trajopt constraints (TOPP-RA, Ruckig "
     "and the GA have them); a tray constraint set for trajopt is code, not physics"),
    (r"GA --checkpoint", "UR5|Panda", r"keeps no checkpoint",
     MISSING, "the spatial GA runs the same planners/ga.run_ga, which writes checkpoints; only the plumbing is missing"),
    (r"--margin", "energy", r"takes no time scale",
     MISSING, "the execution's own verdict (goal reached within tolerance) could flip with a time scale or a plant "
     "step as the carried verdict does; the energy-time execution takes neither"),
    (r"--carried|--success|sweep", "energy", r"energy-time|no uncertainty|carried|payload",
     PHYSICS, "seed 001's vertical arm carries no payload: there is nothing to hold, slip or lose, so 'carried' and "
     "its probability have no meaning (the arm's own tracking could be swept: that would be a new verdict). Issue 27 "
     "asks the refusal to say so; a message naming option families or kinds does not"),
    (r"--success", ".", r"not reached even",
     PHYSICS, "an answer, not a refusal of the feature: under the scenario's uncertainty the plan is not carried often "
     "enough even this much slower (the cell's cheap bound, --success-max-scale 1.5 and 4 cases)"),
    (r"overrides \(API\)", ".", r"overrides apply to transfer",
     MISSING, "the same change in a copy of the YAML file is accepted (row 'scenario YAML copy'): only the dict form "
     "of load_scenario is missing"),
    (r"build_diagram", ".", r"composes transfer scenarios",
     MISSING, "simulate builds a Drake diagram for this kind too; it is not handed to the user to compose"),
    (r"--time-step-ms", "UR5|Panda", r"steps at 1 ms",
     MISSING, "the plant step of a spatial co-simulation is a number like the planar one's; fixed at 1 ms by the code"),
    (r"--time-step-ms|--explicit|--feedforward|--actuator", "energy", r"energy-time execution runs the plan",
     MISSING, "the vertical arm is run under ideal inverse dynamics; a step, a motor drive and its feedforward are "
     "meaningful for it, the code has none"),
    (r"--explicit|--feedforward", "tray", r"servos' own firmware loop",
     PHYSICS, "the Dynamixel servos close their position loop in firmware: there is no motor-voltage loop to step "
     "explicitly and no voltage feedforward to add (the message says so)"),
    (r"--explicit", "UR5|Panda", r"steps at 1 ms|implicitly|no separate motor loop",
     MISSING, "a numerical choice, not physics: the spatial dc_motor drive folds its back-EMF and PD damping into the "
     "plant as joint damping, integrated implicitly (stable at every step); stepping them explicitly, as the planar "
     "--explicit does, is not offered (the message argues physics; it is a missing option)"),
    (r"^retime$", "UR5|Panda", r"collides between waypoints",
     PHYSICS, "the cell's own path (straight lines between a few samples of the base plan) cuts through the cell's "
     "bins; retime times a path, it cannot change it, so refusing a colliding path is the answer"),
    (r"--feedforward back-emf", "UR5|Panda", r"applies to actuator dc_motor",
     PHYSICS, "the default ideal actuator is a torque source: it has no back-EMF to feed forward (with --actuator "
     "dc_motor the option applies; the message says so)"),
    (r"--actuator dc_motor", "planar|tray", r"actuator is its YAML actuator section",
     MISSING, "an interface gap, not physics: the planar arm's YAML actuator already is a DC motor with a gear (the "
     "tray's, Dynamixel servos), and the flag cannot name it"),
    (r"--actuator dc_motor", "tray", r"Dynamixel position servos .*firmware closes the position loop",
     PHYSICS, "the tray arm's YAML actuator is Dynamixel position servos: their firmware closes the loop, there is no "
     "motor voltage to drive (the planar magnet arm's dc_motor_gear YAML actuator is accepted; the message says so)"),
    (r"--explicit|--feedforward|--actuator", "energy", r"ideal torque sources",
     PHYSICS, "seed 001's arm is driven by ideal torque sources (the paper models no motor): no motor loop to step, no "
     "back-EMF to feed forward, no DC motor data to drive it with (the message says so)"),
    (r"^(retime|export)$", "planar|tray|energy", r"takes a spatial scenario|spatial",
     MISSING, "a planar joint path has a fastest timing and a controller stream as a spatial one does; the commands "
     "take spatial scenarios only"),
]


def judge(row: dict) -> tuple[str, str]:
    for fpat, kpat, mpat, verdict, why in JUDGEMENTS:
        if re.search(fpat, row["feature"]) and re.search(kpat, row["kind"]) and re.search(mpat, row["message"]):
            return verdict, why
    return "not judged", "no judgement matches this message (new or changed): read it"


def short(command: str) -> str:
    """The command without the words every cell shares (--quiet, the JSON output, the small energy-time
    problem, the spatial GA's population): what the row's feature adds."""
    for words in ("--quiet", " ".join(ENERGY_SMALL), "--option population=6"):
        command = command.replace(" " + words, "")
    return re.sub(r" --json \S+", "", command)


def _cmd_cell(row: dict | None) -> str:
    if row is None:
        return "(not run)"
    cmd = short(row["command"]).replace("|", "\\|")
    return f"**{row['status']}** `{cmd}`"


def markdown(cells: dict, meta: dict) -> str:
    kinds = list(KINDS)
    counts = {s: sum(1 for r in cells.values() if r["status"] == s) for s in ("ok", "refused", "error")}
    total_s = sum(r["seconds"] for r in cells.values())
    commits = sorted({r.get("commit", meta.get("commit", "?")) for r in cells.values()})
    timeouts = sorted({r.get("timeout_s", meta.get("timeout_s", "?")) for r in cells.values()}, key=str)
    lines = [
        "# Features x kinds", "",
        "Written by `python -m studies.feature_matrix` (issue 27 item 6) from out/feature_matrix.json; do not edit by "
        "hand. Each cell is the command that was run (in a temporary folder; `qmt-drake` is `python -m "
        "qmt_drake.apps.cli`, `base.json` the kind's base plan: " + ", ".join(
            f"{k}: `{BASE_METHOD[f]}`" for k, f in {"transfer": "transfer", "spatial": "spatial",
                                                     "energy": "energy"}.items()) + ") and its status: "
        "**ok** (exit 0, or exit 3 with the plan written), **refused** (exit 2, one line), **error** (traceback, "
        "timeout, other exit).", "",
        f"Commit{'s' if len(commits) > 1 else ''} {', '.join(commits)} (last run {meta.get('date', '?')}): "
        f"{len(cells)} cells, {counts['ok']} ok, {counts['refused']} refused, {counts['error']} error; "
        f"{total_s / 60:.1f} min of wall time in the cells, base plans not counted (per-step timeout "
        f"{', '.join(f'{t:g}' if isinstance(t, float) else str(t) for t in timeouts)} s).", "",
        "Kinds: " + ", ".join(f"{k} = `{v[0]}`" for k, v in KINDS.items()) + ".", "",
        "Run again: `python -m studies.feature_matrix --fresh` (every cell; the first full run took 47 min of wall "
        "time, 15.5 min of CPU, on 2 cores shared with 7 other jobs); without --fresh a cell already in the JSON with "
        "the same command is skipped; `--only TEXT --kinds NAME` selects cells. An exit 0 whose output lacks the "
        "feature's trace (--carried: carried_search, --success: its fresh check, --margin: the flip, the GA resume: "
        "'resuming' on stderr) counts as an error: the option was ignored.", "",
        "| feature | " + " | ".join(kinds) + " |", "|---|" + "---|" * len(kinds)]
    for f in FEATURES:
        lines.append(f"| {f} | " + " | ".join(_cmd_cell(cells.get(f"{f}|{k}")) for k in kinds) + " |")
    refused = [(r, *judge(r)) for r in cells.values() if r["status"] == "refused"]
    verdicts = {v: sum(1 for _, w, _ in refused if w == v) for v in (PHYSICS, MISSING, NO_DATA, "not judged")}
    lines += ["", "## Refusals", "",
              f"{len(refused)} refusals: " + ", ".join(f"{n} {v}" for v, n in verdicts.items()) + ". Verdicts (judged "
              "in studies/feature_matrix.py JUDGEMENTS, by the message): **physics**, the combination is meaningless "
              "for this arm; **missing feature**, it would mean something and the code does not offer it; **no "
              "data**, the scenario lacks what the feature replays. A refusal whose message changed is 'not judged'.",
              "", "| feature | kind | message | verdict | why |", "|---|---|---|---|---|"]
    for r, verdict, why in refused:
        msg = r["message"].replace("|", "\\|")
        lines.append(f"| {r['feature']} | {r['kind']} | {msg} | {verdict} | {why} |")
    errors = [r for r in cells.values() if r["status"] == "error"]
    lines += ["", "## Errors (defects)", "", "| feature | kind | command | first line |", "|---|---|---|---|"]
    for r in errors:
        lines.append(f"| {r['feature']} | {r['kind']} | `{r['command'].replace('|', '/')}` | "
                     f"{r['message'].replace('|', '/')} |")
    return "\n".join(lines) + "\n"
