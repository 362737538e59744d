"""The layers hold: read every module's imports (``ast``, nothing is imported) and check the
rules of the packages' layering: the product (``tactex_ros``) imports neither torch nor the lab;
the lab (``tactex_lab``) may import the product and has layers of its own. A violation names the
module, the line and the import."""

import ast
from pathlib import Path

import pytest

import tactex_lab
import tactex_ros

PKG = Path(tactex_ros.__file__).resolve().parent
LAB = Path(tactex_lab.__file__).resolve().parent
EXPERIMENTS = LAB / "experiments"
# shared helpers of the experiments; every other module there is one command
SHARED = {"__init__", "common", "runner", "trials", "curves", "protocol", "press_cache",
          "scenes"}


def _module(path: Path) -> str:
    rel = path.relative_to(PKG.parent).with_suffix("")
    parts = list(rel.parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path) -> list[tuple[int, str, list[str]]]:
    """(line, absolute module, imported names) of every import in a file, relative ones
    resolved against the file's package; names are [] for ``import x``."""
    tree = ast.parse(path.read_text(), str(path))
    package = _module(path) if path.name == "__init__.py" else _module(path).rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name, []) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                pkg = package.split(".")
                pkg = pkg[:len(pkg) - (node.level - 1)]
                base = ".".join(pkg + ([base] if base else []))
            out.append((node.lineno, base, [a.name for a in node.names]))
            # ``from package import module`` imports that module too: checked as such
            out += [(node.lineno, f"{base}.{a.name}", []) for a in node.names
                    if _is_module(f"{base}.{a.name}")]
    return out


