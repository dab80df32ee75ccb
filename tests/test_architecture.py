"""The house's import rules (docs/architecture.md), read from the source: no import circle
between the project's modules, the pipeline imports no simulator, robot or calibration code, the
simulator takes from the pipeline only what cannot let their errors cancel, the robots' rooms do
not import each other, and no module (nor script of docs/ or tests/tools/) imports another
module's private name. Function-level (lazy) imports count like top-level ones."""

import ast
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: the repository's package folders and the import name each installs under (pyproject.toml's
#: package-dir): one installed name, stcvision, whose rooms keep their folders at the top
FOLDERS = {
    "stcvision": "stcvision",
    "sim_camera": "stcvision.sim_camera",
    "controllers": "stcvision.controllers",
    "calibration": "stcvision.calibration",
}
#: the ground floor: what every layer may import, and which imports nothing of the project above it
GROUND = {"stcvision.errors", "stcvision.fileio", "stcvision.limits", "stcvision.angles", "stcvision.stc_geometry"}
#: the roof: the command line, and the two entry points that drive it (``python -m stcvision``,
#: the numba warm-up that runs the CLI's commands once)
ROOF = ("stcvision.cli", "stcvision.__main__", "stcvision.warm")
#: what the simulator may take from stcvision: errors, file helpers, caps, angle wrapping, and
#: the default sub-cell side; never the mirror model, the stages or the STC geometry's rules
SIM_MAY_IMPORT = {
    "stcvision.errors": None,
    "stcvision.fileio": None,
    "stcvision.limits": None,
    "stcvision.angles": None,
    "stcvision.stc_geometry": {"DEFAULT_SUBCELL_M"},
}


#: the datasets' owner sits above the simulator and the calibration workflow: it renders frames
#: with the one and fits their profiles with the other, and a recipe's scene parameters are the
#: simulator's scene function's; reading a dataset (stcvision.datasets.reading) imports neither
DATASETS_MAY_IMPORT = {
    "stcvision.datasets.render": ("sim_camera", "calibration"),
    "stcvision.datasets.recipe": ("sim_camera",),
}


def _module_name(path: Path) -> str:
    """The installed name of a module file of one of :data:`FOLDERS`."""
    folder, *rest = path.relative_to(ROOT).with_suffix("").parts
    return ".".join([FOLDERS[folder], *rest]).removesuffix(".__init__")


def room(module: str) -> str:
    """The package a module belongs to: ``sim_camera``, ``controllers``, ``calibration`` (the
    folders installed under stcvision), or ``stcvision`` for the pipeline's own modules."""
    parts = module.split(".")
    if parts[0] == "stcvision" and len(parts) > 1 and f"stcvision.{parts[1]}" in FOLDERS.values():
        return parts[1]
    return parts[0]


def _ours(module: str) -> bool:
    return module.split(".")[0] == "stcvision"


def _imports() -> dict[str, set[tuple[str, tuple[str, ...]]]]:
    """module -> {(imported module, names imported from it)} for the project's own modules."""
    out: dict[str, set] = defaultdict(set)
    for folder in FOLDERS:
        for path in (ROOT / folder).rglob("*.py"):
            name = _module_name(path)
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.Import):
                    targets = [(a.name, ()) for a in node.names]
                elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                    targets = [(node.module, tuple(a.name for a in node.names))]
                else:
                    continue
                out[name] |= {t for t in targets if _ours(t[0])}
    return out


IMPORTS = _imports()


def _graph() -> dict[str, set[str]]:
    """Module-level edges; ``from pkg import mod`` counts as importing ``pkg.mod``."""
    mods = set(IMPORTS) | {m for ts in IMPORTS.values() for m, _ in ts}
    g: dict[str, set[str]] = defaultdict(set)
    for m, ts in IMPORTS.items():
        for t, names in ts:
            subs = {f"{t}.{n}" for n in names if f"{t}.{n}" in mods}
            g[m] |= subs or {t}
    return g


