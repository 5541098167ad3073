"""The optional `simulation:` section (config/simulation.py): Drake's MultibodyPlantConfig / SimulatorConfig
fields by Drake's names, loaded through the one validation layer, used by every co-simulation kind as the
default a run option overrides, and no part of a plan's identity."""

import json

import numpy as np
import pytest
from pydrake.multibody.plant import DiscreteContactApproximation
from pydrake.systems.analysis import ExtractSimulatorConfig, GetIntegrationSchemes
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, Integrator

from qmt_drake.api import load_scenario
from qmt_drake.apps.cli import main
from qmt_drake.config.simulation import INTEGRATION_SCHEMES, NO_SIMULATION, SimulatorSettings
from qmt_drake.energy.energy_plan import make_energy_plan
from qmt_drake.energy.experiments import paper_initial_x
from qmt_drake.energy.steepest import restore_endpoint
from qmt_drake.errors import QmtInputError
from qmt_drake.plan_files import load_plan
from qmt_drake.plan_identity import energy_sections, identity, spatial_sections, transfer_sections
from qmt_drake.planners import plan_with
from qmt_drake.planners.spatial_plan_io import write_spatial_plan
from qmt_drake.scenario_data import load_scenario_data
from qmt_drake.sim.cosim import build_cosim
from qmt_drake.sim.cosim_run import CoSim, run
from qmt_drake.tray.execute import build_tray_plan_cosim
from tests.scenario_files import scenario_yaml
from tests.spatial_fixtures import shipped_toppra

SIMULATOR = {"integration_scheme": "runge_kutta2", "max_step_size": 0.002, "accuracy": 0.001,
             "use_error_control": False, "target_realtime_rate": 0.0, "publish_every_time_step": False}


def _refusal(call) -> str:
    with pytest.raises(QmtInputError) as exc:
        call()
    assert "\n" not in str(exc.value)
    return str(exc.value)


def _with(name, plant=None, simulator=None):
    sim = {k: v for k, v in (("plant", plant), ("simulator", simulator)) if v is not None}
    return load_scenario(name, overrides={"simulation": sim})


def _plan_file(name, tmp_path):
    """A plan of the built-in scenario `name` (no simulation section) written to a file."""
    path = tmp_path / f"{name}.json"
    sc = load_scenario(name)
    if name == "ur5-suction-bins":
        write_spatial_plan(sc, shipped_toppra(name, 400), path)  # once per session, shared with test_obstacles
    elif name == "ohsaka-fig2":
        P = sc.problem(m=3)
        make_energy_plan(sc, P, "test", restore_endpoint(P, paper_initial_x(P, {}, sc.fixed_T_s)), True).write_json(path)
    else:
        plan_with("thesis", sc).write_json(path)
    return path


def _plans(name, tmp_path, **section):
    """(the scenario with `section`, the plan made before it loaded against it: a scenario that only adds
    `simulation:` accepts the plans made before, its identity checked; the plain scenario, the plan on it)."""
    sc = _with(name, **section)
    path = _plan_file(name, tmp_path)
    return sc, load_plan(path, sc), load_scenario(name), load_plan(path, load_scenario(name))


# ---------------------------------------------------------------------------------------------- loading

def test_a_good_section_loads_as_plain_data_and_a_file_without_it_gives_nothing(tmp_path):
    path = scenario_yaml(tmp_path, simulation={"plant": {"time_step": 1e-3, "discrete_contact_approximation": "sap",
                                                         "penetration_allowance": 2e-3, "stiction_tolerance": 1e-4,
                                                         "sap_near_rigid_threshold": 0.5},
                                               "simulator": SIMULATOR})
    d = load_scenario_data(path)
    assert d.simulation.plant.given() == {"time_step": 1e-3, "discrete_contact_approximation": "sap",
                                          "penetration_allowance": 2e-3, "stiction_tolerance": 1e-4,
                                          "sap_near_rigid_threshold": 0.5}
    assert d.simulation.simulator.given() == SIMULATOR
    for name in ("thesis-ch4", "crane-tray", "ur5-suction-bins", "ohsaka-fig2"):
        assert load_scenario_data(name).simulation == NO_SIMULATION


