"""The markdown table of studies/verdict_margins.py (its rows, as stored in verdict_margins.json)."""

from __future__ import annotations

SHORT = {"max_slip_m": "slip", "final_slide_m": "slide", "max_grip_ratio_while_held": "hand ratio",
         "max_gap_m": "gap", "max_slide_m": "slide", "final_slide_on_face_m": "final slide",
         "final_goal_error_rad": "goal error"}
CONTACT_HOLD = ("max_gap_m", "max_slide_m", "final_slide_on_face_m")
CONTACT_NOTE = ("Contact-hand cells: detached, when and the largest tilt while held; else the outcome, the hold's "
                "quantity nearest its threshold in mm and as its ratio (gap 5 mm or slide 10 mm: detached; final "
                "slide 5 mm: slipped), the largest tilt, and the arrival's ratio (final goal error against 1 mrad: "
                "unfinished at or above 1; 'after 2.0 s': measured that long past the 0.5 s hold at the goal, once "
                "the arm was steady, sim/spatial_contact_hand).")


def fmt(c: dict) -> str:
    """One cell: outcome and deciding quantity (module docstring of studies/verdict_margins.py)."""
    if c["held"] is None:
        return "n/a (TAMSI: no weld constraint)" if c.get("approximation") == "tamsi" else f"n/a ({c.get('error')})"
    if c.get("ratio") is None:
        return f"{c['outcome']} ({c.get('error', 'nothing measured')})"
    q = c["quantity"]
    if "max_tilt_while_held_rad" in c:  # the contact hand: its hold's nearest quantity, the tilt, the arrival
        tilt = f"tilt {c['max_tilt_while_held_rad'] * 1e3:.3g} mrad"
        if c.get("lost_at_s") is not None:  # after the loss the part falls: its gap says nothing more
            return f"{c['outcome']} at {c['lost_at_s']:.3f} s ({tilt} while held)"
        ratios = c["criteria"]
        hold = max((k for k in CONTACT_HOLD if ratios.get(k) is not None), key=lambda k: ratios[k])
        wait = f" after {c['arrival_wait_s']:.1f} s" if c.get("arrival_wait_s") else ""  # its wait past the tail
        return (f"{c['outcome']}, {SHORT[hold]} {c[hold] * 1e3:.3g} mm ({ratios[hold]:.2f}), {tilt}, "
                f"arrival {ratios['final_goal_error_rad']:.2f}{wait}")
    if q in ("max_slip_m", "final_slide_m"):
        return f"{c['outcome']}, {SHORT[q]} {c['value'] * 1e3:.3f} mm"
    return f"{c['outcome']}, {SHORT.get(q, q)} {c['value']:.5f}"


def grids(row: dict) -> list[tuple[str, float, dict]]:
    """(label, time scale, cells) of every grid of a row."""
    label = f"{row['scenario']} {row['method']}" + (", contact hand" if row.get("hand") == "contact" else "")
    out = []
    if row.get("hand") == "contact":
        out.append((label + " (the weld's fastest carried)", row["weld_time_scale"], row["cells_at_weld"]))
        if row.get("chosen_time_scale") is not None and row["chosen_time_scale"] != row["weld_time_scale"]:
            out.append((label + " (its own fastest carried)", row["chosen_time_scale"], row["cells"]))
    else:
        out.append((label, row["chosen_time_scale"], row["cells"]))
    every = row.get("carried_at_every_cell") or {}
    if every.get("cells"):
        out.append((label + " (carried at every cell)", every["time_scale"], every["cells"]))
    return out


def flip_line(row: dict) -> str | None:
    m = row.get("margin") or {}
    f = m.get("flip") or {}
    name = f"- {row['scenario']} {row['method']}"
    if row.get("hand") == "contact":
        s = row.get("chosen_time_scale")
        if s is None:
            return f"{name}, contact hand: not carried at {m.get('cell', '1 ms lagged')} up to its search's end"
        lost = f"lost at x{f['lost_at']:.5f}" if f.get("lost_at") else "the plan itself (x1)"
        return (f"{name}, contact hand: fastest carried at its default cell ({m['cell']}) x{s:.5f}, {lost}; the "
                f"weld's x{row['weld_time_scale']:.5f} is there "
                f"{row['cells_at_weld'][m['cell']]['outcome']}")
    if not f.get("flip_time_scale"):
        return None
    return (f"{name} at x{row['chosen_time_scale']:.5f}: deciding {m['quantity']} {m['ratio']:.4f} of its threshold; "
            f"the verdict flips at x{f['flip_time_scale']:.5f} ({f['relative_to_run']:+.2%}; carried at "
            f"x{f['carried_at']:.5f}, lost at x{f['lost_at']:.5f}, {f['runs']} runs); at half the step "
            f"{m['half_step']['outcome_at_half_step']}")


def markdown(res: dict, steps_s, approximations) -> str:
    lines = ["Cells: outcome, then the deciding quantity (slip against 1 mm, or the weld hand's ratio against 1). "
             + CONTACT_NOTE, "",
             "| plan | time scale | step | " + " | ".join(approximations) + " |",
             "|---|---|---|" + "---|" * len(approximations)]
    flips = []
    for row in res.values():
        line = flip_line(row)
        if line:
            flips.append(line)
        for label, s, cells in grids(row):
            for h in steps_s:
                cs = [cells[f"{h * 1e3:g} ms {a}"] for a in approximations]
                lines.append(f"| {label} | x{s:.4f} ({row['planned_s'] * s:.4f} s) | {h * 1e3:g} ms | "
                             + " | ".join(fmt(c) for c in cs) + " |")
    return "\n".join(lines + [""] + flips) + "\n"
