"""Registries that say no (issue 30, item 3): every register_* refuses an existing name in one line
naming it and the fix (replace=True), and checks a plug-in's callables when it is registered, not at
first use."""

from dataclasses import replace

import pytest

from qmt_drake.actuators import ActuatorPlugin, register_actuator
from qmt_drake.config.registry import ACTUATORS, FAMILIES, HANDS, OBJECTIVES, FamilyPlugin, ObjectivePlugin
from qmt_drake.errors import QmtInputError
from qmt_drake.hands import register_hand
from qmt_drake.plan_files import PLAN_KINDS, register_plan_kind
from qmt_drake.planners import PLANNERS, plan_with, register_planner, unregister_planner
from qmt_drake.transfer_scenario import load_scenario


def _refused(call, *needles) -> str:
    with pytest.raises(QmtInputError) as exc:
        call()
    msg = str(exc.value)
    assert "\n" not in msg and all(n in msg for n in needles), msg
    return msg


def test_a_built_in_planner_is_not_replaced_silently():
    thesis = PLANNERS["thesis"]
    msg = _refused(lambda: register_planner("thesis", lambda sc, *, seed=0, progress=None: None),
                   "planner 'thesis' is already registered", "replace=True")
    assert msg == ("planner 'thesis' is already registered; pass replace=True to replace it, or register "
                   "under another name")
    assert PLANNERS["thesis"] is thesis


def test_replace_true_swaps_a_planner_and_a_new_name_registers():
    thesis = PLANNERS["thesis"]
    mine = lambda sc, *, seed=0, progress=None, **options: ("mine", seed, options)  # noqa: E731
    try:
        register_planner("thesis", mine, replace=True)
        sc = load_scenario("thesis-ch4")  # the registry dispatches on the scenario's kind
        assert plan_with("thesis", sc, seed=3) == ("mine", 3, {})
        register_planner("mine", mine)
        assert plan_with("mine", sc, k=1) == ("mine", 0, {"k": 1})
    finally:
        register_planner("thesis", thesis, replace=True)
        unregister_planner("mine")
    assert PLANNERS["thesis"] is thesis and "mine" not in PLANNERS


@pytest.mark.parametrize("name, planner, needle", [
    ("mine", lambda sc: None, "cannot be called as planner(scenario, *, seed, progress, **options)"),
    ("mine", lambda: None, "cannot be called as planner"),
    ("mine", "not a function", "is not callable"),
    ("", lambda sc, **kw: None, "the name must be a non-empty string"),
    (None, lambda sc, **kw: None, "the name must be a non-empty string"),
])
def test_a_planner_is_checked_when_registered(name, planner, needle):
    _refused(lambda: register_planner(name, planner), needle)
    assert "mine" not in PLANNERS


def test_replace_must_be_a_bool():
    _refused(lambda: register_planner("thesis", lambda sc, **kw: None, replace="yes"),
             "replace must be True or False")


def test_hand_and_actuator_kinds_twice_name_the_fix():
    _refused(lambda: register_hand(HANDS["magnet"]), "hand.kind 'magnet' is already registered", "replace=True")
    _refused(lambda: register_actuator(ACTUATORS["ideal"]), "actuator.kind 'ideal' is already registered",
             "replace=True")
    _refused(lambda: FAMILIES.register(FAMILIES["via_cubic"]), "family.kind 'via_cubic' is already registered")
    _refused(lambda: OBJECTIVES.register(OBJECTIVES["min_time"]), "objective.kind 'min_time' is already registered")


def test_replace_true_re_registers_a_hand():
    magnet = HANDS["magnet"]
    register_hand(magnet, replace=True)
    assert HANDS["magnet"] is magnet


def test_plug_ins_are_checked_for_their_callables_when_registered():
    _refused(lambda: register_hand(replace(HANDS["magnet"], kind="broken", simulate=None)),
             "hand.kind 'broken': simulate must be a callable", "HandPlugin's docstring")
    _refused(lambda: register_hand(replace(HANDS["magnet"], kind="broken", check_payload="no")),
             "hand.kind 'broken': check_payload must be a callable")
    _refused(lambda: register_actuator(ActuatorPlugin(kind="broken", parse=42)),
             "actuator.kind 'broken': parse must be a callable")
    _refused(lambda: FAMILIES.register(FamilyPlugin("broken", make=None)), "family.kind 'broken': make must be")
    _refused(lambda: OBJECTIVES.register(ObjectivePlugin("broken", make=len, scenario_kind=None)),
             "scenario_kind None must name a scenario kind")
    _refused(lambda: register_hand("magnet"), "register_hand needs a HandPlugin, got str")
    _refused(lambda: register_actuator(object()), "register_actuator needs an ActuatorPlugin")
    assert all("broken" not in reg for reg in (HANDS, ACTUATORS, FAMILIES, OBJECTIVES))
    # an optional callable may be None: the magnet's copy without a payload check registers
    ok = replace(HANDS["magnet"], kind="magnet_no_check", check_payload=None)
    try:
        register_hand(ok)
        assert HANDS["magnet_no_check"] is ok
    finally:
        HANDS.unregister("magnet_no_check")


def test_plan_kinds_register_once():
    _refused(lambda: register_plan_kind("transfer", object, lambda p, d, s: None),
             "plan kind 'transfer' is already registered", "replace=True")
    _refused(lambda: register_plan_kind("other", "Scenario", lambda p, d, s: None), "give the scenario's class")
    assert "other" not in PLAN_KINDS


@pytest.mark.parametrize("kind", ["transfer", "spatial_transfer", "energy_time"])
def test_every_function_of_a_kinds_view_takes_the_scenario_alone(kind):
    """registry.functions(kind)[name](scenario) is a whole call for every row: a row that shares its
    function with others (the energy-time solvers, told which by `method`) gets its name bound, so
    spatial_methods.plan_all over every spatial row does not stop on a missing keyword."""
    import inspect

    from qmt_drake.planners import registry

    view = registry.functions(kind)
    assert len(view) > 0
    for name in view:
        sig = inspect.signature(view[name])
        required = [p for p in sig.parameters.values() if p.default is p.empty
                    and p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD)]
        assert len(required) == 1, (name, [p.name for p in required])
