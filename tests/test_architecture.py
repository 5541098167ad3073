"""The house: no import circle, the scenario a leaf, no qmt_drake import hidden inside a function,
and modules of one job (size)."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "qmt_drake"


def _modules() -> dict[str, Path]:
    mods = {}
    for p in PKG.rglob("*.py"):
        name = ".".join(p.relative_to(ROOT).with_suffix("").parts)
        mods[name.removesuffix(".__init__")] = p
    return mods


def _imports(mods):
    """(module -> set of qmt_drake modules it imports at import time, including the packages whose
    __init__ runs on the way; [(module, line) of qmt_drake imports inside functions])."""
    def resolve(n):
        while n and n not in mods:
            n = n.rpartition(".")[0]
        return n
    edges, inner = {}, []
    for name, path in mods.items():
        edges[name] = set()

        def visit(node, in_function):
            for ch in ast.iter_child_nodes(node):
                if isinstance(ch, (ast.Import, ast.ImportFrom)):
                    targets = ([a.name for a in ch.names] if isinstance(ch, ast.Import)
                               else [ch.module] + [f"{ch.module}.{a.name}" for a in ch.names] if ch.module else [])
                    for t in (t for t in targets if t.startswith("qmt_drake")):
                        r = resolve(t)
                        if in_function:
                            inner.append((name, ch.lineno))
                        elif r and r != name:
                            parts = r.split(".")
                            for k in range(2, len(parts) + 1):
                                anc = ".".join(parts[:k])
                                if anc in mods and anc != name and not name.startswith(anc + "."):
                                    edges[name].add(anc)
                visit(ch, in_function or isinstance(ch, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)))
        visit(ast.parse(path.read_text()), False)
    return edges, inner


def _cycles(edges):
    index, low, stack, on, out = {}, {}, [], set(), []

    def strong(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))
    for v in edges:
        if v not in index:
            strong(v)
    return out


def test_no_import_circle_and_no_qmt_drake_import_inside_a_function():
    edges, inner = _imports(_modules())
    assert _cycles(edges) == []
    assert inner == [], "import these at the module's top (an import inside a function hides a circle)"


# the only packages imported inside functions, each lazy for a stated reason: toppra loads
# matplotlib.pyplot (about 0.2 s at every CLI start), matplotlib only draws figures, Dask (with asyncio
# for its event loop) only runs sweeps
LAZY_PACKAGES = {"toppra", "matplotlib", "dask", "distributed", "asyncio"}


def test_no_other_import_inside_a_function():
    found = []
    for name, path in _modules().items():
        for fn in ast.walk(ast.parse(path.read_text())):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for node in ast.walk(fn):
                mods = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                        [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else [])
                found += [(name, node.lineno, m) for m in mods if m.split(".")[0] not in LAZY_PACKAGES]
    assert found == [], "import these at the module's top: " + repr(found)


def test_the_scenario_imports_nothing_above_config():
    edges, _ = _imports(_modules())
    allowed = {"qmt_drake", "qmt_drake.errors", "qmt_drake.catalog"}  # and config/'s own modules
    for name in (n for n in edges if n.startswith("qmt_drake.config")):
        above = {t for t in edges[name] if t != "qmt_drake.config" and not t.startswith("qmt_drake.config.")}
        assert above <= allowed, (name, above - allowed)
    assert edges["qmt_drake.catalog"] <= {"qmt_drake.errors"}


def test_seed_packages_do_not_import_each_other():
    edges, _ = _imports(_modules())
    seeds = ("energy", "tray", "design")
    for name, targets in edges.items():
        mine = name.split(".")[1] if name.count(".") else ""
        for t in targets:
            theirs = t.split(".")[1] if t.count(".") else ""
            if mine in seeds and theirs in seeds:
                assert mine == theirs, f"{name} imports {t}: seed packages plug into the core only"


def test_the_core_does_not_import_the_seed_packages():
    """Seed packages plug into the core (hands.py registers them), never the other way round: only the
    plug-in registry and the applications above it may import energy/, tray/ or design/."""
    edges, _ = _imports(_modules())
    seeds = ("energy", "tray", "design")
    above = ("apps", "api", "hands", "builders", "sweep", "budgets", "scenario_data") + seeds
    for name, targets in edges.items():
        part = name.split(".")[1] if name.count(".") else ""
        if part in above:
            continue
        for t in targets:
            theirs = t.split(".")[1] if t.count(".") else ""
            assert theirs not in seeds, f"{name} (core) imports {t} (a seed package)"


MAX_MODULE_LINES = 450
# Modules allowed to stay bigger ({path: their own bound}), each with why; none today. Split a module
# by its jobs rather than add it here.
BIG_MODULES: dict[str, int] = {}


def test_modules_stay_small():
    """One job per module: every module under qmt_drake/ and studies/ below MAX_MODULE_LINES lines,
    except the allow-listed ones (which may not grow past their own bound)."""
    too_big = []
    for p in sorted([*PKG.rglob("*.py"), *(ROOT / "studies").rglob("*.py")]):
        rel = p.relative_to(ROOT).as_posix()
        n = len(p.read_text(encoding="utf-8").splitlines())
        if n >= BIG_MODULES.get(rel, MAX_MODULE_LINES):
            too_big.append(f"{rel}: {n} lines")
    assert too_big == [], "split these into modules of one job each: " + "; ".join(too_big)
    stale = [m for m in BIG_MODULES if not (ROOT / m).is_file()
             or len((ROOT / m).read_text(encoding="utf-8").splitlines()) < MAX_MODULE_LINES]
    assert stale == [], f"drop from BIG_MODULES (gone or small now): {stale}"


def test_no_hand_kind_branch_outside_the_hand_plug_ins():
    """Code asks the hand's plug-in (hands.HandPlugin) instead of branching on the hand kind: no
    `is_tray` and no TrayHand outside the tray plug-in (hands.py, tray/) and the scenario's own
    section types and parsers (config/)."""
    allowed = ("qmt_drake/hands.py", "qmt_drake/tray/")
    typed = allowed + ("qmt_drake/config/",)
    found = []
    for p in sorted([*PKG.rglob("*.py"), *(ROOT / "studies").rglob("*.py")]):
        rel, text = p.relative_to(ROOT).as_posix(), p.read_text(encoding="utf-8")
        if "is_tray" in text and not rel.startswith(allowed):
            found.append(f"{rel}: is_tray")
        if "TrayHand" in text and not rel.startswith(typed):
            found.append(f"{rel}: TrayHand")
    assert found == [], "ask the hand plug-in (hands.hand_plugin(scenario)) instead: " + "; ".join(found)
