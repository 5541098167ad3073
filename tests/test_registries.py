"""The plug-in registries (config/registry.py): a hand, an actuator, a family and an objective
registered here, in-process, are dispatched by the loader, the builders, the planners and the CLI
without any core file naming them; unknown kinds are refused in one line listing the registered ones;
each test unregisters what it added."""

import json
from dataclasses import replace

import numpy as np
import pytest
import yaml

from qmt_drake import load_scenario
from qmt_drake.actuators import actuator_plugin
from qmt_drake.apps.bang_bang import bang_bang_acceleration_m_s2
from qmt_drake.apps.cli import main
from qmt_drake.budgets import check_replay_budget
from qmt_drake.config.registry import ACTUATORS, FAMILIES, HANDS, OBJECTIVES, ObjectivePlugin, Registry
from qmt_drake.config.scenario import SCENARIO_DIR
from qmt_drake.config.validate import parse_dc_motor_gear, parse_ideal_torque, parse_magnet_hand
from qmt_drake.errors import QmtInputError
from qmt_drake.families import make_family
from qmt_drake.hands import hand_plugin
from qmt_drake.problem import PlanningProblem
from qmt_drake.sim import GenesPlan, build_transfer_diagram, run_transfer_simulate
from qmt_drake.sim.magnet_actuation import IDEAL_TORQUE_ACTUATION


@pytest.fixture
def registered():
    """register(registry, entry): registered for one test, unregistered after it."""
    added = []

    def register(registry, entry):
        registry.register(entry)
        added.append((registry, entry.kind))
        return entry
    yield register
    for registry, kind in added:
        registry.unregister(kind)
    assert all(kind not in registry for registry, kind in added)


def _yaml(tmp_path, name, **sections):
    raw = yaml.safe_load((SCENARIO_DIR / f"{name}.yaml").read_text())
    raw["arm"]["urdf"] = str((SCENARIO_DIR / raw["arm"]["urdf"]).resolve())
    for key, value in sections.items():
        raw[key].update(value)
    p = tmp_path / f"{name}-copy.yaml"
    p.write_text(yaml.safe_dump(raw))
    return str(p)


def _magnet_copy(kind, **changes):
    """The magnet's plug-in registered under another kind (its section keeps the new kind)."""
    return replace(HANDS["magnet"], kind=kind, parse=lambda h, where: replace(parse_magnet_hand(h, where), kind=kind),
                   **changes)


def test_a_registry_registers_once_and_refuses_unknown_kinds_in_one_line():
    reg = Registry("widget")
    reg.register(ObjectivePlugin("a", make=lambda sc: None))
    reg.register(ObjectivePlugin("b", make=lambda sc: None, scenario_kind="other"))
    with pytest.raises(ValueError, match="already registered"):
        reg.register(ObjectivePlugin("a", make=lambda sc: None))
    with pytest.raises(QmtInputError) as exc:
        reg.get("c", "file.yaml: widget")
    assert str(exc.value) == "file.yaml: widget.kind 'c' is not one of a, b (the registered kinds)"
    with pytest.raises(QmtInputError, match=r"'b' is not one of a \("):
        reg.get("b", accept=lambda e: e.scenario_kind != "other")  # registered, but not for this use
    reg.unregister("a")
    assert reg.kinds() == ("b",)


def test_a_new_hand_kind_runs_through_the_loader_the_builders_and_the_cli(tmp_path, capsys, registered):
    """A copy of the magnet's plug-in under the kind 'magnet_copy' (with its own plan line): the
    scenario loads, its limit set, bang-bang bound and replay budget come from the plug-in, and
    `plan` / `simulate` give the magnet's numbers while printing the copy's line."""
    registered(HANDS, _magnet_copy("magnet_copy", plan_ratios_text=lambda plan: "copy's own ratios"))
    path = _yaml(tmp_path, "thesis-ch2", hand={"kind": "magnet_copy"})
    sc, ref = load_scenario(path), load_scenario("thesis-ch2")
    assert sc.hand.kind == "magnet_copy" and hand_plugin(sc).kind == "magnet_copy"
    assert bang_bang_acceleration_m_s2(sc) == bang_bang_acceleration_m_s2(ref)
    assert check_replay_budget(sc, 1.0).seconds == check_replay_budget(ref, 1.0).seconds
    genes = np.array([ref.reported["genes"][g] for g in ref.family.gene_names])
    assert PlanningProblem(sc).peaks(genes).worst_ratio == pytest.approx(PlanningProblem(ref).peaks(genes).worst_ratio,
                                                                       rel=1e-12)

    assert main(["plan", path, "--method", "thesis"]) == 0
    assert "copy's own ratios" in capsys.readouterr().out
    results = {}
    for name, scenario in (("copy", path), ("magnet", "thesis-ch2")):
        out = tmp_path / f"{name}.json"
        assert main(["simulate", scenario, "--method", "thesis", "--json", str(out), "--quiet"]) == 0
        results[name] = json.loads(out.read_text())
    assert results["copy"]["outcome"] == results["magnet"]["outcome"]
    assert results["copy"]["max_slip_m"] == results["magnet"]["max_slip_m"]

    HANDS.unregister("magnet_copy")
    with pytest.raises(QmtInputError, match=r"hand.kind 'magnet_copy' is not one of magnet, tray"):
        load_scenario(path)


