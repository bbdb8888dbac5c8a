"""Files that ship inside the package (the default body and model), found wherever it is installed.

In the source tree ``segadeform/_data`` holds links to ``samples/``; a built wheel holds the files
themselves (``[tool.setuptools.package-data]`` in pyproject.toml), so an installed segadeform
animates garments with no checkout and no download.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["data_path"]


def data_path(*parts: str) -> Path:
    """The path of a shipped file or folder, e.g. ``data_path("default_body.npz")`` (it may not exist)."""
    return Path(str(resources.files("segadeform").joinpath("_data", *parts)))