@pytest.mark.parametrize("section, expected", [
    ({"plant": {"time_stepp": 1e-3}}, "simulation.plant: unknown key 'time_stepp'; allowed keys are "
                                      "discrete_contact_approximation, penetration_allowance, sap_near_rigid_threshold, "
                                      "stiction_tolerance, time_step"),
    ({"plants": {}}, "simulation: unknown key 'plants'; allowed keys are plant, simulator"),
    ({"simulator": {"accuracy": 1e-3, "integrator": "rk3"}}, "simulation.simulator: unknown key 'integrator'"),
    ({"plant": {"time_step": True}}, "simulation.plant.time_step must be a number, got True"),
    ({"plant": {"time_step": "0.001"}}, "simulation.plant.time_step must be a number, got '0.001'"),  # a string
    ({"plant": {"time_step": -1e-3}}, "simulation.plant.time_step must be non-negative, got -0.001"),
    ({"plant": {"discrete_contact_approximation": "Sap"}}, "simulation.plant.discrete_contact_approximation 'Sap' is not "
                                                           "one of tamsi, sap, similar, lagged"),
    ({"simulator": {"use_error_control": 1}}, "simulation.simulator.use_error_control must be true or false, got 1"),
    ({"simulator": {"integration_scheme": "rk4"}}, "simulation.simulator.integration_scheme 'rk4' is not one of"),
    ({"plant": {"use_sampled_output_ports": True}}, "simulation.plant.use_sampled_output_ports is not a setting of the "
                                                    "co-simulation"),
    ({"simulator": {"start_time": 1.0}}, "simulation.simulator.start_time is not a setting of the co-simulation"),
    ({"plant": {"time_step": 0.0}}, "simulation.plant.time_step 0 (a continuous plant) cannot run this scenario"),
    ("fast", "simulation must be a mapping with plant and/or simulator, got 'fast'"),
])
def test_a_bad_section_stops_in_one_line_naming_the_key_path(tmp_path, section, expected):
    path = scenario_yaml(tmp_path, simulation=section)
    msg = _refusal(lambda: load_scenario_data(path))
    assert msg.startswith(f"{path}: ") and expected in msg, msg


def test_what_cannot_apply_to_a_kind_is_refused_with_its_physics_reason():
    msg = _refusal(lambda: _with("ur5-suction-bins", plant={"discrete_contact_approximation": "tamsi"}))
    assert "ur5-suction-bins.yaml: simulation.plant.discrete_contact_approximation tamsi: the hand holds its part by " \
           "a weld constraint" in msg
    _with("ur5-suction-bins", plant={"time_step": 5e-4})  # a step is fine
    msg = _refusal(lambda: _with("ohsaka-fig2", plant={"stiction_tolerance": 1e-3}))
    assert "simulation.plant.stiction_tolerance: the vertical arm makes no contact" in msg
    msg = _refusal(lambda: _with("ur5-suction-bins", plant={"time_step": 0.0}))
    assert "simulation.plant.time_step 0 (a continuous plant) cannot run this scenario" in msg


def test_the_integration_schemes_are_drakes():
    assert tuple(sorted(GetIntegrationSchemes())) == INTEGRATION_SCHEMES


# ------------------------------------------------------------------------- every kind takes the section

def test_planar_magnet_plant_takes_the_section_and_a_run_option_wins(tmp_path):
    sc, plan, plain_sc, plain_plan = _plans("thesis-ch4", tmp_path, simulator=SIMULATOR,
                                            plant={"time_step": 1.5e-3, "discrete_contact_approximation": "sap"})
    cosim = build_cosim(sc, plan)
    assert cosim.plant.time_step() == 1.5e-3 and cosim.time_step_s == 1.5e-3
    assert cosim.plant.get_discrete_contact_approximation() == DiscreteContactApproximation.kSap
    assert cosim.simulator_settings.given() == SIMULATOR
    over = build_cosim(sc, plan, time_step_s=1e-3)
    assert over.plant.time_step() == 1e-3
    plain = build_cosim(plain_sc, plain_plan)  # without the section: the kind's 2 ms, kLagged
    assert plain.plant.time_step() == 2e-3
    assert plain.plant.get_discrete_contact_approximation() == DiscreteContactApproximation.kLagged
    assert plain.simulator_settings.given() == {}
    # a section's step the explicit loop is known unstable at is refused naming the section
    msg = _refusal(lambda: build_cosim(_with("thesis-ch4", plant={"time_step": 2e-3}), plan,
                                       implicit_loop_damping=False))
    assert msg.startswith("scenario thesis-ch4: simulation.plant.time_step: time step 2 ms is above 1 ms"), msg