def test_a_new_family_kind_is_built_by_its_registered_constructor(tmp_path, registered):
    calls = []

    def make(scenario):
        calls.append(scenario.name)
        return FAMILIES["line_cubic_velocity"].make(scenario)
    registered(FAMILIES, replace(FAMILIES["line_cubic_velocity"], kind="line_copy", make=make))
    path = _yaml(tmp_path, "thesis-ch2", family={"kind": "line_copy"})
    sc, ref = load_scenario(path), load_scenario("thesis-ch2")
    fam, fam_ref = make_family(sc), make_family(ref)
    assert calls == [sc.name]
    genes = np.array([[ref.reported["genes"][g] for g in ref.family.gene_names]])
    t = np.linspace(0.0, float(fam_ref.motion_time_s(genes)[0]), 50)
    for a, b in zip(fam.sample(genes, t), fam_ref.sample(genes, t)):
        np.testing.assert_array_equal(a, b)

    FAMILIES.unregister("line_copy")
    with pytest.raises(QmtInputError) as exc:
        load_scenario(path)
    msg = str(exc.value)
    assert "family.kind 'line_copy' is not one of line_cubic_velocity, trapezoid_ptp, via_cubic" in msg
    assert "fourier_velocity" not in msg and "\n" not in msg  # only the transfer families, one line


def test_a_new_actuator_kind_says_what_it_adds(tmp_path, registered):
    """A copy of dc_motor_gear whose joints' speeds are given: the loader checks its per-joint list
    and refuses a control section it does not take, the limit set's joint-speed term scales its speeds."""
    def parse(a, limits, where):
        return replace(parse_dc_motor_gear(a, limits, where), kind="motor_copy")
    registered(ACTUATORS, replace(ACTUATORS["dc_motor_gear"], kind="motor_copy", parse=parse,
                                  joint_speeds_rad_s=lambda act: [4.0, 8.0]))
    path = _yaml(tmp_path, "thesis-ch4", actuator={"kind": "motor_copy"}, limits={"joint_speed_fraction": 0.5})
    sc = load_scenario(path)
    assert actuator_plugin(sc).kind == "motor_copy"
    (speed,) = [t for t in sc.limit_set.terms if type(t).__name__ == "JointSpeedTerm"]
    np.testing.assert_allclose(speed.limit_rad_s, [2.0, 4.0])
    with pytest.raises(QmtInputError, match=r"actuator.motors has 1 entries but the arm"):
        load_scenario(_yaml(tmp_path, "thesis-ch4", actuator={"kind": "motor_copy", "motors": ["maxon_RE30_60W_24V"]}))

    ACTUATORS.unregister("motor_copy")
    registered(ACTUATORS, replace(ACTUATORS["dc_motor_gear"], kind="motor_copy", parse=parse,
                                  control_refused="this copy takes no PID gains: drop the control section"))
    with pytest.raises(QmtInputError, match="this copy takes no PID gains"):
        load_scenario(path)


