"""The dependency arrows between the layers point down the layer list below, never back up."""

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "switchest"

# lower index = lower layer; a module may import only from layers at or below its own
LAYERS = [
    {"_checks", "_toml", "_threads", "_lazy"},
    {"_linalg"},
    {"system"},
    {"signals"},
    {"switching"},
    {"discretize", "dyadic"},
    {"simulate"},
    {"modelfile"},
    {"measurements"},  # the measurement table (CSV / pandas) checked against a model file
    {"models"},  # the published systems: system, signals and modelfile only
    {"metrics"},
    {"analysis"},  # certificates and designs: functions of a system and of gains
    {"default_designs"},  # the designs the methods take from a model file alone
    {"engine"},  # the compiled time loops: arrays, not classes; imported by the estimators only
    {"estimators"},  # the filters, which may run designs from the analysis
    {"learn"},  # fitting a system to data: runs the filters and smoothers, and the analysis
    {"plotting"},
    {"tabular", "certify"},
    {"experiments"},
    {"cli"},
    {"__main__"},
]
RANK = {name: i for i, group in enumerate(LAYERS) for name in group}


def top_level(path: Path, src: Path = SRC) -> str:
    return path.relative_to(src).with_suffix("").parts[0]


def internal_imports(path: Path, src: Path = SRC):
    """Top-level switchest modules that ``path`` imports (absolute or relative)."""
    tree = ast.parse(path.read_text())
    pkg = path.relative_to(src).parent.parts
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = list(pkg[: len(pkg) - node.level + 1])
                target = base + (node.module.split(".") if node.module else [])
                yield from [target[0]] if target else [a.name for a in node.names]
            elif node.module and node.module.startswith("switchest."):
                yield node.module.split(".")[1]
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("switchest."):
                    yield alias.name.split(".")[1]


def upward_imports(path: Path, src: Path = SRC) -> list[str]:
    own = top_level(path, src)
    assert own in RANK, f"{own} is not placed in a layer: add it to LAYERS"
    return [t for t in internal_imports(path, src) if t in RANK and RANK[t] > RANK[own]]


MODULES = [p for p in SRC.rglob("*.py") if p.parent != SRC or p.name != "__init__.py"]


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(SRC)))
def test_imports_point_down(path):
    assert upward_imports(path) == []


def test_the_checker_catches_upward_imports(tmp_path):
    (tmp_path / "estimators").mkdir()
    system = tmp_path / "system.py"
    system.write_text("from .experiments import runner\nimport numpy\n")
    nested = tmp_path / "estimators" / "imm.py"
    nested.write_text("from ..discretize import interval\nfrom switchest.cli import main\n")
    assert upward_imports(system, tmp_path) == ["experiments"]
    assert upward_imports(nested, tmp_path) == ["cli"]


def test_the_checker_keeps_the_analysis_below_the_estimators(tmp_path):
    """The analysis may not import the estimators (relative, absolute, or deferred inside a
    function); the estimators may import the analysis."""
    (tmp_path / "analysis").mkdir()
    (tmp_path / "estimators").mkdir()
    design = tmp_path / "analysis" / "design.py"
    design.write_text("from ..estimators.kalman import kf_update\n"
                      "import switchest.estimators.imm\n"
                      "def f():\n    from .. import estimators\n"
                      "from ._lmi import solve_sdp\n")
    filt = tmp_path / "estimators" / "filter.py"
    filt.write_text("from ..analysis.steady_state_kalman import steady_state_gain\n")
    assert upward_imports(design, tmp_path) == ["estimators"] * 3
    assert upward_imports(filt, tmp_path) == []


def test_the_readme_layout_names_every_module_in_layer_order():
    """README's Layout section lists every top-level module and package of src/switchest, in
    an order the layers allow (a module's layer is never below an earlier one's)."""
    readme = (SRC.parents[1] / "README.md").read_text()
    layout = readme.split("## Layout", 1)[1].split("```")[1]
    names = {p.stem if p.is_file() else p.name for p in SRC.iterdir()
             if (p.suffix == ".py" or (p.is_dir() and (p / "__init__.py").exists()))
             and p.name not in ("__init__.py", "__main__.py")}
    position = {}
    for name in names:
        mark = f"{name}.py" if (SRC / f"{name}.py").exists() else f"{name}/"
        assert mark in layout, f"README's Layout section does not name {mark}"
        position[name] = layout.index(mark)
    ranked = sorted(names, key=position.get)
    assert [RANK[n] for n in ranked] == sorted(RANK[n] for n in ranked), ranked


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(SRC)))
def test_only_the_estimators_import_the_engine(path):
    """The engine knows arrays, not classes (it imports no estimator), and only the estimators
    call it: the learning code, the tables, the experiments and the command line reach the
    compiled loops through the estimators."""
    own = top_level(path)
    imported = {name for name in internal_imports(path) if name in ("engine", "estimators")}
    if own == "engine":
        assert "estimators" not in imported
    elif own != "estimators":
        assert "engine" not in imported
