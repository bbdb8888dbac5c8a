"""The core, runtime and CLI never import torch (DEVELOPERS.md)."""

import subprocess
import sys

TORCH_FREE = ["segadeform", "segadeform.io", "segadeform.geometry", "segadeform.body", "segadeform.cli.main"]


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
