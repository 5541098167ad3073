"""One co-simulation build path (qmt_drake/sim/cosim.py): every kind is built by build_cosim and run by the one
run, which is the only place in the package that makes a Drake Simulator (counted from the code); a spatial
scenario's diagram composes in user code (api.build_diagram) and gives run()'s arm motion."""

import ast
import dataclasses
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import Gain, LogVectorOutput

import qmt_drake.api as api
from qmt_drake import build_diagram, load_scenario, plan_with, simulate
from qmt_drake.errors import QmtInputError
from qmt_drake.outcome import OUTCOMES
from qmt_drake.sim import cosim_run
from qmt_drake.sim.cosim import CoSim, build_cosim, run
from tests.spatial_fixtures import load_or_skip

PKG = Path(__file__).resolve().parents[1] / "qmt_drake"


def _calls(name: str) -> list[str]:
    """'path:line' of every call of `name` (a plain name or an attribute) in the package's code."""
    found = []
    for p in sorted(PKG.rglob("*.py")):
        text = p.read_text()
        if name + "(" not in text:  # (a call written otherwise, getattr say, is not looked for)
            continue
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.Call):
                f = node.func
                if (isinstance(f, ast.Name) and f.id == name) or (isinstance(f, ast.Attribute) and f.attr == name):
                    found.append(f"{p.relative_to(PKG.parent).as_posix()}:{node.lineno}")
    return found


def test_one_simulator_construction_and_one_urdf_parse_in_the_code():
    assert [s.split(":")[0] for s in _calls("Simulator")] == ["qmt_drake/sim/cosim_run.py"]
    assert [s.split(":")[0] for s in _calls("Parser")] == ["qmt_drake/model/arm.py"]


class _Reached(Exception):
    pass


def _stop_at_the_simulator(monkeypatch, seen: list):
    """The one Simulator replaced by a stop that records the CoSim's kind: a path that reaches it went
    through build_cosim's CoSim and run (no simulation is paid for)."""
    real_run = cosim_run.run

    def spy(cosim):
        seen.append(cosim.kind)
        return real_run(cosim)

    def stop(diagram):
        raise _Reached
    monkeypatch.setattr(cosim_run, "Simulator", stop)
    for mod in ("qmt_drake.sim.cosim", "qmt_drake.api"):
        monkeypatch.setattr(f"{mod}.run", spy)


@pytest.mark.parametrize("name,method,kind", [("thesis-ch4", "thesis", "magnet"), ("crane-tray", "thesis", "tray"),
                                              ("ohsaka-fig2", "snopt", "energy_time")])
def test_simulate_of_every_planar_and_energy_kind_goes_through_build_cosim_and_run(monkeypatch, name, method, kind):
    sc = load_scenario(name)
    plan = plan_with(method, sc)
    seen = []
    _stop_at_the_simulator(monkeypatch, seen)
    with pytest.raises(_Reached):
        simulate(sc, plan)
    assert seen == [kind]


class _RestThenMove:
    """Rest at q0 for rest_s, then a quintic rest-to-rest move by dq [rad] in move_s (a spatial trajectory)."""

    def __init__(self, q0, dq, rest_s: float = 0.05, move_s: float = 0.3) -> None:
        self.q0, self.dq, self.rest_s, self.move_s = np.asarray(q0, float), np.asarray(dq, float), rest_s, move_s
        self.duration_s = rest_s + move_s

    def sample(self, t):
        s = np.clip((np.atleast_1d(np.asarray(t, float)) - self.rest_s) / self.move_s, 0.0, 1.0)[:, None]
        p, v, a = 10 * s**3 - 15 * s**4 + 6 * s**5, (30 * s**2 - 60 * s**3 + 30 * s**4) / self.move_s, \
            (60 * s - 180 * s**2 + 120 * s**3) / self.move_s**2
        return self.q0 + p * self.dq, v * self.dq, a * self.dq


def _short_plan(sc):
    return SimpleNamespace(trajectory=_RestThenMove(sc.q_poses_rad[0], np.full(sc.n_dof, 0.005), move_s=0.4))


