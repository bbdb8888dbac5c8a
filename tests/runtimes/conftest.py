"""The shared test vector every runtime is held to."""

from __future__ import annotations

import pytest

from tests.conftest import SAMPLES


@pytest.fixture(scope="session")
def shared_bundle(tmp_path_factory, random_package):
    """A scene's bundle with the Python runtime's output: the test vector every runtime is held to."""
    from segadeform.runtime.bundles import scene_bundle
    from segadeform.scene import load_scene

    d = tmp_path_factory.mktemp("bundle")
    scene = d / "s.toml"
    scene.write_text(f'[garment]\nmesh = "{SAMPLES / "garments" / "dress.obj"}"\n[motion]\nkind = "dance"\n'
                     f'seconds = 0.4\nseed = 2\n[body]\nbetas = [0.5, -0.3]\n[output]\npath = "{d / "o.pc2"}"\n'
                     '[effects]\nskinning = "dqs"\ndynamics = true\nwrinkles = true\n')
    # force: the sample dress was made on the mean body; here it is only numbers to run, shaped by betas
    return scene_bundle(load_scene(scene), d / "s.sgdb", model=random_package, batch=5, force=True)
