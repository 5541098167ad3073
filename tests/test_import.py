"""`import qmt_drake` is light and has no side effect, and `qmt-drake --help` loads no Drake (issue 27
item 7): checked in fresh interpreters, since each is about what a new process loads."""

import json
import os
import subprocess
import sys

import pytest

from qmt_drake.apps import cli

PROBE = r"""
import ctypes, json, sys
libc = ctypes.CDLL("libc.so.6")
before = set(sys.modules)
{body}
print(json.dumps({{"pydrake": "pydrake" in sys.modules, "numpy": "numpy" in sys.modules,
                  "new": sorted(set(sys.modules) - before)}}))
"""


def _probe(body: str) -> dict:
    out = subprocess.run([sys.executable, "-c", PROBE.format(body=body)], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_import_qmt_drake_loads_no_submodule_and_no_pydrake():
    got = _probe("import qmt_drake")
    assert not got["pydrake"] and not got["numpy"]
    assert [m for m in got["new"] if m.startswith("qmt_drake.")] == []


def test_public_names_load_on_first_use():
    got = _probe("import qmt_drake\nassert callable(qmt_drake.load_scenario) and qmt_drake.Plan.__name__ == 'Plan'")
    assert got["pydrake"]
    with pytest.raises(AttributeError):
        __import__("qmt_drake").no_such_name  # noqa: B018


MALLOPT_PROBE = """
import ctypes
{setup}
libc = ctypes.CDLL("libc.so.6")
class MI(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks",
                                               "fsmblks", "uordblks", "fordblks", "keepcost")]
libc.mallinfo2.restype = MI
libc.malloc.restype = ctypes.c_void_p
h0 = libc.mallinfo2().hblkhd
p = libc.malloc(1 << 20)
print("MMAPPED", libc.mallinfo2().hblkhd - h0 >= 1 << 20)
libc.free(ctypes.c_void_p(p))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc only")
def test_import_qmt_drake_leaves_mallopt_alone():
    """glibc serves a 1 MiB block by mmap (counted in mallinfo2's hblkhd) while its mmap threshold is at
    its 128 kB start; malloc_tuning.tune() raises it to 32 MiB. After `import qmt_drake` the block is
    still mmapped: the import left mallopt alone; after tune() it is not (the probe sees a change)."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "QMT_DRAKE_MALLOC_TUNING")}
    seen = {}
    for setup in ("import qmt_drake", "import qmt_drake.malloc_tuning as m\nassert m.tune()"):
        out = subprocess.run([sys.executable, "-c", MALLOPT_PROBE.format(setup=setup)], capture_output=True,
                             text=True, check=True, env=env)
        seen[setup.split("\n")[0]] = out.stdout.strip()
    assert seen == {"import qmt_drake": "MMAPPED True", "import qmt_drake.malloc_tuning as m": "MMAPPED False"}


@pytest.mark.parametrize("argv", [["--help"], ["plan", "--help"], ["simulate", "--help"], ["bench", "--help"],
                                  ["benchmark", "--help"], ["reproduce", "--help"], ["scenarios", "--help"]])
def test_cli_help_loads_no_drake(argv):
    got = _probe(f"from qmt_drake.apps.cli import main\ntry:\n    main({argv!r})\nexcept SystemExit:\n    pass")
    assert not got["pydrake"] and not got["numpy"], argv


def test_cli_choices_agree_with_the_registries():
    from qmt_drake.apps import plan_command, spatial_cli
    from qmt_drake.planners import registry
    from qmt_drake.sim import EXPLICIT_MAX_TIME_STEP_S, FEEDFORWARD_OPTIONS
    from qmt_drake.sim.spatial_actuation import ACTUATORS
    assert cli.METHODS == registry.names(registry.TRANSFER) and cli.ENERGY_METHODS == registry.names(registry.ENERGY)
    assert cli.SPATIAL_METHODS == registry.names(registry.SPATIAL) == spatial_cli.SPATIAL_METHODS
    assert cli.SPATIAL_FAMILIES == spatial_cli.SPATIAL_FAMILIES and cli.SPATIAL_ACTUATORS == ACTUATORS
    assert set(cli.FEEDFORWARD_CHOICES) == set(FEEDFORWARD_OPTIONS)
    assert cli.EXPLICIT_MAX_TIME_STEP_MS * 1e-3 == EXPLICIT_MAX_TIME_STEP_S
    assert (cli.EXIT_INPUT, cli.EXIT_INFEASIBLE, cli.EXIT_SIMULATION, cli.EXIT_INTERRUPTED) == (
        plan_command.EXIT_INPUT, plan_command.EXIT_INFEASIBLE, plan_command.EXIT_SIMULATION, plan_command.EXIT_INTERRUPTED)


def test_every_command_resolves_and_says_what_its_module_says():
    import argparse
    for name, c in cli.COMMANDS.items():
        if c.add_parser is not None:  # the module's own subparser: the same help line
            sub = argparse.ArgumentParser().add_subparsers()
            cli._resolve(c.add_parser)(sub)
            assert sub.choices[name].get_default("func") is not None
            assert sub._choices_actions[0].help == c.help, name
        else:
            assert callable(cli._resolve(c.run)), name


def test_a_scenario_loaded_without_the_api_builds_its_arm():
    """The loader builds the arm by plain import (transfer_scenario -> builders), not because
    qmt_drake.api was imported."""
    got = _probe("from qmt_drake.transfer_scenario import load_scenario\n"
                 "assert load_scenario('thesis-ch4').arm is not None\n"
                 "assert 'qmt_drake.api' not in sys.modules")
    assert got["pydrake"]