@pytest.mark.parametrize("name,physics,kind", [
    ("ur5-magnet-part", "weld", "spatial_weld"),
    ("ur5-suction-bins", "contact", "spatial_contact"),
    ("panda-tray-cup", "weld", "spatial_tray"),  # (a tray's cup stands free whatever hand.physics says)
])
def test_every_spatial_hand_is_built_by_build_cosim_and_run_by_run(name, physics, kind):
    sc = dataclasses.replace(load_or_skip(name), hand_physics=physics)
    cosim = build_cosim(sc, _short_plan(sc))
    assert isinstance(cosim, CoSim) and cosim.kind == kind
    assert {"desired_state", "arm_state", "body_poses"} <= set(cosim.ports)
    summary = run(cosim)
    assert summary["outcome"] in OUTCOMES and summary["held"] == (summary["outcome"] == "carried")
    assert summary["outcome"] == "carried", summary  # a slow 5 mrad move keeps the part
    assert cosim.simulator is not None and math.isfinite(summary["final_goal_error_rad"])
    with pytest.raises(RuntimeError, match="has run already"):
        run(cosim)


def test_the_spatial_time_step_is_an_option_and_refused_out_of_range():
    sc = load_or_skip("ur5-magnet-part")
    a = run(build_cosim(sc, _short_plan(sc), time_step_s=2e-3))
    assert a["outcome"] == "carried" and a["final_goal_error_rad"] < 1e-3
    with pytest.raises(QmtInputError, match="plant step"):
        build_cosim(sc, _short_plan(sc), time_step_s=0.02)


@pytest.fixture(scope="module")
def suction():
    sc = load_or_skip("ur5-suction-bins")
    return sc, plan_with("toppra", sc)


def test_simulate_of_a_spatial_plan_takes_the_plant_step(suction):
    sc, plan = suction
    # (at time scale 1 this TOPP-RA plan is at the cup's limit, ratio 0.995 at 1 ms: a 2 ms step's coarser
    # acceleration takes it over 1; 10 % slower, 0.912 at 1 ms, 0.941 at 2 ms, 0.908 at 0.5 ms)
    at_1ms, at_2ms = (simulate(sc, plan, time_scale=1.1, time_step_s=h) for h in (None, 2e-3))
    assert at_1ms["outcome"] == at_2ms["outcome"] == "carried" and at_2ms["final_goal_error_rad"] < 1e-3
    assert 0.0 < abs(at_2ms["max_grip_ratio_while_held"] - at_1ms["max_grip_ratio_while_held"]) < 0.05
    with pytest.raises(QmtInputError, match="plant step"):
        simulate(sc, plan, time_step_s=0.02)


def test_a_spatial_diagram_composes_in_user_code_and_moves_the_arm_as_run_does(suction):
    sc, plan = suction
    ref = build_cosim(sc, plan)
    lib = run(ref)
    assert lib["outcome"] == "carried"
    # --- user code: the library's diagram as one block of the user's own diagram, a user system on its port
    cosim = build_diagram(sc, plan)
    builder = DiagramBuilder()
    block = builder.AddSystem(cosim.diagram)
    n = sc.n_dof
    double = builder.AddSystem(Gain(2.0, 2 * n))  # the user's own system, fed by the exported arm state
    builder.Connect(block.GetOutputPort("arm_state"), double.get_input_port())
    log = LogVectorOutput(double.get_output_port(), builder, 1e-2)
    sim = Simulator(builder.Build())
    sim.AdvanceTo(cosim.t_final_s)
    mine = log.FindLog(sim.get_context()).data()[:n, -1] / 2.0
    # --- the same arm motion as run's (the weld held in both: carried)
    assert np.max(np.abs(cosim.q_goal - mine)) == pytest.approx(lib["final_goal_error_rad"], abs=1e-9)
    desired0 = log.FindLog(sim.get_context()).data()[:n, 0] / 2.0
    np.testing.assert_allclose(desired0, plan.trajectory.sample([0.0])[0][0], atol=1e-9)  # starts at the plan's start


def test_build_diagram_of_a_spatial_scenario_refuses_what_it_cannot_take():
    sc = load_or_skip("ur5-magnet-part")
    plan = plan_with("toppra", sc)
    with pytest.raises(QmtInputError, match="coil_current_A"):
        api.build_diagram(sc, plan, coil_current_A=1.0)
    with pytest.raises(QmtInputError, match="feedforward"):
        api.build_diagram(sc, plan, feedforward="none")  # the ideal drive's controller always has it


def test_build_diagram_then_run_gives_simulates_summary_on_a_planar_arm():
    sc = load_scenario("thesis-ch4")
    plan = plan_with("thesis", sc)
    lib = simulate(sc, plan)
    cosim = build_diagram(sc, plan, step_logs=True)  # the 5 ms loggers only observe
    mine = run(cosim)
    assert cosim.kind == "magnet" and mine["outcome"] == lib["outcome"] == "carried"
    for key in ("max_slip_m", "max_tilt_rad", "final_goal_error_rad", "max_tracking_error_rad", "energy_J"):
        assert mine[key] == lib[key], key