def _is_module(name: str) -> bool:
    """Whether ``name`` (dotted) is a module or package of the product or the lab."""
    if name.split(".")[0] not in ("tactex_ros", "tactex_lab"):
        return False
    path = PKG.parent.joinpath(*name.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def _files(folder: Path = PKG) -> list[Path]:
    """The product's modules (or those under ``folder``)."""
    return sorted(p for p in folder.rglob("*.py") if "__pycache__" not in p.parts)


def _violations(files, bad, root: Path = PKG.parent) -> list[str]:
    return [f"{p.relative_to(root)}:{line}: {mod} {names or ''}"
            for p in files for line, mod, names in imports(p) if bad(p, mod, names)]


def test_the_import_reader_resolves_relative_imports():
    # a file inside the package: relative imports are resolved against its own package
    got = imports(PKG / "core" / "engine.py")
    mods = {m for _, m, _ in got}
    assert "tactex_ros.core.learners" in mods and "tactex_ros.core.touch" in mods
    got = imports(PKG / "cli" / "sim_commands.py")
    assert "tactex_ros.sources" in {m for _, m, _ in got}
    # ``from package import module`` counts as importing the module
    got = imports(LAB / "experiments" / "ladder.py")
    assert "tactex_lab.experiments.protocol" in {m for _, m, _ in got}
    assert (PKG / "core" / "__init__.py").is_file() and (LAB / "__init__.py").is_file()


# layer of a module = its first part below tactex_ros (top-level modules are their own layer);
# what each layer may import of the package (cli: everything, nothing imports cli)
ALLOWED = {
    "core": {"core"},
    "robot": {"core", "robot"},
    "sim": {"core", "robot", "sim"},   # core.paths: read_yaml only (test below)
    "sources": {"core", "robot", "sim", "sources"},
    "trial": {"core", "trial"},
    "ros": {"core", "robot", "sim", "sources", "trial", "ros"},
    "export": {"core", "robot", "sources", "trial", "export"},   # tactex export (open data)
}
PRODUCT_BELOW_CLI = set(ALLOWED) - {"cli"}

# the lab's layers (first part below tactex_lab): what each may import of the lab and of the
# product (the lab's cli: everything but ros, nothing of the lab imports it)
LAB_ALLOWED = {
    "cnn": ({"cnn"}, {"core"}),
    "analysis": ({"analysis"}, {"core", "robot", "sim", "sources"}),
    "experiments": ({"cnn", "analysis", "experiments"},
                    {"core", "robot", "sim", "sources", "trial"}),
    "env": ({"env"}, {"core", "sources"}),     # the benchmark environment (Gymnasium)
    "cli": ({"cnn", "analysis", "experiments", "env", "cli"}, PRODUCT_BELOW_CLI | {"cli"}),
}


def _layer(mod: str) -> str:
    parts = mod.split(".")
    return parts[1] if len(parts) > 1 else ""


def test_every_module_belongs_to_a_known_layer():
    layers = {_layer(_module(p)) for p in _files()} - {""}
    assert layers == set(ALLOWED) | {"cli"}
    assert {_layer(_module(p)) for p in _files(LAB)} - {""} == set(LAB_ALLOWED)


def _torch_or_lab(p, mod, names) -> bool:
    return mod.split(".")[0] in ("torch", "torchvision", "captum", "tactex_lab")


def test_the_product_imports_neither_torch_nor_the_lab():
    """The shipped method runs without torch; the lab plugs in through entry points
    (``core/plugins.py``), never by an import."""
    assert _violations(_files(), _torch_or_lab) == []


def test_the_product_rule_flags_torch_and_the_lab():
    found = _violations([LAB / "cnn" / "saliency.py", LAB / "cnn" / "learner.py"], _torch_or_lab)
    assert any(": torch" in v for v in found) and any(": tactex_lab.cnn" in v for v in found)


@pytest.mark.parametrize("layer", sorted(LAB_ALLOWED))
def test_lab_layer_imports_only_what_it_may(layer):
    files = [p for p in _files(LAB) if _layer(_module(p)) == layer]
    assert files
    lab_ok, product_ok = LAB_ALLOWED[layer]

    def bad(p, mod, names):
        if mod.startswith("tactex_lab."):
            return _layer(mod) not in lab_ok
        return mod.startswith("tactex_ros.") and _layer(mod) not in product_ok
    assert _violations(files, bad) == []


def test_lab_learners_need_no_ros_and_no_plotting():
    def bad(p, mod, names):
        return mod.split(".")[0] in ("rclpy", "matplotlib", "tactex")
    assert _violations(_files(LAB / "cnn"), bad) == []


@pytest.mark.parametrize("layer", sorted(ALLOWED))
def test_layer_imports_only_the_layers_below(layer):
    files = [p for p in _files() if _layer(_module(p)) == layer]
    assert files

    def bad(p, mod, names):
        return mod.startswith("tactex_ros.") and _layer(mod) not in ALLOWED[layer]
    assert _violations(files, bad) == []


def test_the_layer_rule_flags_an_import_from_above():
    def bad(p, mod, names):
        return mod.startswith("tactex_ros.") and _layer(mod) not in ALLOWED["robot"]
    found = _violations([PKG / "ros" / "nodes" / "motion_node.py"], bad)
    assert any(": tactex_ros.ros" in v for v in found), found


def test_core_imports_no_ros_and_no_plotting():
    def bad(p, mod, names):
        return mod.split(".")[0] in ("rclpy", "matplotlib")
    assert _violations(_files(PKG / "core"), bad) == []


def test_only_ros_imports_rclpy_or_messages():
    ros_tops = ("rclpy", "geometry_msgs", "sensor_msgs", "std_msgs", "std_srvs",
                "visualization_msgs", "action_msgs", "builtin_interfaces", "tactex")

    def bad(p, mod, names):
        return mod.split(".")[0] in ros_tops
    outside = [p for p in _files() + _files(LAB) if _layer(_module(p)) not in ("ros", "cli")
               or p.is_relative_to(LAB)]
    assert _violations(outside, bad) == []


def test_robot_domain_imports_no_torch():
    def bad(p, mod, names):
        return mod.split(".")[0] in ("torch", "rclpy")
    assert _violations(_files(PKG / "robot"), bad) == []


def test_sim_takes_its_paths_and_knows_no_ros():
    """The simulator reads files through the one YAML reader but finds none itself."""
    def bad(p, mod, names):
        return ((mod == "tactex_ros.core.paths" and set(names) != {"read_yaml"})
                or mod.split(".")[0] == "rclpy")
    assert _violations(_files(PKG / "sim"), bad) == []


def test_experiments_import_no_command_module_no_private_name_and_no_cli():
    commands = {f"tactex_lab.experiments.{p.stem}" for p in _files(EXPERIMENTS)
                if p.stem not in SHARED and p.parent == EXPERIMENTS}

    def bad(p, mod, names):
        own = _module(p)
        return (mod.startswith(("tactex_ros.cli", "tactex_lab.cli"))
                or mod.split(".")[0] == "rclpy"
                or (mod in commands and mod != own)
                or (mod.startswith(("tactex_ros", "tactex_lab"))
                    and any(n.startswith("_") for n in names)))
    assert _violations(_files(EXPERIMENTS), bad) == []


def test_one_chart_module_one_statistics_module_one_progress_display():
    def bad(p, mod, names):
        top = mod.split(".")[0]
        return ((top == "matplotlib" and p.name != "charts.py")
                or (mod == "scipy.stats" and p.name != "stats.py")
                # the experiments' progress bar; the graph's press / decision lines
                or (top == "rich" and p.name not in ("common.py", "progress.py")))
    assert _violations(_files() + _files(LAB), bad) == []


def test_no_module_imports_a_private_name_of_another_package():
    """``from x import _y`` across packages: private helpers stay in their package."""
    def bad(p, mod, names):
        pkg = _module(p).rpartition(".")[0]
        return (mod.startswith(("tactex_ros", "tactex_lab")) and mod.rpartition(".")[0] != pkg
                and mod != pkg and any(n.startswith("_") for n in names))
    assert _violations(_files() + _files(LAB), bad) == []


def test_no_machine_path_in_the_package():
    hits = [f"{p.relative_to(PKG.parent)}: {s.value}" for p in _files() + _files(LAB)
            for s in ast.walk(ast.parse(p.read_text()))
            if isinstance(s, ast.Constant) and isinstance(s.value, str)
            and s.value.startswith(("/work/", "/home/", "/root/", "/tmp/"))]
    assert hits == []


def test_no_module_uses_a_private_member_of_another_module():
    """``mod._helper`` where ``mod`` is an imported tactex module (e.g. ``real._run``)."""
    hits = []
    for p in _files() + _files(LAB):
        tree = ast.parse(p.read_text())
        modules = {}       # local name -> module it names
        for _, mod, names in imports(p):
            for n in names:
                modules[n] = f"{mod}.{n}"
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                for a in node.names:
                    modules[a.asname or a.name.split(".")[0]] = a.name
        own = _module(p)
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                    and node.attr.startswith("_") and not node.attr.startswith("__")):
                target = modules.get(node.value.id, "")
                if target.startswith(("tactex_ros", "tactex_lab")) and target != own \
                        and (PKG.parent / (target.replace(".", "/") + ".py")).is_file():
                    hits.append(f"{p.relative_to(PKG.parent)}:{node.lineno}: "
                                f"{node.value.id}.{node.attr}")
    assert hits == []