def _cycles(g: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, on, stack, comps, counter = {}, {}, set(), [], [], [0]
    for root in list(g):
        if root in index:
            continue
        work = [(root, iter(sorted(g[root])))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        x = stack.pop()
                        on.discard(x)
                        comp.append(x)
                        if x == v:
                            break
                    if len(comp) > 1:
                        comps.append(sorted(comp))
            elif w not in index:
                index[w] = low[w] = counter[0]
                counter[0] += 1
                stack.append(w)
                on.add(w)
                work.append((w, iter(sorted(g.get(w, ())))))
            elif w in on:
                low[v] = min(low[v], index[w])
    return comps


def test_the_rules_see_the_modules():
    """The reader finds the packages' modules and their imports (a broken reader passes all)."""
    assert len(IMPORTS) > 50
    assert ("stcvision.errors", ("BadInputError",)) in IMPORTS["stcvision.sim_camera.arenas"]


def test_cycle_finder_finds_a_circle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_circle():
    assert _cycles(_graph()) == []


def test_the_pipeline_imports_no_simulator_robot_or_calibration():
    """stcvision is the bottom layer; only its CLI (and the warm-up that drives it) reach up, and
    the datasets' renderer and recipes to the simulator and calibration (:data:`DATASETS_MAY_IMPORT`)."""
    bad = [
        (m, t)
        for m, ts in IMPORTS.items()
        if room(m) == "stcvision" and not m.startswith(ROOF)
        for t, _ in ts
        if room(t) != "stcvision" and room(t) not in DATASETS_MAY_IMPORT.get(m, ())
    ]
    assert bad == []


def test_the_simulator_does_not_share_the_pipelines_model():
    bad = []
    for m, ts in IMPORTS.items():
        if room(m) != "sim_camera":
            continue
        for t, names in ts:
            top = room(t)
            if top in ("controllers", "calibration"):
                bad.append((m, t))
            elif top == "stcvision":
                allowed = SIM_MAY_IMPORT.get(t, set())
                if t not in SIM_MAY_IMPORT or (allowed is not None and not set(names) <= allowed):
                    bad.append((m, t, names))
    assert bad == []


@pytest.mark.parametrize("name", ["stc", "buffon", "search"])
def test_a_robots_room_imports_no_other_room(name):
    bad = [
        (m, t)
        for m, ts in IMPORTS.items()
        if m.startswith(f"stcvision.controllers.{name}")
        for t, _ in ts
        if t.startswith("stcvision.controllers.") and not t.startswith(f"stcvision.controllers.{name}")
    ]
    assert bad == []


def test_the_packages_facade_is_the_one_place_the_pipeline_names_other_packages():
    """``stcvision/__init__.py`` re-exports the robots' runs, the board and the shipped profile
    lazily, by name (``_LAZY``), so that users write ``from stcvision import run_cover``; no other
    module of the pipeline loads a module by name, except the sweep runner, which loads the task
    a caller names (``Task.experiment``), and the roof (the command line; the warm-up, which
    compiles the demo's kernels by their modules' names)."""
    by_name = []
    for path in (ROOT / "stcvision").rglob("*.py"):
        name = _module_name(path)
        if name.startswith(ROOF) or name in ("stcvision", "stcvision.sweep._task"):
            continue
        if "import_module(" in path.read_text(encoding="utf-8"):
            by_name.append(name)
    assert by_name == []
    import stcvision

    outside = {room(m) for m, _ in stcvision._LAZY.values()} - {"stcvision"}
    assert outside <= {"sim_camera", "controllers", "calibration"}


#: (importing module, imported module, private name) pairs still allowed: none
PRIVATE_IMPORTS_ALLOWED: set[tuple[str, str, str]] = set()


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _private_imports(path: Path, me: str) -> list[tuple[str, str, str]]:
    """(``me``, module, private name) for each import in ``path`` of a private name of another
    module: ``from M import _x``, or a private module ``P._m`` (or a name from it) imported from
    outside its package ``P``. A package's own modules may import each other's private modules
    (``stcvision.sweep`` from ``stcvision.sweep._run``)."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            targets = [(node.module, a.name) for a in node.names]
        elif isinstance(node, ast.Import):
            targets = [(a.name, None) for a in node.names]
        else:
            continue
        for mod, name in targets:
            if not _ours(mod):
                continue
            parts = mod.split(".")
            for i, part in enumerate(parts):  # a private module on the way: only its package may
                pkg = ".".join(parts[:i])
                if _private(part) and not (me == pkg or me.startswith(pkg + ".")):
                    out.append((me, pkg, part))
                    break
            else:
                if name is not None and _private(name):
                    inside = me.startswith(mod + ".") or (path.name == "__init__.py" and me == mod)
                    if not inside:
                        out.append((me, mod, name))
    return out


def test_the_private_name_finder_finds_them(tmp_path):
    src = tmp_path / "m.py"
    src.write_text(
        "from stcvision.observation import _rotate, observe_cell\n"
        "import stcvision.sweep._worker\n"
        "from stcvision.sweep._run import run_sweep\n"
        "from stcvision.sweep import run_sweep\n"
        "from numpy import _globals\n"
    )
    assert _private_imports(src, "docs.m") == [
        ("docs.m", "stcvision.observation", "_rotate"),
        ("docs.m", "stcvision.sweep", "_worker"),
        ("docs.m", "stcvision.sweep", "_run"),
    ]
    assert _private_imports(src, "stcvision.sweep.other")[1:] == []


def test_no_module_imports_another_modules_private_name():
    """Every installed module and every script of docs/ and tests/tools/: a name another module
    uses is public (no leading underscore), so a module's private names can change without
    breaking others."""
    found = []
    for folder in FOLDERS:
        for path in (ROOT / folder).rglob("*.py"):
            found += _private_imports(path, _module_name(path))
    for path in sorted([*(ROOT / "docs").rglob("*.py"), *(ROOT / "tests" / "tools").glob("*.py")]):
        found += _private_imports(path, ".".join(path.relative_to(ROOT).with_suffix("").parts))
    assert sorted(set(found) - PRIVATE_IMPORTS_ALLOWED) == []


def test_the_ground_floor_imports_nothing_above_it():
    """Errors, file helpers, caps, angle wrapping and the STC geometry are what every layer
    stands on: they import one another at most, so no arrow of the house runs back up from them."""
    bad = [(m, t) for m in GROUND for t, _ in IMPORTS.get(m, ()) if t not in GROUND]
    assert bad == []
    assert all((ROOT / f"{m.replace('.', '/')}.py").is_file() for m in GROUND)  # the rule names real modules


def test_nothing_but_the_command_line_imports_it():
    """The CLI is the roof: it may import every room; nothing under it imports the CLI back."""
    bad = [(m, t) for m, ts in IMPORTS.items() if not m.startswith(ROOF) for t, _ in ts if t.startswith(ROOF)]
    assert bad == []
    assert any(t.startswith("stcvision.cli") for t, _ in IMPORTS["stcvision.warm"])  # the rule sees the roof


def _listed_packages() -> list[str]:
    import tomllib

    return tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]["packages"]


def test_the_distribution_lists_every_package_folder_under_one_name():
    """pyproject.toml lists its packages by hand (a package-dir mapping cannot be found by
    search): the list is every folder of :data:`FOLDERS` holding an ``__init__.py``, by its
    installed name, and the mapping sends each installed name to its folder."""
    import tomllib

    folders = sorted(_module_name(p) for f in FOLDERS for p in (ROOT / f).rglob("__init__.py"))
    assert sorted(_listed_packages()) == folders
    mapping = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]["package-dir"]
    assert mapping == {name: folder for folder, name in FOLDERS.items() if name != folder}
    # make writes the bytecode of the same folders
    make = (ROOT / "Makefile").read_text(encoding="utf-8")
    (line,) = [ln for ln in make.splitlines() if ln.startswith("PACKAGE_FOLDERS :=")]
    assert sorted(line.split(":=")[1].split()) == sorted(FOLDERS)


def test_a_built_wheel_installs_stcvision_alone(tmp_path):
    """The wheel's top level is stcvision (and its metadata), the shipped profile inside it; and
    from outside the checkout the generic folder names are not importable from it."""
    import subprocess
    import sys
    import zipfile

    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "-q",
            "--no-deps",
            "--no-build-isolation",
            "-w",
            str(tmp_path),
            str(ROOT),
        ],
        check=True,
        capture_output=True,
        cwd=tmp_path,
    )
    (wheel,) = tmp_path.glob("stcvision-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert {n.split("/")[0] for n in names} == {
        "stcvision",
        wheel.name.split("-")[0] + "-" + wheel.name.split("-")[1] + ".dist-info",
    }
    assert "stcvision/calibration/profiles/default.json" in names
    assert "stcvision/controllers/stc/fsm.py" in names
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    probe = (
        "import importlib.util as u, sys; sys.path[:1] = []; "
        "names = ('controllers', 'calibration', 'sim_camera', 'stcvision.controllers.stc.fsm'); "
        "print([n for n in names if u.find_spec(n)])"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe],
        env={"PYTHONPATH": str(site)},
        cwd=tmp_path,
        capture_output=True,
        text=True,
        check=True,
    )
    assert out.stdout.strip() == "['stcvision.controllers.stc.fsm']"
