"""The package's layering, enforced: every import points down (or sideways where allowed).

The rule: a functional core (model, control, mission) of pure functions on arrays, each taking an optional leading
batch axis so that one vehicle and a swarm of particles run the same code, and around it a thin imperative shell
(MAVLink I/O, clocks, Rerun, the command line). Each folder is one layer; a layer imports only the layers below it
(MAY_IMPORT) and the foundation modules; only the command line (TOP) may import everything, and nothing imports
it; the core imports none of the shell's libraries (SHELL_LIBRARIES).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# Each layer and the layers it may import (besides itself and the foundation modules rov_mav.config/units).
MAY_IMPORT = {
    "rov_mav.model": set(),
    "rov_mav.control": {"rov_mav.model"},
    "rov_mav.mission": {"rov_mav.model", "rov_mav.control"},
    "rov_mav.offline": {"rov_mav.model", "rov_mav.control", "rov_mav.mission"},
    "rov_mav.flight": {"rov_mav.model", "rov_mav.control", "rov_mav.mission"},
    "sim_bridge": {"rov_mav.model"},
    "rov_mav.telemetry": {"rov_mav.model", "rov_mav.control", "rov_mav.mission", "rov_mav.offline",
                          "rov_mav.flight"},
    "rov_mav.review": {"rov_mav.model", "rov_mav.control", "rov_mav.mission", "rov_mav.offline", "rov_mav.flight",
                       "rov_mav.telemetry"},
}
FOUNDATION = {"rov_mav", "rov_mav.config", "rov_mav.units", "rov_mav.signing", "rov_mav.sitl", "rov_mav.shipped",
              "rov_mav.fault_items"}
# The top: the command line and one module per subcommand; it may import any layer, and no layer may import it.
TOP = ("rov_mav.cli", "rov_mav.commands")
# Libraries that belong to the shell: none of them may be imported below it.
SHELL_LIBRARIES = {"pymavlink", "rerun", "socket", "argparse", "select", "threading"}
CORE = ("rov_mav.model", "rov_mav.control", "rov_mav.mission")


def _modules():
    for path in sorted((ROOT / "rov_mav").rglob("*.py")) + sorted((ROOT / "sim_bridge").rglob("*.py")):
        name = ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
        yield name, path


def _imports(path: Path) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module)
            found |= {f"{node.module}.{alias.name}" for alias in node.names}
    return found


def _foundation(target: str) -> bool:
    return target == "rov_mav" or any(target == f or target.startswith(f + ".") for f in FOUNDATION - {"rov_mav"})


def _layer(module: str) -> str | None:
    return next((layer for layer in MAY_IMPORT if module == layer or module.startswith(layer + ".")), None)


def _top(module: str) -> bool:
    return any(module == t or module.startswith(t + ".") for t in TOP)


def _ours(target: str) -> bool:
    return target.split(".")[0] in ("rov_mav", "sim_bridge")


@pytest.mark.parametrize("module,path", list(_modules()), ids=lambda v: v if isinstance(v, str) else "")
def test_imports_point_down(module, path):
    """Every module has its place: the foundation imports only the foundation, a layer only what is below it, the
    top (cli, commands) anything; nothing but the top imports the top."""
    imports = {target for target in _imports(path) if _ours(target)}
    if _top(module):
        assert all(_top(t) or _foundation(t) or _layer(t) is not None for t in imports), f"{module}: {imports}"
        return
    assert not any(_top(t) for t in imports), f"{module} imports the command line: {imports}"
    if _foundation(module):
        assert all(_foundation(t) for t in imports), f"foundation module {module} imports a layer: {imports}"
        return
    layer = _layer(module)
    assert layer is not None, f"{module} belongs to no layer, the foundation or the top: give it its place"
    allowed = MAY_IMPORT[layer] | {layer}
    for target in _imports(path):
        top = target.split(".")[0]
        if _ours(target) and not _foundation(target):
            target_layer = _layer(target)
            assert target_layer in allowed, \
                f"{module} imports {target} ({target_layer}), above or beside its layer {layer}"
        if layer in CORE:
            assert top not in SHELL_LIBRARIES, f"{module} (core layer {layer}) imports the shell library {top}"


# The rooms of the two largest layers, from the bottom up: a module in a room imports only its own room and the
# rooms listed before it; a module at the package's root (the assembly) may import any of its rooms.
ROOMS = {
    "rov_mav.flight": ("record", "session", "state", "thrusters", "run"),
    "sim_bridge": ("hardware", "modes", "autopilot", "gcs", "navigation", "onboard_log", "transport"),
}


def _room(package: str, module: str) -> int | None:
    """The rank of `module`'s room in `package` (None: the package's root, or another package)."""
    if not module.startswith(package + "."):
        return None
    name = module[len(package) + 1:].split(".")[0]
    return ROOMS[package].index(name) if name in ROOMS[package] else None


@pytest.mark.parametrize("package", list(ROOMS))
def test_every_module_of_a_roomed_package_is_in_a_room_or_its_root_assembly(package):
    base = ROOT.joinpath(*package.split("."))
    stray = [p.name for p in base.iterdir() if p.is_dir() and (p / "__init__.py").exists()
             and p.name not in ROOMS[package]]
    assert not stray, f"{package}: sub-packages {stray} are in no room order (tests/test_layers.py ROOMS)"


@pytest.mark.parametrize("module,path", [(m, p) for m, p in _modules() if any(m.startswith(k + ".") for k in ROOMS)],
                         ids=lambda v: v if isinstance(v, str) else "")
def test_rooms_import_only_the_rooms_below_them(module, path):
    package = next(k for k in ROOMS if module.startswith(k + "."))
    rank = _room(package, module)
    if rank is None:
        return                                   # the root's assembly (sim_bridge.server, .process, .config)
    for target in _imports(path):
        if not target.startswith(package + "."):
            continue
        other = _room(package, target)
        assert other is not None, f"{module} ({ROOMS[package][rank]}) imports the package's assembly: {target}"
        assert other <= rank, \
            f"{module} ({ROOMS[package][rank]}) imports {target} ({ROOMS[package][other]}), a room above it"
