"""The core, runtime and CLI never import torch (DEVELOPERS.md)."""

import subprocess
import sys

TORCH_FREE = ["segadeform", "segadeform.io", "segadeform.geometry", "segadeform.body", "segadeform.motion",
              "segadeform.scene", "segadeform.physics", "segadeform.physics.scene_sim", "segadeform.garments",
              "segadeform.dataset", "segadeform.runtime", "segadeform.cli.main",
              "segadeform.executors", "segadeform.io.location", "segadeform.runtime.batch"]


def test_torch_free_packages_import_with_torch_blocked():
    code = (
        "import sys\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'torch' or name.startswith('torch.'):\n"
        "            raise ImportError('torch is blocked in this test')\n"
        "sys.meta_path.insert(0, Block())\n"
        f"for m in {TORCH_FREE!r}:\n"
        "    __import__(m)\n"
        "from segadeform.cli.main import cli\n"
        "assert 'torch' not in sys.modules\n"
    )
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr


def test_blender_stays_out_of_process():
    """bpy (GPL-3.0, numpy<2) is only ever imported by the worker script the simulator runs."""
    from pathlib import Path

    import segadeform

    root = Path(segadeform.__file__).resolve().parents[2]
    offenders = []
    for p in list(root.glob("src/**/*.py")) + list(root.glob("cli/*.py")) + list(root.glob("runtimes/python/*.py")) \
            + list(root.glob("export/*.py")):
        text = p.read_text()
        if p.name == "blender_worker.py":
            continue
        if "import bpy" in text or "from bpy" in text or "import blender_worker" in text \
                or "from .blender_worker" in text:
            offenders.append(str(p))
    assert offenders == []
    assert "bpy" not in sys.modules
