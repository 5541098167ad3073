"""Seed 001's gap: which reading of the paper reproduces its Fig. 3 costs and their order?

The paper (Ohsaka & Kurahashi 1988) prints, for the coordinate vector (0.7, 0, 0, 0.2), c1 = 1,
c2 = 1e5: z = 22766 for the rotation pattern (+,-,-), 20266 for (+,+,+) and 18815 for (-,+,-)
(its global optimum), and, for Fig. 4 (0.68, 0.075, 0.100, 0.600) at c2 = 1e5, T = 0.188 s.
Each hypothesis below changes ONE thing against the shipped model (qmt_drake/energy: tau'tau with
gravity, X2 up, trapezoid rule on 40 divisions, m = 5 Fourier terms of the joint velocity, free end
posture, SNOPT) and re-solves:

- Fig. 3: for each of the paper's three patterns, the best trajectory whose joint travels have
  that sign pattern (SNOPT from the pattern's start, travel bounded to the pattern's closed
  orthant: the optimum may sit on its boundary, a joint not turning, marked "*");
- Fig. 4: T of the best of the 8 free starts at c2 = 1e5;
- whether the order (+,-,-) > (+,+,+) > (-,+,-) of the paper holds.

Run: PYTHONPATH=. python -m studies.ohsaka_gap [--only NAME,NAME] [--no-fig4]
Prints the table (and writes nothing): about 4 min of CPU, half of it the two power rows.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from qmt_drake.energy.dynamics import OHSAKA_URDF, inverse_dynamics_with_gravity, make_plant, ohsaka_arm
from qmt_drake.energy.experiments import paper_initial_x
from qmt_drake.energy.fourier import basis
from qmt_drake.energy.kinematics import lowest_cog_posture, posture_on_manifold
from qmt_drake.energy.multistart import (
    PATTERNS,
    initial_end_posture,
    initial_reduced_genes,
    pattern_str,
    signed_travel,
    travel_pattern,
)
from qmt_drake.energy.nlp import solve_nlp
from qmt_drake.energy.scenario import get_experiment
from qmt_drake.energy.steepest import restore_endpoint, steepest_descent

PAPER_Z = {(1, -1, -1): 22766.0, (1, 1, 1): 20266.0, (-1, 1, -1): 18815.0}
PAPER_ORDER = ((1, -1, -1), (1, 1, 1), (-1, 1, -1))   # most expensive first
PAPER_FIG4_T_S = {1.0: 1.900, 1e4: 0.330, 1e5: 0.188, 1e6: 0.100}
POWER_EPS_W = 1e-2    # smoothing of |p| = sqrt(p^2 + eps^2) so SNOPT gets a gradient


class VariantObjective:
    """z = T sum_k w_k (c1 h(tau_k, qd_k) + c2) with a chosen energy density h and quadrature
    weights w (sum w = 1 in normalised time), exact gradient; the shipped objective's interface
    (value, value_and_gradient, reduced_value_and_gradient, energy_integral).

    energy: "tau2" (shipped: tau'tau, tau with gravity), "tau2_dyn" (tau'tau of the torque
    without its gravity part), "tau2_no_qd" (tau = M qdd + g, no Coriolis/centrifugal terms), "power_abs" (|tau . qd|, smoothed), "power_pos" (positive
    mechanical work only, smoothed max(p, 0)).
    quad: "trapezoid" (shipped), "rect" (left rectangles, N values), "nodes" (N + 1 node values
    each weighted 1/N), "simpson", "sum_no_dt" (sum of the N + 1 node values, no dt: z =
    c1 sum_k h_k + c2 T).
    """

    def __init__(self, family, arm, c1, c2, divisions=40, energy="tau2", quad="trapezoid"):
        self.family, self.arm, self.c1, self.c2 = family, arm, c1, c2
        self.energy, self.quad = energy, quad
        N = int(divisions)
        s = np.linspace(0.0, 1.0, N + 1)
        if quad == "trapezoid":
            w = np.full(N + 1, 1.0 / N)
            w[[0, -1]] *= 0.5
        elif quad == "rect":
            w = np.full(N + 1, 1.0 / N)
            w[-1] = 0.0
        elif quad in ("nodes", "sum_no_dt"):
            w = np.full(N + 1, 1.0 / N)
        elif quad == "simpson":
            w = np.ones(N + 1)
            w[1:-1:2], w[2:-1:2] = 4.0, 2.0
            w /= 3.0 * N
        else:
            raise ValueError(quad)
        self.w = w
        self.B = basis(s, family.m)
        self.arm_dyn = arm.with_gravity_sign(0.0)   # the same chain with zero gravity

    def _h(self, q, qd, qdd, derivatives):
        """h (S,), dh/dq, dh/dqd, dh/dqdd (S, n) each."""
        arm = self.arm_dyn if self.energy == "tau2_dyn" else self.arm
        if self.energy == "tau2_no_qd":   # M(q) qdd + g(q): Coriolis and centrifugal terms left out
            tau, Jq, _, Jqdd = inverse_dynamics_with_gravity(q, np.zeros_like(qd), qdd, arm)
            Jqd = np.zeros_like(Jq)
        else:
            tau, Jq, Jqd, Jqdd = inverse_dynamics_with_gravity(q, qd, qdd, arm)
        if self.energy in ("tau2", "tau2_dyn", "tau2_no_qd"):
            h = np.sum(tau * tau, axis=1)
            dtau = 2.0 * tau
            dqd_direct = 0.0
        else:
            p = np.sum(tau * qd, axis=1)
            r = np.sqrt(p * p + POWER_EPS_W ** 2)
            if self.energy == "power_abs":
                h, dp = r, p / r
            elif self.energy == "power_pos":
                h, dp = 0.5 * (p + r), 0.5 * (1.0 + p / r)
            else:
                raise ValueError(self.energy)
            dtau = dp[:, None] * qd
            dqd_direct = dp[:, None] * tau
        gq = np.einsum("si,sij->sj", dtau, Jq)
        gqd = np.einsum("si,sij->sj", dtau, Jqd) + dqd_direct
        gqdd = np.einsum("si,sij->sj", dtau, Jqdd)
        return h, gq, gqd, gqdd

    def _scale(self, T):
        return 1.0 if self.quad == "sum_no_dt" else T

    def value_and_gradient(self, x):
        F, B = self.family, self.B
        a, b, T = F.unpack(x)
        q, qd, qdd = F.evaluate_s(x, None, B)
        h, gq, gqd, gqdd = self._h(q, qd, qdd, True)
        if self.quad == "sum_no_dt":
            wsum = self.w * (len(self.w) - 1)          # each node weight 1
            z = float(self.c1 * wsum @ h + self.c2 * T)
            r = self.c1 * wsum[:, None]
            dT0 = self.c2
        else:
            z = float(T * (self.w @ (self.c1 * h + self.c2)))
            r = self.c1 * T * self.w[:, None]
            dT0 = float(self.w @ (self.c1 * h + self.c2))
        gq, gqd, gqdd = r * gq, r * gqd, r * gqdd
        da = T * (gq.T @ B.Pa) + gqd.T @ B.Va + (gqdd.T @ B.Aa) / T
        db = T * (gq.T @ B.Pb) + gqd.T @ B.Vb + (gqdd.T @ B.Ab) / T
        dT = dT0 + np.sum(gq * (q - F.theta0)) / T - np.sum(gqdd * qdd) / T
        return z, F.pack(da, db, dT)

    def value(self, x):
        return self.value_and_gradient(x)[0]

    def reduced_value_and_gradient(self, y):
        x, J = self.family.reduced_to_full(y)
        z, g = self.value_and_gradient(x)
        return z, g @ J

    def energy_integral(self, x):
        return self.value(x) - self.c2 * self.family.unpack(x)[2]


def paper_printed_M_g(q, m=(2.0, 1.0, 0.5, 5.0), L=(0.3, 0.25, 0.15), g=9.81):
    """The paper's printed M(theta) and g(theta) (section 3; its one missing bracket read as
    cos(theta2 + theta3))."""
    m1, m2, m3, m4 = m
    l1, l2, l3 = L
    c2, c3, c23 = np.cos(q[1]), np.cos(q[2]), np.cos(q[1] + q[2])
    A3, B3 = m3 / 3 + m4, m3 / 2 + m4
    m33 = A3 * l3 ** 2
    m23 = m33 + B3 * l2 * l3 * c3
    m22 = (m2 / 3 + m3 + m4) * l2 ** 2 + m33 + (m3 + 2 * m4) * l2 * l3 * c3
    m13 = m33 + B3 * l2 * l3 * c3 + B3 * l1 * l3 * c23
    m12 = m22 + (m2 / 2 + m3 + m4) * l1 * l2 * c2 + B3 * l1 * l3 * c23
    m11 = ((m1 / 3 + m2 + m3 + m4) * l1 ** 2 + (m2 / 3 + m3 + m4) * l2 ** 2 + m33
           + (m2 + 2 * m3 + 2 * m4) * l1 * l2 * c2 + (m3 + 2 * m4) * l2 * l3 * c3 + (m3 + 2 * m4) * l1 * l3 * c23)
    M = np.array([[m11, m12, m13], [m12, m22, m23], [m13, m23, m33]])
    a1, a12, a123 = np.cos(q[0]), np.cos(q[0] + q[1]), np.cos(q[0] + q[1] + q[2])
    g3 = g * B3 * l3 * a123
    g2 = g * (m2 / 2 + m3 + m4) * l2 * a12 + g3
    g1 = g * (m1 / 2 + m2 + m3 + m4) * l1 * a1 + g2
    return M, np.array([g1, g2, g3])


def model_vs_printed(samples=200, seed=1):
    """Max relative deviation of the shipped model's M(q) (Drake's CalcMassMatrix of the URDF) and
    g(q) (its static torque, eq. 1 with qd = qdd = 0) from the paper's printed formulas."""
    plant = make_plant(str(OHSAKA_URDF))
    ctx = plant.CreateDefaultContext()
    rng = np.random.default_rng(seed)
    dM = dg = 0.0
    for q in rng.uniform(-np.pi, np.pi, (samples, 3)):
        plant.SetPositions(ctx, q)
        Mp, gp = paper_printed_M_g(q, g=ohsaka_arm().gravity_m_s2)
        dM = max(dM, np.abs(plant.CalcMassMatrix(ctx) - Mp).max() / np.abs(Mp).max())
        gm = inverse_dynamics_with_gravity(q[None], np.zeros((1, 3)), np.zeros((1, 3)), derivatives=False)[0]
        dg = max(dg, np.abs(gm - gp).max() / np.abs(gp).max())
    return dM, dg


