"""The code stays a map a newcomer can read: no import cycle among the project's modules (imports
inside functions included), no function of the add-on over 80 lines, and the engine never imports
Blender."""

from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
ADD_ON = ("grass_addon", "operators", "panels")
LONGEST = 80


def _modules() -> dict[str, Path]:
    """{dotted name relative to the repository root: path} of the extension's modules."""
    out = {}
    for folder in ADD_ON:
        for path in (REPO / folder).rglob("*.py"):
            parts = list(path.relative_to(REPO).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            out[".".join(parts)] = path
    out[""] = REPO / "__init__.py"
    return out


def _imports(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The project's modules that ``name`` imports anywhere in its file (relative imports)."""
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    if name == "":
        package = []
    found = set()
    tree = ast.parse(path.read_text())
    typing_only = {id(n) for block in ast.walk(tree) if isinstance(block, ast.If)
                   and isinstance(block.test, ast.Name) and block.test.id == "TYPE_CHECKING"
                   for stmt in block.body for n in ast.walk(stmt)}  # (annotations: never imported at run time)
    for node in ast.walk(tree):
        if not isinstance(node, ast.ImportFrom) or not node.level or id(node) in typing_only:
            continue
        base = package[: len(package) - (node.level - 1)] if node.level > 1 else package
        target = ".".join(base + ([node.module] if node.module else []))
        if target in modules:
            found.add(target)
        for alias in node.names:
            sub = f"{target}.{alias.name}" if target else alias.name
            if sub in modules:
                found.add(sub)
    found.discard(name)
    return found


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected groups of more than one module (Tarjan)."""
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
            group = []
            while True:
                w = stack.pop()
                on.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                out.append(sorted(group))

    for v in graph:
        if v not in index:
            visit(v)
    return out


def test_no_import_cycle_among_the_modules():
    modules = _modules()
    graph = {name: _imports(name, path, modules) for name, path in modules.items()}
    assert len(graph) > 40 and sum(map(len, graph.values())) > 80  # the walk sees the imports
    assert _cycles(graph) == []


def test_a_cycle_is_seen():
    """The cycle finder finds a cycle made on purpose (so an empty answer means something)."""
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == [["a", "b", "c"]]


def test_no_function_of_the_add_on_is_over_80_lines():
    long = []
    for path in _modules().values():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                if lines > LONGEST:
                    long.append(f"{path.relative_to(REPO)}:{node.lineno} {node.name} ({lines} lines)")
    assert not long, long


def test_the_engine_never_imports_blender():
    engine = [p for p in (REPO / "grass_addon").glob("*.py")]
    assert len(engine) > 20
    for path in engine:
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else []
            assert not any(n.split(".")[0] in ("bpy", "mathutils", "bmesh") for n in names), path


def _door_breaches(path: Path) -> list[str]:
    """The imports of a UI module (operators/, panels/) that reach the add-on's engine or bridge
    other than through ``grass_addon.bridge.runtime``."""
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if not isinstance(node, ast.ImportFrom) or node.level < 2:  # (level 1: its own folder)
            continue
        module, names = node.module or "", sorted(a.name for a in node.names)
        if module == "grass_addon.bridge.runtime" or (module == "grass_addon.bridge" and names == ["runtime"]):
            continue
        out.append(f"{path.name}:{node.lineno} from {'.' * node.level}{module} import {', '.join(names)}")
    return out


def test_the_ui_reaches_the_add_on_only_through_the_runtime():
    """runtime.py is the operators' and panels' one door: every name they use from the bridge and
    the engine is on its list."""
    ui = [p for folder in ("operators", "panels") for p in (REPO / folder).glob("*.py")]
    assert len(ui) > 15
    assert [b for p in ui for b in _door_breaches(p)] == []


def test_a_breach_of_the_door_is_seen(tmp_path):
    """An import of a bridge module beside the runtime, or of the engine, is named."""
    ui = tmp_path / "probe.py"
    ui.write_text("from ..grass_addon.bridge import properties, runtime\nfrom ..grass_addon import schema\n"
                  "from ._common import reported\nfrom ..grass_addon.bridge.runtime import schema as s\n")
    breaches = _door_breaches(ui)
    assert [b.split(" ", 1)[1] for b in breaches] == ["from ..grass_addon.bridge import properties, runtime",
                                                      "from ..grass_addon import schema"]


# What only a field's one live record holds: its error, the frame its objects show, its terrain and
# paint as sampled (issue #38: two records held them, refreshed by five flags set in four modules)
PER_FIELD = {"error", "frame", "terrain", "paint"}


def _frozen(node: ast.ClassDef) -> bool:
    return any(isinstance(d, ast.Call) and any(k.arg == "frozen" and getattr(k.value, "value", False)
                                               for k in d.keywords) for d in node.decorator_list)


def _records(folder: Path) -> dict[str, set[str]]:
    """{module.Class: the PER_FIELD names it declares} of the mutable classes under ``folder`` that
    declare any (a frozen dataclass is a value: ``resolve.Inputs``)."""
    out = {}
    for path in sorted(folder.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef) and not _frozen(node):
                names = {s.target.id for s in node.body if isinstance(s, ast.AnnAssign)
                         and isinstance(s.target, ast.Name)}
                if names & PER_FIELD:
                    out[f"{path.stem}.{node.name}"] = names & PER_FIELD
    return out


def _flags_set_outside(folder: Path, owner: str) -> list[str]:
    """Lines outside ``owner`` that raise a record's wait flag (``x.stale = True``, ...) instead of
    calling the record's method that says what happened."""
    out = []
    for path in sorted(folder.glob("*.py")):
        if path.name == owner:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Assign) and isinstance(node.value, ast.Constant) and node.value.value is True:
                out += [f"{path.name}:{node.lineno} .{t.attr}" for t in node.targets
                        if isinstance(t, ast.Attribute) and t.attr in {"stale", "moved", "stroked", "dirty", "motion"}]
    return out


def _live_fields() -> set[str]:
    """The names of ``registry.LiveField``'s fields."""
    tree = ast.parse((REPO / "grass_addon" / "bridge" / "registry.py").read_text())
    cls = next(n for n in ast.walk(tree) if isinstance(n, ast.ClassDef) and n.name == "LiveField")
    return {s.target.id for s in cls.body if isinstance(s, ast.AnnAssign) and isinstance(s.target, ast.Name)}


def _record_writes(folder: Path, owner: str, names: set[str]) -> list[str]:
    """Lines outside ``owner`` that write one of ``names`` (a record's fields) on anything but
    ``self``, a field's settings ``item`` or a Blender ``cache`` file (``live.frame = None``,
    ``rt.trail, x = ...``, ``s.strokes += 1``)."""
    out = []
    for path in sorted(folder.glob("*.py")):
        if path.name == owner:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            targets = node.targets if isinstance(node, ast.Assign) else \
                [node.target] if isinstance(node, (ast.AugAssign, ast.AnnAssign)) else []
            for target in targets:
                for t in (target.elts if isinstance(target, ast.Tuple) else [target]):
                    owner_name = t.value.id if isinstance(t, ast.Attribute) and isinstance(t.value, ast.Name) else ""
                    if isinstance(t, ast.Attribute) and t.attr in names and owner_name not in {"self", "item", "cache"}:
                        out.append(f"{path.name}:{node.lineno} .{t.attr}")
    return out


def test_each_field_lives_in_one_record_changed_by_its_methods():
    """The bridge keeps a field in one live record (``registry.LiveField``: its engine, what its
    objects show, its samples, its error, what waits), and the handlers, edits and operators say
    what happened through its methods (``edited``, ``stroke``, ``motion_edited``)."""
    assert _records(REPO / "grass_addon" / "bridge") == {"registry.LiveField": PER_FIELD}
    assert _flags_set_outside(REPO / "grass_addon" / "bridge", "registry.py") == []
    assert _flags_set_outside(REPO / "operators", "") == []
    names = _live_fields()
    for folder, owner in ((REPO / "grass_addon" / "bridge", "registry.py"), (REPO / "operators", ""),
                          (REPO / "panels", "")):
        assert _record_writes(folder, owner, names) == [], "a LiveField is changed only through its methods"


def test_a_second_record_and_a_raised_flag_are_seen(tmp_path):
    (tmp_path / "state.py").write_text("class FieldState:\n    error: str\n    terrain: tuple\n\n\n"
                                       "@dataclass(frozen=True)\nclass Inputs:\n    frame: int\n")
    (tmp_path / "edit.py").write_text("def edit(rt):\n    rt.dirty = True\n    rt.frame = None\n")
    assert _records(tmp_path) == {"state.FieldState": {"error", "terrain"}}
    assert _flags_set_outside(tmp_path, "state.py") == ["edit.py:2 .dirty"]
    assert _record_writes(tmp_path, "state.py", {"frame", "dirty"}) == ["edit.py:2 .dirty", "edit.py:3 .frame"]


def _untyped_settings(paths) -> list[str]:
    """Functions of ``paths`` with an argument ``params`` that carries no type."""
    found = []
    for path in paths:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                args = node.args.posonlyargs + node.args.args + node.args.kwonlyargs
                if any(a.arg == "params" and a.annotation is None for a in args):
                    found.append(f"{path.name}:{node.lineno} {node.name}")
    return found


def test_every_settings_argument_of_the_engine_and_bridge_is_typed():
    """mypy checks a read of a parameter (``params.wind.speed``, against params_typed.py) where the
    settings are typed: every argument called ``params`` in grass_addon is (issue #58: 106 were
    not, so their reads went unchecked). The decorators that pass any function's settings on
    (``edit_parts``) are the exception."""
    paths = [p for p in (REPO / "grass_addon").rglob("*.py") if p.name != "edit_parts.py"]
    assert not _untyped_settings(paths)


def test_an_untyped_settings_argument_is_seen(tmp_path):
    path = tmp_path / "module.py"
    path.write_text("def f(layout, params, n: int = 1):\n    return params.wind.speed\n")
    assert _untyped_settings([path]) == ["module.py:1 f"]


_ROLE_NAMES = {"BLADES", "CARDS", "ROLE_BLADES", "ROLE_CARDS"}


def _role_branches(paths) -> list[str]:
    """Where code outside ``roles.py`` tells the levels of detail apart by name: a comparison with
    one of them, or both listed side by side (a loop over two of them)."""
    found = []
    for path in paths:
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, (ast.Compare, ast.Tuple)):
                continue
            names = {n.id if isinstance(n, ast.Name) else n.attr for n in ast.walk(node)
                     if isinstance(n, (ast.Name, ast.Attribute))}
            if isinstance(node, ast.Compare) and names & _ROLE_NAMES:
                found.append(f"{path.name}:{node.lineno} compares a role by name")
            elif isinstance(node, ast.Tuple) and len(names & _ROLE_NAMES) >= 2:
                found.append(f"{path.name}:{node.lineno} lists the roles by name")
    return found


