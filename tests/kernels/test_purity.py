"""kernels/ is pure NumPy: importable with bpy made unimportable, and never importing Blender or the
add-on layers (STYLE.md, 1)."""

import ast
import subprocess
import sys
from pathlib import Path

KERNELS = Path(__file__).resolve().parents[2] / "kernels"
FORBIDDEN = {"bpy", "mathutils", "bmesh", "bpy_extras", "addon", "operators", "pipeline"}


def kernel_modules() -> list[str]:
    return sorted(p.stem for p in KERNELS.glob("*.py") if p.stem != "__init__")


def test_no_forbidden_imports_in_source():
    offenders = []
    for path in KERNELS.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                # relative imports name a sibling kernel ("from .scene") or climb out ("from ..addon")
                if node.level > 1:
                    names = [(node.module or "").split(".")[0] or ".."]
                elif node.level == 1:
                    continue
                else:
                    names = [node.module or ""]
            else:
                continue
            for name in names:
                if name.split(".")[0] in FORBIDDEN or name == "..":
                    offenders.append(f"{path.name}: {name}")
    assert offenders == []


def test_every_kernel_imports_without_blender():
    modules = kernel_modules()
    assert "scene" in modules and "lights" in modules
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