def test_tray_plant_takes_the_section_and_run_options_win(tmp_path):
    sc, plan, plain_sc, plain_plan = _plans("crane-tray", tmp_path,
                                            plant={"time_step": 2.5e-4, "discrete_contact_approximation": "similar"})
    cosim = build_cosim(sc, plan)
    assert cosim.plant.time_step() == 2.5e-4
    assert cosim.plant.get_discrete_contact_approximation() == DiscreteContactApproximation.kSimilar
    assert build_cosim(sc, plan, time_step_s=5e-4).plant.time_step() == 5e-4
    approx = build_tray_plan_cosim(sc, plan, contact_approximation="sap").plant  # the margin study's run option
    assert approx.get_discrete_contact_approximation() == DiscreteContactApproximation.kSap
    plain = build_cosim(plain_sc, plain_plan)
    assert plain.plant.time_step() == 1e-3
    assert plain.plant.get_discrete_contact_approximation() == DiscreteContactApproximation.kLagged
    msg = _refusal(lambda: build_cosim(_with("crane-tray", plant={"time_step": 2e-3}), plan))
    assert msg.startswith("crane-tray: simulation.plant.time_step 0.002 s: the tray co-simulation's plant step must "
                          "not exceed the servos' control period (1 ms)"), msg


def test_spatial_plant_takes_the_section_and_a_run_option_wins(tmp_path):
    sc, plan, plain_sc, plain_plan = _plans("ur5-suction-bins", tmp_path, simulator={"max_step_size": 0.01},
                                            plant={"time_step": 5e-4, "discrete_contact_approximation": "similar"})
    cosim = build_cosim(sc, plan)
    assert cosim.plant.time_step() == 5e-4
    assert cosim.plant.get_discrete_contact_approximation() == DiscreteContactApproximation.kSimilar
    assert cosim.simulator_settings.given() == {"max_step_size": 0.01}
    assert build_cosim(sc, plan, time_step_s=2e-3).plant.time_step() == 2e-3
    plain = build_cosim(plain_sc, plain_plan)
    assert plain.plant.time_step() == 1e-3
    assert plain.plant.get_discrete_contact_approximation() == DiscreteContactApproximation.kSap


def test_energy_time_plant_takes_the_section(tmp_path):
    sc, plan, plain_sc, plain_plan = _plans("ohsaka-fig2", tmp_path, plant={"time_step": 5e-4},
                                            simulator={"accuracy": 1e-5})
    cosim = build_cosim(sc, plan)
    assert cosim.plant.time_step() == 5e-4 and cosim.simulator_settings.given() == {"accuracy": 1e-5}
    assert build_cosim(plain_sc, plain_plan).plant.time_step() == 0.0  # continuous as before


def test_run_applies_the_simulator_fields_given_and_only_those():
    def cosim(settings):
        b = DiagramBuilder()
        src, integ = b.AddSystem(ConstantVectorSource(np.ones(1))), b.AddSystem(Integrator(1))
        b.Connect(src.get_output_port(), integ.get_input_port())
        return CoSim("toy", b.Build(), None, lambda sim: sim.Initialize(), lambda sim: sim.AdvanceTo(0.05),
                     lambda sim, wall: None, lambda r: {}, simulator_settings=settings)

    given = cosim(SimulatorSettings(integration_scheme="runge_kutta2", max_step_size=0.002, accuracy=0.001,
                                    use_error_control=False, target_realtime_rate=0.0, publish_every_time_step=True))
    run(given)
    cfg = ExtractSimulatorConfig(given.simulator)
    assert (cfg.integration_scheme, cfg.max_step_size, cfg.use_error_control, cfg.publish_every_time_step) == \
        ("runge_kutta2", 0.002, False, True)
    plain = cosim(NO_SIMULATION.simulator)
    run(plain)
    cfg = ExtractSimulatorConfig(plain.simulator)
    assert (cfg.integration_scheme, cfg.max_step_size) == ("runge_kutta3", 0.1)  # the Simulator as made