def test_a_new_actuator_kind_brings_its_own_magnet_actuation(tmp_path, registered):
    """A copy of `ideal` under the kind 'ideal_copy' whose magnet actuation records each call: the
    magnet co-simulation checks and builds through it (sim/ names no actuator kind), runs to ideal's
    outcome and max slip exactly, and refuses motor options naming the copy's kind."""
    calls = []

    class Recorded:  # ideal's magnet actuation, each call recorded
        def __getattr__(self, name):
            def call(*args, **kwargs):
                calls.append(name)
                return getattr(IDEAL_TORQUE_ACTUATION, name)(*args, **kwargs)
            return call

    def parse(a, limits, where):
        return replace(parse_ideal_torque(a, limits, where), kind="ideal_copy")
    registered(ACTUATORS, replace(ACTUATORS["ideal"], kind="ideal_copy", parse=parse, magnet_actuation=Recorded()))
    ref = load_scenario("thesis-ch4")
    plant = ref.arm.plant
    J, w = np.diag(plant.CalcMassMatrix(plant.CreateDefaultContext())), 60.0  # a 60 rad/s PD loop
    raw = yaml.safe_load((SCENARIO_DIR / "thesis-ch4.yaml").read_text())
    raw["arm"]["urdf"] = str((SCENARIO_DIR / raw["arm"]["urdf"]).resolve())
    raw["control"] = {"kp": (J * w**2).tolist(), "kd": (2 * J * w).tolist()}
    results = {}
    for kind in ("ideal_copy", "ideal"):
        raw["actuator"] = {"kind": kind}
        path = tmp_path / f"{kind}.yaml"
        path.write_text(yaml.safe_dump(raw))
        sc = load_scenario(str(path))
        assert actuator_plugin(sc).kind == kind
        results[kind] = run_transfer_simulate(sc, GenesPlan(sc, (0.622, 0.532, 0.562)), feedforward="full")
    assert calls == ["feedforward_keywords", "check", "loop_scheme", "setup", "add"]
    assert results["ideal_copy"]["outcome"] == results["ideal"]["outcome"] == "carried"
    assert results["ideal_copy"]["max_slip_m"] == results["ideal"]["max_slip_m"]
    copy = load_scenario(str(tmp_path / "ideal_copy.yaml"))
    with pytest.raises(QmtInputError, match="has actuator.kind ideal_copy [(]no motors[)]"):
        build_transfer_diagram(copy, GenesPlan(copy, (0.622, 0.532, 0.562)), back_emf_feedforward=True)


def test_a_transfer_objective_is_picked_by_kind(registered):
    sc = load_scenario("thesis-ch4")
    assert type(PlanningProblem(sc).objective).__name__ == "MinimumTime"  # the default, min_time

    class Flat:
        def fitness(self, ev):
            return np.where(ev.feasible, 1.0, 0.0)
    registered(OBJECTIVES, ObjectivePlugin("feasible_only", lambda scenario: Flat()))
    P = PlanningProblem(sc, "feasible_only")
    genes = np.array([[sc.reported["genes"][g] for g in sc.family.gene_names]])
    ev = P.evaluate(genes)
    assert P.fitness(ev)[0] == (1.0 if ev.feasible[0] else 0.0)
    with pytest.raises(QmtInputError, match=r"objective.kind 'energy_time' is not one of min_time, feasible_only"):
        PlanningProblem(sc, "energy_time")  # registered, but for energy-time scenarios


def test_the_scenario_objective_section_picks_a_registered_objective(tmp_path, registered):
    """`objective: {kind: ...}` in a transfer scenario: the default min_time keeps the fingerprint of a file
    without the section (saved plans stay valid), another registered kind is what PlanningProblem
    minimises and changes the fingerprint, an unknown or energy-time kind is refused in one line."""
    base = load_scenario("thesis-ch4")

    def with_objective(kind):
        raw = yaml.safe_load((SCENARIO_DIR / "thesis-ch4.yaml").read_text())
        raw["arm"]["urdf"] = str((SCENARIO_DIR / raw["arm"]["urdf"]).resolve())
        raw["objective"] = {"kind": kind}
        p = tmp_path / f"ch4-{kind}.yaml"
        p.write_text(yaml.safe_dump(raw))
        return load_scenario(str(p))

    same = with_objective("min_time")
    assert same.objective == base.objective == "min_time" and same.fingerprint() == base.fingerprint()

    class Flat:
        def fitness(self, ev):
            return np.where(ev.feasible, 1.0, 0.0)
    registered(OBJECTIVES, ObjectivePlugin("feasible_only", lambda scenario: Flat()))
    other = with_objective("feasible_only")
    assert isinstance(PlanningProblem(other).objective, Flat) and other.fingerprint() != base.fingerprint()
    for kind in ("energy_time", "fastest"):
        with pytest.raises(QmtInputError, match=rf"objective.kind '{kind}' is not one of min_time, feasible_only") as e:
            with_objective(kind)
        assert "\n" not in str(e.value)
