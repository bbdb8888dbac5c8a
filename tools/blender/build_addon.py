"""Build the installable Blender add-on zip: ``python tools/blender/build_addon.py [OUT.zip]``
(default ``dist/segadeform_addon.zip``).  The zip holds the ``segadeform_addon`` folder, as Blender's
*Install from Disk* expects; it is written under a temporary name and renamed."""

from __future__ import annotations

import os
import sys
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
PACKAGE = HERE / "segadeform_addon"


def build(out: Path) -> Path:
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.tmp-{os.getpid()}")
    try:
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
            for f in sorted(PACKAGE.rglob("*.py")):
                z.write(f, f"segadeform_addon/{f.relative_to(PACKAGE)}")
        os.replace(tmp, out)
    finally:
        if tmp.exists():
            tmp.unlink()
    return out


if __name__ == "__main__":
    print(build(Path(sys.argv[1]) if len(sys.argv) > 1 else HERE.parents[1] / "dist" / "segadeform_addon.zip"))
