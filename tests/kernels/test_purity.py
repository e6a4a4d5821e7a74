"""kernels/ is pure NumPy: importable with bpy made unimportable, and never importing Blender or the
add-on layers (STYLE.md, 1)."""

import ast
import subprocess
import sys
from pathlib import Path

KERNELS = Path(__file__).resolve().parents[2] / "kernels"
FORBIDDEN = {"bpy", "mathutils", "bmesh", "bpy_extras", "addon", "operators", "pipeline"}


def kernel_modules() -> list[str]:
    """Dotted names under kernels/ ("geometry.scene", "progress", ...), packages' __init__ left out."""
    return sorted(".".join(p.relative_to(KERNELS).with_suffix("").parts)
                  for p in KERNELS.rglob("*.py") if p.stem != "__init__")


def imported_names(path: Path, node) -> list[str]:
    """The top-level names an import statement in `path` reaches, relative ones resolved from the
    repository root ("kernels", "addon", "numpy", ...)."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    if node.level == 0:
        return [node.module or ""]
    package = path.relative_to(KERNELS.parent).parent.parts  # e.g. ("kernels", "geometry")
    if node.level > len(package):
        return [".."]  # climbs out of the extension itself
    base = package[: len(package) - (node.level - 1)]
    return [".".join(base + tuple((node.module or "").split(".")) if node.module else base)]


def test_no_forbidden_imports_in_source():
    offenders = []
    for path in KERNELS.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            for name in imported_names(path, node):
                top = name.split(".")[0]
                # a relative import must stay inside kernels/
                inside = not (isinstance(node, ast.ImportFrom) and node.level) or top == "kernels"
                if top in FORBIDDEN or name == ".." or not inside:
                    offenders.append(f"{path.relative_to(KERNELS)}: {name}")
    assert offenders == []


def test_every_kernel_imports_without_blender():
    modules = kernel_modules()
    assert "geometry.scene" in modules and "shading.lights" in modules
    code = (
        "import sys\n"
        "for m in ('bpy', 'mathutils', 'bmesh'):\n"
        "    sys.modules[m] = None  # any import of them now raises ImportError\n"
        "import importlib\n"
        f"for name in {modules!r}:\n"
        "    importlib.import_module('classic_bake.kernels.' + name)\n"
        "print('ok')\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"
