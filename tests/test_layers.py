"""Dependencies point one way: every import in ``slide_gym``, ``agents``, ``benchmarks`` and
``tools`` (at module level or inside a function) goes to a module of its own layer or a lower
one. The Contributing page of the documentation shows :data:`LAYERS` as it is here."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("slide_gym", "agents", "benchmarks", "tools")

# layers: start
LAYERS: tuple[tuple[str, ...], ...] = (
    # 0: foundations: PyBullet client, URDF paths, polygons and shapes, small shared helpers
    (
        "slide_gym.sim",
        "slide_gym.assets",
        "slide_gym.geometry",
        "slide_gym.stats",
        "slide_gym.jobs",
    ),
    ("slide_gym.robot",),  # 1: the WAM + T42 model, kinematics, springs and tendon
    ("slide_gym.task",),  # 2: scenes, start poses, success tests
    ("slide_gym.planning",),  # 3: the planners
    ("slide_gym.envs", "slide_gym", "slide_gym.version"),  # 4: the environments, their ids
    ("agents",),  # 5: the expert (planner agent), the scripted slider, episode records
    ("slide_gym.datasets",),  # 6: demonstrations recorded from the expert
    ("agents.learned", "agents.bc", "agents.evaluate"),  # 7: policies learned from datasets
    ("slide_gym.bench",),  # 8: benchmarks of the env, the planners and the expert
    ("slide_gym.experiments",),  # 9: the paper's experiments (run with bench's cases)
    ("slide_gym.cli",),  # 10: the `slide-gym` command
    ("benchmarks", "tools"),  # 11: scripts
)
# layers: end


def layer_of(module: str) -> int:
    """The layer of the longest prefix in :data:`LAYERS` that names ``module`` or a parent."""
    best, rank = "", -1
    for i, prefixes in enumerate(LAYERS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > len(best):
                best, rank = prefix, i
    if rank < 0:
        raise KeyError(f"{module} is in no layer: add it to LAYERS")
    return rank


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path) -> list[tuple[int, str]]:
    """``(line, module)`` of every absolute import of one of :data:`PACKAGES` in a file."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom):
            assert node.level == 0, f"{path}:{node.lineno}: relative import"
            names = [node.module or ""]
            # `from slide_gym import version` imports the module slide_gym.version
            names += [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        found += [(node.lineno, n) for n in names if n.split(".")[0] in PACKAGES]
    return found


def sources() -> list[Path]:
    return sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))


def is_module(name: str) -> bool:
    path = ROOT.joinpath(*name.split("."))
    return path.with_suffix(".py").exists() or (path / "__init__.py").exists()


def test_every_import_points_down_or_sideways() -> None:
    upward = []
    for path in sources():
        mine = layer_of(module_name(path))
        for line, name in imports(path):
            if not is_module(name):  # a name from a module, not a module
                continue
            if layer_of(name) > mine:
                upward.append(f"{path.relative_to(ROOT)}:{line} imports {name}")
    assert not upward, "imports up the layers:\n" + "\n".join(upward)


def test_the_check_sees_upward_imports() -> None:
    assert layer_of("slide_gym.experiments.report") > layer_of("agents.evaluate")
    assert layer_of("agents.learned.dagger") > layer_of("slide_gym.datasets.store")
    assert layer_of("slide_gym.datasets.collect") > layer_of("agents.params")
    assert layer_of("slide_gym.planning.pair") < layer_of("slide_gym.envs.control")
    assert layer_of("slide_gym") == layer_of("slide_gym.envs")
    assert len(sources()) > 90 and all(layer_of(module_name(p)) >= 0 for p in sources())