def _import_graph(files: list[Path]) -> dict[str, set[str]]:
    """module -> the package's modules it imports (anywhere in the file, lazy imports and
    ``TYPE_CHECKING`` blocks included; ``from pkg import mod`` counts as importing ``mod``)."""
    known = {_module(p) for p in files}

    def target(name: str) -> str | None:
        while name and name not in known:
            name = name.rpartition(".")[0]
        return name or None

    graph: dict[str, set[str]] = {}
    for p in files:
        own = _module(p)
        edges = set()
        for _, mod, names in imports(p):
            for t in [target(f"{mod}.{n}") for n in names] + [target(mod)]:
                if t and t != own and not own.startswith(t + "."):   # not its own package
                    edges.add(t)
        graph[own] = edges
    return graph


def _cycle(graph: dict[str, set[str]]) -> list[str]:
    """One import cycle of ``graph`` (modules in order, the first repeated), [] if none."""
    state: dict[str, int] = {}          # 1 on the current path, 2 done
    path: list[str] = []

    def visit(m: str) -> list[str]:
        state[m] = 1
        path.append(m)
        for n in sorted(graph.get(m, ())):
            if state.get(n) == 1:
                return path[path.index(n):] + [n]
            if n not in state and (found := visit(n)):
                return found
        state[m] = 2
        path.pop()
        return []

    for m in sorted(graph):
        if m not in state and (found := visit(m)):
            return found
    return []


def test_no_module_imports_back_a_module_that_imports_it():
    """The product's and the lab's imports form no cycle, lazy and type-only ones included
    (e.g. cli/main -> cli/robot -> cli/main; explorer_node <-> session_mode)."""
    assert _cycle(_import_graph(_files() + _files(LAB))) == []


def test_the_cycle_finder_finds_a_cycle():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set()}) == []


# where a run's settings enter and are validated, once: the command line (``cli/``), the one
# settings resolver (``ros/run_settings.py``, which the launch file, the command line and the
# explorer node call) and the launch file (outside the package); below it settings are frozen
# typed objects and nothing validates them again
EDGE = ("tactex_ros/cli/", "tactex_ros/ros/run_settings.py")


def _validate_calls(files: list[Path]) -> list[str]:
    """``validate(...)`` / ``x.validate(...)`` calls (a settings object checked again)."""
    hits = []
    for p in files:
        for node in ast.walk(ast.parse(p.read_text(), str(p))):
            if isinstance(node, ast.Call):
                f = node.func
                name = (f.id if isinstance(f, ast.Name) else
                        f.attr if isinstance(f, ast.Attribute) else "")
                if name == "validate":
                    hits.append(f"{p.name}:{node.lineno}")
    return hits


def test_no_validate_call_below_the_edge():
    below = [p for p in _files() + _files(LAB)
             if not str(p.relative_to(PKG.parent)).startswith(EDGE)]
    assert below and _validate_calls(below) == []


def test_the_validate_rule_flags_a_call(tmp_path):
    p = tmp_path / "learner.py"
    p.write_text("def make(cfg):\n    cfg = validate(cfg)\n    return schema.validate(cfg)\n")
    assert _validate_calls([p]) == ["learner.py:2", "learner.py:3"]