def test_the_levels_of_detail_are_described_once():
    """The blade strips and the cards are entries of ``roles.ROLES`` (which cells need each, its
    pool's reach, its quads, vertices, per-corner data, what rides on it): no other module of the
    add-on tells them apart by name (issue #58: a dozen places did), so a third level is one entry."""
    paths = [p for p in _modules().values() if p.name != "roles.py"]
    assert not _role_branches(paths)


def test_a_role_told_apart_by_name_is_seen(tmp_path):
    path = tmp_path / "module.py"
    path.write_text("def f(role, x):\n    if role == BLADES:\n        return x\n    for r in (owned.ROLE_BLADES, "
                    "owned.ROLE_CARDS):\n        pass\n")
    assert _role_branches([path]) == ["module.py:2 compares a role by name", "module.py:4 lists the roles by name"]


def test_a_slider_reaches_the_engine_through_three_modules():
    """Issue #58: a setting's edit goes properties -> edits -> resolve (the engine kept, retuned or
    made, then the frame written by frame_pass, which resolves nothing): ``edits`` calls
    ``resolve.update_field``, ``resolve`` holds the engine's ``GrassField``, ``frame_pass`` imports
    neither ``resolve`` nor ``edits``, and ``properties`` reaches the rest only by its hook."""
    modules = _modules()
    graph = {name: _imports(name, path, modules) for name, path in modules.items()}
    bridge = "grass_addon.bridge"
    assert f"{bridge}.resolve" in graph[f"{bridge}.edits"]
    assert "grass_addon.field" in graph[f"{bridge}.resolve"]
    assert not graph[f"{bridge}.frame_pass"] & {f"{bridge}.resolve", f"{bridge}.edits", "grass_addon.field"}
    assert not graph[f"{bridge}.properties"] & {f"{bridge}.edits", f"{bridge}.resolve", f"{bridge}.frame_pass"}
    edits = ast.parse(modules[f"{bridge}.edits"].read_text())
    taken = {alias.name for node in edits.body if isinstance(node, ast.ImportFrom) and node.module == "resolve"
             for alias in node.names}
    assert "update_field" in taken  # (the edits' one call: the engine brought to the settings, then written)
