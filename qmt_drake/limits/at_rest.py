"""Which limit makes a path impossible: the ratios at rest (gravity alone) along it.

When TOPP-RA finds no parameterisation, a limit is broken where the arm cannot even stand still
(the quasi-static load: gravity torque against a joint's limit, the hand's static ratio); moving
cannot help there. `worst_at_rest` finds the largest ratio column over the path's samples computed
at zero speed and acceleration, `describe_at_rest` says it in one line: the limit, the joint or
hand row, the path point and the ratio (in N m too for a joint torque).
"""

from __future__ import annotations

import numpy as np


def worst_at_rest(cols, labels, ratio_mask=None, limits_Nm=None) -> dict:
    """{'column', 'sample', 'ratio', 'value_Nm', 'limit_Nm'} of the largest column of cols (S, M),
    computed at rest; ratio_mask (M,) the ratio columns (others ignored); limits_Nm (M,) the torque
    limit behind a torque column (nan elsewhere)."""
    c = np.asarray(cols, float)
    if ratio_mask is not None:
        c = np.where(np.asarray(ratio_mask)[None, :], c, -np.inf)
    k, j = np.unravel_index(int(np.argmax(c)), c.shape)
    lim = float(limits_Nm[j]) if limits_Nm is not None else float("nan")
    return {"column": str(labels[j]), "sample": int(k), "ratio": float(c[k, j]),
            "value_Nm": float(c[k, j]) * lim, "limit_Nm": lim}


def describe_at_rest(worst: dict, where: str) -> str:
    """One clause: '<column> needs <ratio> of its limit at rest (54 N m of 50 N m) at <where>'."""
    torque = "" if not np.isfinite(worst["limit_Nm"]) else f" ({worst['value_Nm']:.3g} N m of {worst['limit_Nm']:.3g} N m)"
    verdict = "needs" if worst["ratio"] > 1.0 else "is at"
    return f"{worst['column']} {verdict} {worst['ratio']:.4g} of its limit at rest{torque} at {where}"


def worst_terms_at_rest(chain, terms, q) -> tuple[dict, dict]:
    """(worst_at_rest of the limit terms' columns, the chain's state) at joint positions q (S, n) held
    still: `chain.evaluate` (gravity and the carried part) fed to every term (the motor torque, the
    hand's grip), a joint torque column with its limit in N m. Used by the spatial TOPP-RA's and
    Ruckig's refusals."""
    q = np.atleast_2d(np.asarray(q, float))
    zero = np.zeros_like(q)
    state = chain.evaluate(q, zero, zero)
    cols = np.concatenate([t.columns(state) for t in terms], axis=1)
    labels = [c for t in terms for c in t.column_names]
    lim = np.concatenate([np.asarray(getattr(t, "joint_limit_Nm", np.full(len(t.column_names), np.nan)), float)
                          for t in terms])
    return worst_at_rest(cols, labels, limits_Nm=lim), state
