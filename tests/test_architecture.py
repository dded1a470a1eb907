"""The package's shape, checked on its source (issue: one closed loop for every arm).

* no import circle between modules, counting imports inside functions too
  (a lazy import is still a dependency: it only hides the circle from Python);
* no module imports a private name (``_x``) of another package;
* above ``model/`` and ``surface/`` nothing branches on the joint count or on a
  robot's or a shape's name: the robot declares its task and the surface
  answers for its shape.
"""

from __future__ import annotations

import ast
import pathlib
import re


ROOT = pathlib.Path(__file__).resolve().parents[1] / "tmtcontrol"


def _modules() -> dict[str, pathlib.Path]:
    out = {}
    for f in ROOT.rglob("*.py"):
        parts = list(f.relative_to(ROOT.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = f
    return out


MODULES = _modules()


def _resolve(module: str, node: ast.ImportFrom, is_pkg: bool) -> str:
    if node.level == 0:
        return node.module or ""
    base = module.split(".") if is_pkg else module.split(".")[:-1]
    base = base[:len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def imports_of(module: str) -> list[tuple[str, str]]:
    """``(imported module, name)`` for every import in ``module`` (names: '' for a plain import)."""
    path = MODULES[module]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(a.name, "") for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            target = _resolve(module, node, path.name == "__init__.py")
            for a in node.names:
                sub = f"{target}.{a.name}"
                out.append((sub, "") if sub in MODULES else (target, a.name))
    return [(m, n) for m, n in out if m.split(".")[0] == "tmtcontrol"]


def _graph() -> dict[str, set[str]]:
    g = {m: set() for m in MODULES}
    for m in MODULES:
        for target, _ in imports_of(m):
            while target not in MODULES and "." in target:
                target = target.rsplit(".", 1)[0]
            if target in MODULES and target != m and not m.startswith(target + ".") and target != "tmtcontrol":
                g[m].add(target)
    return g


def import_circles(graph) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
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

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_circle_finder_finds_a_planted_circle():
    """The checker itself: a -> b -> c -> a is one circle, d alone none."""
    assert import_circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert import_circles({"a": {"b"}, "b": set()}) == []


def test_no_import_circles():
    assert import_circles(_graph()) == []


def _package(module: str) -> str:
    parts = module.split(".")
    return ".".join(parts[:2]) if len(parts) > 1 else parts[0]


def test_no_private_name_is_imported_from_another_package():
    bad = [(m, t, n) for m in MODULES for t, n in imports_of(m)
           if n.startswith("_") and not n.startswith("__") and _package(t) != _package(m)]
    assert bad == []


BRANCH = re.compile(r"""(\.n\s*(<|<=|>|>=|==|!=)\s*\d)|(["']puma560["'])|"""
                    r"""(\bn_joints\s*(<|>|==))|(["'](plane|sphere|cylinder|heightmap)["']\s*(==|!=|in))|"""
                    r"""((==|!=)\s*["'](plane|sphere|cylinder|heightmap)["'])""")
"""What a branch on the joint count, a robot's name or a shape's name looks like."""

ALLOWED = {"tmtcontrol/simulation/scenario/robot.py", "tmtcontrol/simulation/scenario/builtin.py",
           "tmtcontrol/cli.py"}
"""Data, not branches: the scenario's default ``robot.model = "puma560"`` and its built-in
scenarios, and the command line's help text naming the bundled arms. (The whole scenario
package was allowed, which hid its one branch on the arm's name: the PUMA refused
``environment.normal``.)"""

SHAPE_SETTINGS = "tmtcontrol/simulation/scenario"
"""The scenario's settings declare which keys each shape takes (a sphere's radius, a
cylinder's axis) and validate them: a shape's name there is its schema, so only a
branch on a shape's name is allowed in this package."""

SHAPE = re.compile(r"""(["'](plane|sphere|cylinder|heightmap)["']\s*(==|!=|in))|"""
                   r"""((==|!=)\s*["'](plane|sphere|cylinder|heightmap)["'])""")


def test_the_branch_pattern_sees_the_branches_it_is_for():
    for line in ('if robot.n < 6:', 'if sc.robot.model.lower() == "puma560":', 'if self.plant.n > 6 else',
                 'if kind == "sphere":'):
        assert BRANCH.search(line), line
    for line in ('if task.rotational:', 'n = robot.n', 'if n < 4 or not np.any(x):', 'for i in range(n):'):
        assert not BRANCH.search(line), line


def test_no_branch_on_the_joint_count_or_a_name_above_model_and_surface():
    hits = []
    for m, f in MODULES.items():
        rel = f.relative_to(ROOT.parent).as_posix()
        if rel.startswith(("tmtcontrol/model/", "tmtcontrol/surface/")) or any(
                rel == a or rel.startswith(a + "/") for a in ALLOWED):
            continue
        for i, line in enumerate(f.read_text(encoding="utf-8").splitlines(), 1):
            code = line.split("#", 1)[0]
            if rel.startswith(SHAPE_SETTINGS + "/"):
                code = SHAPE.sub("", code)
            if BRANCH.search(code) and not code.lstrip().startswith(('"', "'")):
                hits.append(f"{rel}:{i}: {line.strip()}")
    assert hits == []


LAYERS = ("model", "surface", "control", "simulation", "stability", "checks", "export", "sweep", "report", "cli")
"""The data path (docs/architecture.md): a package imports only earlier layers
(and the utilities: cache, processes, files, fmt, settings, plotstyle, drawing, the
package root)."""


def test_packages_import_only_earlier_layers_of_the_data_path():
    bad = []
    for module in MODULES:
        layer = module.split(".")[1] if "." in module else None
        if layer not in LAYERS:
            continue
        for target, _ in imports_of(module):
            other = target.split(".")[1] if "." in target else None
            if other in LAYERS and LAYERS.index(other) > LAYERS.index(layer):
                bad.append(f"{module} imports {target}")
    assert not bad, bad