def _problem(exp_name, h, **over):
    E = get_experiment(exp_name)
    kw = {"m": h.get("m", E.m), "divisions": h.get("divisions", E.divisions)}
    if "gravity_sign" in h:
        kw["arm"] = ohsaka_arm().with_gravity_sign(h["gravity_sign"])
    kw.update(over)
    return E.problem(**kw)


def _attach(P, h):
    if h.get("energy", "tau2") != "tau2" or h.get("quad", "trapezoid") != "trapezoid":
        P.objective = VariantObjective(P.family, P.arm, P.c1, P.c2, P.divisions,
                                       h.get("energy", "tau2"), h.get("quad", "trapezoid"))
    return P


def _fixed_end_posture(P, pattern):
    """theta_T = the lowest-centre-of-gravity posture at X(T) (step I's rule applied to the end),
    reached turning each joint the pattern's way."""
    thT = lowest_cog_posture(P.arm, P.XT)
    return P.theta0 + signed_travel(P.theta0, thT[None, :], pattern)[0]


def fig3_row(h):
    """{pattern: (z, T, end pattern, success)} for the paper's three patterns under hypothesis h."""
    base = _problem("ohsaka-fig3", h)
    out = {}
    for paper_p in PAPER_ORDER:
        # mirrored labels: the paper's angles counted the other way round (clockwise positive)
        p = tuple(-v for v in paper_p) if h.get("mirror") else paper_p
        P = _attach(base.with_travel_signs(p), h)
        if h.get("end") == "lowest_cog":
            thT = _fixed_end_posture(P, p)
            P.lower[:3] = P.upper[:3] = thT
        else:
            thT = initial_end_posture(P, p)
        y0 = initial_reduced_genes(P, thT, 1.0)
        if h.get("method") == "steepest":
            r = steepest_descent(P, P.family.reduced_to_full(y0)[0], max_iter=h["iters"], max_wall_s=60.0)
            x, z, ok = r.x, r.z, True
        else:
            r = solve_nlp(P, y0, "snopt")
            x, z, ok = r.x, r.z, r.success
        endp = travel_pattern(P.theta0, P.family.end_posture(x))
        out[paper_p] = (z, float(x[-1]), tuple(-v for v in endp) if h.get("mirror") else endp, ok)
    return out


