"""Features of the plan command on the spatial arms as on the planar ones: GA checkpoints that resume to
the same plan, limits no plan meets (exit 3: the least-violating plan, or one line naming the binding
limit where no timing exists), --carried-feedforward (the search on the scenario's DC motors)."""

import json
from pathlib import Path

import numpy as np
import pytest

from qmt_drake.api import load_scenario, plan_with
from qmt_drake.apps.cli import main
from qmt_drake.errors import QmtInputError, QmtNoPlanError
from qmt_drake.planners.spatial_search import check_ga_checkpoint

SC = "ur5-magnet-part"
GA = {"generations": 6, "population": 6, "stall": 6}
SHIPPED = Path(__file__).resolve().parents[1] / "models" / "scenarios" / f"{SC}.yaml"


def _main(capsys, *argv):
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture(scope="module")
def sc():
    return load_scenario(SC)


@pytest.fixture(scope="module")
def weak_shoulder(tmp_path_factory):
    """The UR5 magnet task with a 1 N m shoulder-lift torque limit: gravity alone breaks it at rest."""
    text = SHIPPED.read_text().replace("torque_limit_Nm: [150.0, 150.0, 150.0, 28.0, 28.0, 28.0]",
                                       "torque_limit_Nm: [150.0, 1.0, 150.0, 28.0, 28.0, 28.0]")
    assert "[150.0, 1.0, 150.0" in text
    p = tmp_path_factory.mktemp("weak") / "ur5-weak-shoulder.yaml"
    p.write_text(text.replace(f"name: {SC}", "name: ur5-weak-shoulder"))
    return p


class _Stop(Exception):
    pass


def _stopped_at_generation_4(sc, tmp_path) -> Path:
    """The checkpoint of a seed-1 GA run (GA's size) stopped, as by Ctrl-C, at generation 4."""
    ckpt = tmp_path / "ga.ckpt.json"

    def crash(msg):
        if "generation 4 of" in msg:
            raise _Stop

    with pytest.raises(_Stop):
        plan_with("ga", sc, seed=1, checkpoint_path=str(ckpt), checkpoint_every=2, progress=crash,
                  progress_every_s=0.0, **GA)
    return ckpt


def test_interrupted_spatial_ga_resumes_to_the_same_plan(sc, tmp_path):
    full = plan_with("ga", sc, seed=1, **GA)
    ckpt = _stopped_at_generation_4(sc, tmp_path)
    assert ckpt.is_file()
    with pytest.raises(QmtInputError, match="belongs to another run"):  # another seed: refused before any work
        check_ga_checkpoint(sc, ckpt, seed=2, **GA)
    resumed = plan_with("ga", sc, seed=1, checkpoint_path=str(ckpt), **GA)
    assert resumed.genes == full.genes and resumed.duration_s == full.duration_s
    t = np.linspace(0.0, full.duration_s, 50)
    np.testing.assert_array_equal(resumed.trajectory.sample(t)[0], full.trajectory.sample(t)[0])
    assert not ckpt.exists()  # a finished run leaves no checkpoint


def test_a_stopped_spatial_ga_resumes_with_more_generations(sc, tmp_path):
    """How long a run may go is not part of its identity (as on the planar arms): stopped at generation 4
    of 6, it resumes under generations=10 and ends where an uninterrupted 10-generation run ends."""
    longer = {**GA, "generations": 10, "stall": 10}
    full = plan_with("ga", sc, seed=1, **longer)
    ckpt = _stopped_at_generation_4(sc, tmp_path)
    check_ga_checkpoint(sc, ckpt, seed=1, **longer)  # the same run: accepted
    said = []
    resumed = plan_with("ga", sc, seed=1, checkpoint_path=str(ckpt), progress=said.append, **longer)
    assert any(line.startswith("resuming") for line in said), said
    assert resumed.genes == full.genes and resumed.duration_s == full.duration_s


def test_cli_checkpoint_of_another_run_is_refused_in_one_line(capsys, tmp_path):
    bad = tmp_path / "c.json"
    bad.write_text('{"format": "not a checkpoint"}')
    rc, _, err = _main(capsys, "plan", SC, "--method", "ga", "--checkpoint", bad, "--generations", "2", "--quiet")
    assert rc == 2 and err.startswith("qmt-drake: error: --checkpoint: checkpoint") and err.count("\n") == 1, err


def test_limits_no_plan_meets_exit_3_with_the_least_violating_ga_plan(capsys, tmp_path, weak_shoulder):
    out = tmp_path / "ga.json"
    rc, stdout, err = _main(capsys, "plan", weak_shoulder, "--method", "ga", "--generations", "2", "--option",
                            "population=6", "--json", out)
    assert rc == 3, err
    d = json.loads(out.read_text())
    assert d["feasible"] is False and d["recheck"]["max"] > 1.0
    assert d["recheck"]["binding"] == "motor_torque[shoulder_lift_joint]"
    assert "motor_torque[shoulder_lift_joint]" in d["info"]["least_violating"]
    assert "INFEASIBLE (least-violating plan; binding limit motor_torque[shoulder_lift_joint]" in stdout
    assert "the GA found no via_cubic motion within the limits in 2 generations: motor_torque[shoulder_lift_joint]" in err


def test_a_path_broken_at_rest_exit_3_naming_the_binding_limit(capsys, tmp_path, weak_shoulder):
    rc, _, err = _main(capsys, "plan", weak_shoulder, "--method", "toppra", "--json", tmp_path / "t.json", "--quiet")
    assert rc == 3 and err.count("\n") == 1, err
    assert err.startswith("qmt-drake: no plan: TOPP-RA found no parameterisation of the path: "
                          "motor_torque[shoulder_lift_joint] needs"), err
    assert not (tmp_path / "t.json").exists()
    with pytest.raises(QmtNoPlanError, match="shoulder_lift_joint"):  # the API: a QmtInputError subclass
        plan_with("toppra", load_scenario(weak_shoulder))


def test_carried_feedforward_is_refused_only_where_the_scenario_has_no_motors(capsys, tmp_path):
    """--carried-feedforward makes the spatial --carried search co-simulate the scenario's DC motors; a
    scenario without motor constants says so in one line before planning."""
    no_motor = tmp_path / "no-motor.yaml"
    text = SHIPPED.read_text()
    start = text.index("  motor:\n")
    end = text.index("payload:")
    no_motor.write_text(text[:start] + text[end:])
    rc, _, err = _main(capsys, "plan", no_motor, "--method", "toppra", "--carried", "--carried-feedforward", "none",
                       "--quiet")
    assert rc == 2 and "motor" in err and err.count("\n") == 1, err