# ------------------------------------------------------------------------------------------- identity

def test_the_section_changes_no_plan_identity_and_no_fingerprint():
    sim = {"plant": {"time_step": 5e-4}, "simulator": {"accuracy": 1e-5}}
    for name, sections in (("thesis-ch4", transfer_sections), ("crane-tray", transfer_sections),
                           ("ur5-suction-bins", spatial_sections), ("ohsaka-fig2", energy_sections)):
        a, b = load_scenario(name), load_scenario(name, overrides={"simulation": sim})
        assert b.simulation.plant.time_step == 5e-4
        assert identity(sections(a)) == identity(sections(b)), name
    a, b = load_scenario("thesis-ch4"), load_scenario("thesis-ch4", overrides={"simulation": sim})
    assert a.fingerprint() == b.fingerprint()


def test_the_cli_runs_at_the_sections_step_and_time_step_ms_wins(tmp_path, capsys):
    path = scenario_yaml(tmp_path, simulation={"plant": {"time_step": 1.5e-3}})
    plan = _plan_file("thesis-ch4", tmp_path)  # made on the built-in scenario: accepted on the copy with the section
    steps = []
    for extra in ([], ["--time-step-ms", "1"]):
        out = tmp_path / f"run{len(steps)}.json"
        assert main(["simulate", path, "--plan", str(plan), "--json", str(out), "--quiet", *extra]) == 0
        steps.append(json.loads(out.read_text())["time_step_s"])
    assert steps == [1.5e-3, 1e-3]
    tray = scenario_yaml(tmp_path, _base="crane-tray", simulation={"plant": {"time_step": 2e-3}})
    assert main(["simulate", tray, "--method", "toppra", "--quiet"]) == 2  # refused before planning
    assert "simulation.plant.time_step 0.002 s: the tray co-simulation's plant step must not exceed" \
        in capsys.readouterr().err


def test_the_half_step_verdict_halves_the_step_the_run_used_not_the_kinds_default(monkeypatch):
    """--margin's 'verdict at half the step' is at half of the section's step (else it would re-run the same
    step and call the verdict step-independent)."""
    import qmt_drake.margin_runs as margin_runs

    steps = []

    def fake_spatial_run(sc, trajectory, **kw):
        def run(time_scale, time_step_s):
            steps.append(time_step_s)
            return {"outcome": "carried", "held": True, "margin": dict.fromkeys(("quantity", "value", "threshold",
                                                                                  "ratio"))}
        return run

    monkeypatch.setattr(margin_runs, "spatial_run", fake_spatial_run)
    sc = _with("ur5-suction-bins", plant={"time_step": 5e-4})
    half = margin_runs.spatial_half_step(sc, trajectory=None)
    assert (half["time_step_s"], half["half_step_s"], steps) == (5e-4, 2.5e-4, [2.5e-4])
    assert margin_runs.spatial_half_step(load_scenario("ur5-suction-bins"), None)["half_step_s"] == 5e-4


def test_the_transfer_searchs_half_step_is_half_the_sections_step(monkeypatch):
    import qmt_drake.margin_runs as margin_runs

    seen = []

    class Hand:
        replay_cost = type("Cost", (), {"default_step_s": 2e-3})

        def carried_check(self, sc, plan, *, feedforward, time_step_s):
            seen.append(time_step_s)
            return {"outcome": "carried", "max_slip_m": 0.0, "held": True}

    monkeypatch.setattr(margin_runs, "hand_plugin", lambda sc: Hand())
    r = margin_runs.search_half_step(_with("thesis-ch4", plant={"time_step": 1e-3}), plan=None)
    assert (r["time_step_s"], seen) == (1e-3, [5e-4])
    assert margin_runs.search_half_step(load_scenario("thesis-ch4"), plan=None)["half_step_s"] == 1e-3
