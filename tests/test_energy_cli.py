"""`qmt-drake plan` on energy-time scenarios: results, JSON, CSV and one-line input errors (exit 2)."""

import json

import pytest

from qmt_drake.apps.cli import main


@pytest.mark.parametrize("argv,msg", [
    (["--c2", "0"], "no stable solution"), (["--c2", "-1"], "--c2 -1.0 must be >= 0"), (["--c1", "-1"], "--c1 -1.0 must be >= 0"),
    (["--m", "0"], "--m 0 must be >= 1"), (["--coords", "0.7", "0", "0", "0.9"], "out of reach"),
    (["--pattern", "xyz"], "--pattern"), (["--divisions", "1"], "divisions"),
])
def test_bad_input_exit_2_one_line(capsys, argv, msg):
    assert main(["plan", "ohsaka-fig3", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert msg in err and "\n" not in err and "Traceback" not in err


def test_one_pattern_json(tmp_path, capsys):
    path = tmp_path / "r.json"
    assert main(["plan", "ohsaka-fig3", "--pattern", "npn", "--json", str(path)]) == 0
    d = json.loads(path.read_text())
    (opt,) = d["optima"]
    assert opt["success"] and opt["start"] == "(-,+,-)"
    assert opt["z"] == pytest.approx(1e5 * opt["T_s"] + opt["energy"], rel=1e-12)


def test_plan_csv_cost_recomputed_from_its_own_columns_and_simulate_runs_the_plan(tmp_path, capsys):
    """`plan ohsaka-fig3 --method snopt --json p.json --trajectory-csv p.csv`, then `simulate ohsaka-fig3
    --plan p.json`. The cost z = integral (c1 tau'tau + c2) dt is recomputed from the CSV's q, qd, qdd
    columns with Drake's own inverse dynamics (not ours) and the trapezoid rule on the CSV's grid, and
    compared with the plan's fine-grid z (2000 divisions): both quadratures are within ~1e-6 of the
    integral, so 1e-5 relative separates a right CSV from a wrong one (a 1 % torque error moves z by
    ~1e-2 of its energy part)."""
    import numpy as np

    from qmt_drake.energy.dynamics import drake_inverse_dynamics
    pj, pc = tmp_path / "p.json", tmp_path / "p.csv"
    assert main(["plan", "ohsaka-fig3", "--method", "snopt", "--pattern=+--", "--json", str(pj),
                 "--trajectory-csv", str(pc), "--quiet"]) == 0
    d = json.loads(pj.read_text())
    head = pc.read_text().splitlines()[0].split(",")
    data = np.loadtxt(pc, delimiter=",", skiprows=1)
    col = {h: data[:, i] for i, h in enumerate(head)}
    t = col["t_s"]
    q, qd, qdd = (np.column_stack([col[f"{k}{i}{u}"] for i in (1, 2, 3)])
                  for k, u in (("q", "_rad"), ("qd", "_rad_s"), ("qdd", "_rad_s2")))
    tau = drake_inverse_dynamics(q, qd, qdd)
    np.testing.assert_allclose(tau, np.column_stack([col[f"tau{i}_Nm"] for i in (1, 2, 3)]), rtol=1e-9, atol=1e-9)
    f = d["c1"] * np.sum(tau * tau, axis=1) + d["c2"]
    z_csv = float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(t)))
    assert t[-1] == pytest.approx(d["plan"]["motion_time_s"], rel=1e-12)
    assert z_csv == pytest.approx(d["plan"]["z_fine"], rel=1e-5)
    sj = tmp_path / "s.json"
    assert main(["simulate", "ohsaka-fig3", "--plan", str(pj), "--json", str(sj)]) == 0
    s = json.loads(sj.read_text())
    assert s["reached_goal"] and s["motion_time_s"] == pytest.approx(d["plan"]["motion_time_s"])
    assert main(["simulate", "ohsaka-fig2", "--plan", str(pj)]) == 2  # made for another experiment
    assert "was made for 'ohsaka-fig3'" in capsys.readouterr().err