def fig4_T(h):
    """T (s) and z of the best of the 8 free starts for Fig. 4 at c2 = 1e5."""
    base = _problem("ohsaka-fig4", h, c2=1e5)
    best = None
    for p in PATTERNS:
        P = _attach(base.with_travel_signs(None), h)   # a fresh copy: bounds may be changed below
        if h.get("end") == "lowest_cog":
            thT = _fixed_end_posture(P, p)
            P.lower[:3] = P.upper[:3] = thT
        else:
            thT = initial_end_posture(P, p)
        r = solve_nlp(P, initial_reduced_genes(P, thT, 1.0), "snopt")
        if r.success and (best is None or r.z < best[1]):
            best = (float(r.x[-1]), r.z)
    return best or (float("nan"), float("nan"))   # nan: no start converged


def fig4_paper_start(iters=(500, 800)):
    """Fig. 4 from the paper's printed initial vector (a31 = 0.575, all else 0, T = 1 s):
    [(c2, search, T, z, paper's rule fired at, end pattern)]: SNOPT for each of the paper's c2, and
    at c2 = 1e5 the paper's plain steepest descent stopped after each of `iters` iterations (the
    paper: 500-800)."""
    E = get_experiment("ohsaka-fig4")
    out = []
    for c2 in (1.0, 1e4, 1e5, 1e6):
        P = E.problem(c2=c2)
        x0 = paper_initial_x(P, E.paper_initial_a, E.T_init_s)
        r = solve_nlp(P, P.family.full_to_reduced(restore_endpoint(P, x0)), "snopt")
        out.append((c2, "SNOPT" + ("" if r.success else " (not converged)"), float(r.x[-1]), r.z, "-",
                    travel_pattern(P.theta0, P.family.end_posture(r.x))))
        if c2 != 1e5:
            continue
        for n in iters:
            s = steepest_descent(P, x0, max_iter=n, max_wall_s=60.0)
            out.append((c2, f"steepest descent, {n} iterations", float(s.x[-1]), s.z,
                        s.paper_rule_iteration if s.paper_rule_iteration else "not within the run",
                        travel_pattern(P.theta0, P.family.end_posture(s.x))))
    return out


def end_posture_scan(step_deg=20.0):
    """z of the paper's three patterns with the end posture FIXED at points of the self-motion
    manifold of X(T) (absolute angle psi of link 3, both elbow branches), each joint turned the
    pattern's way: [(elbow, psi_deg, theta_T_deg, {pattern: z})]. The local minima over psi of a
    pattern's curve are (approximately) that pattern's local optima with a free end posture."""
    base = _problem("ohsaka-fig3", {})
    rows = []
    for elbow in (1.0, -1.0):
        for psi in np.arange(0.0, 360.0, step_deg):
            q, ok = posture_on_manifold(base.arm, base.XT, np.radians([psi]), elbow)
            if not ok[0]:
                continue
            zs = {}
            for p in PAPER_ORDER:
                P = base.with_travel_signs(None)
                thT = base.theta0 + signed_travel(base.theta0, q, p)[0]
                P.lower[:3] = P.upper[:3] = thT
                r = solve_nlp(P, initial_reduced_genes(P, thT, 1.0), "snopt")
                zs[p] = r.z if r.success else float("nan")
            rows.append((elbow, psi, np.degrees(q[0]), zs))
    return rows


HYPOTHESES = {
    # name: (what it changes, options)
    "shipped": ("the shipped model: tau'tau with gravity, X2 up, trapezoid 40, m = 5", {}),
    "gravity_down": ("gravity along +X2 (the literal 'X2 is the gravity direction')", {"gravity_sign": -1.0}),
    "tau2_no_gravity": ("energy = tau'tau of the torque without its gravity part", {"energy": "tau2_dyn"}),
    "tau2_no_coriolis": ("tau = M(q) qdd + g(q): eq. (1) without its Coriolis/centrifugal terms",
                         {"energy": "tau2_no_qd"}),
    "power_abs": ("energy = |tau . qdot| (absolute mechanical power)", {"energy": "power_abs"}),
    "power_pos": ("energy = max(tau . qdot, 0) (motor work, no regeneration)", {"energy": "power_pos"}),
    "quad_rect": ("quadrature: left rectangles on 40 divisions", {"quad": "rect"}),
    "quad_nodes": ("quadrature: 41 node values each x T/40", {"quad": "nodes"}),
    "quad_simpson": ("quadrature: Simpson on 40 divisions", {"quad": "simpson"}),
    "quad_sum_no_dt": ("z = c1 sum_k tau_k'tau_k (41 nodes, no dt) + c2 T", {"quad": "sum_no_dt"}),
    "divisions_10": ("10 time divisions instead of 40", {"divisions": 10}),
    "m1": ("m = 1 Fourier term", {"m": 1}),
    "m2": ("m = 2 Fourier terms", {"m": 2}),
    "m3": ("m = 3 Fourier terms", {"m": 3}),
    "m8": ("m = 8 Fourier terms", {"m": 8}),
    "end_lowest_cog": ("end posture fixed: lowest centre of gravity at X(T), turned the pattern's way",
                       {"end": "lowest_cog"}),
    "end_lowest_cog_down": ("as end_lowest_cog with gravity along +X2", {"end": "lowest_cog", "gravity_sign": -1.0}),
    "labels_mirrored": ("the paper's rotation labels read with the opposite angle sign ((+,-,-) is our (-,+,+))",
                        {"mirror": True}),
    "labels_mirrored_gravity_down": ("mirrored labels and gravity along +X2", {"mirror": True, "gravity_sign": -1.0}),
    "steepest_500": ("the paper's plain steepest descent, 500 iterations from the pattern's start",
                     {"method": "steepest", "iters": 500}),
    "steepest_800": ("the paper's plain steepest descent, 800 iterations", {"method": "steepest", "iters": 800}),
}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="comma list of hypothesis names (default: all)")
    ap.add_argument("--no-fig4", action="store_true", help="skip the Fig. 4 T column and table")
    ap.add_argument("--fig4-only", action="store_true", help="only the Fig. 4 paper-start table")
    ap.add_argument("--scan", type=float, default=0.0, metavar="STEP_DEG",
                    help="only the end-posture scan of Fig. 3 at this psi step (20: about 45 s CPU)")
    a = ap.parse_args(argv)
    if a.scan:
        print("| elbow | psi (deg) | theta_T mod 360 (deg) | (+,-,-) z | (+,+,+) z | (-,+,-) z | order as paper |")
        print("|---|---|---|---|---|---|---|")
        for elbow, psi, q, zs in end_posture_scan(a.scan):
            z = [zs[p] for p in PAPER_ORDER]
            print(f"| {elbow:+.0f} | {psi:.0f} | ({q[0]:.1f}, {q[1]:.1f}, {q[2]:.1f}) | "
                  + " | ".join(f"{v:.0f}" for v in z) + f" | {'yes' if z[0] > z[1] > z[2] else 'no'} |", flush=True)
        return 0
    names = [] if a.fig4_only else ([n for n in a.only.split(",") if n] or list(HYPOTHESES))
    for n in names:
        if n not in HYPOTHESES:
            print(f"unknown hypothesis '{n}'; choose from {', '.join(HYPOTHESES)}", file=sys.stderr)
            return 2
    dM, dg = model_vs_printed()
    print(f"model vs the paper's printed formulas, 200 random postures: M(q) max rel. dev. {dM:.1e}, "
          f"g(q) {dg:.1e}\n")
    hdr = "| hypothesis | (+,-,-) z | (+,+,+) z | (-,+,-) z | order as paper | Fig. 4 T (s) | cpu s |"
    print(hdr)
    print("|" + "---|" * 7)
    print("| paper | " + " | ".join(f"{PAPER_Z[p]:.0f}" for p in PAPER_ORDER) + f" | yes | {PAPER_FIG4_T_S[1e5]:.3f} | |")
    for n in names:
        desc, h = HYPOTHESES[n]
        c0 = time.process_time()
        rows = fig3_row(h)
        cells = []
        for p in PAPER_ORDER:
            z, T, endp, ok = rows[p]
            mark = "" if endp == p else "*"
            cells.append(f"{z:.0f}{mark} (T {T:.3f}{'' if ok else ', not converged'})")
        zs = [rows[p][0] for p in PAPER_ORDER]
        order = "yes" if zs[0] > zs[1] > zs[2] else "no: " + " > ".join(
            pattern_str(p) for p in sorted(PAPER_ORDER, key=lambda p: -rows[p][0]))
        t4 = "" if a.no_fig4 or h.get("method") == "steepest" else f"{fig4_T(h)[0]:.3f}"
        print(f"| {n}: {desc} | " + " | ".join(cells) + f" | {order} | {t4} | {time.process_time() - c0:.1f} |",
              flush=True)
    if not a.no_fig4:
        print("\nFig. 4 from the paper's printed initial vector (a31 = 0.575, all else 0, T = 1 s)")
        print("| c2 | search | T (s) | paper T (s) | z | paper's rule (1e-4 x 5) fired at | end pattern |")
        print("|---|---|---|---|---|---|---|")
        for c2, lab, T, z, fired, endp in fig4_paper_start():
            print(f"| {c2:g} | {lab} | {T:.4f} | {PAPER_FIG4_T_S[c2]:.3f} | {z:.0f} | {fired} | {pattern_str(endp)} |",
                  flush=True)
    print("\n* the best trajectory of that pattern ends on the pattern's boundary (a joint does not turn);"
          " its actual travel pattern differs.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
