"""Frames in memory from Python (a library user's trial: Node and C++ have a Player, Python had only runs that write a
file): ``Run.stream()`` and ``Run.animate()`` give exactly the frames ``Run.execute()`` writes -- with collisions, the
cloth stage and a first frame past 0 -- and a run with no output cannot be executed."""

from __future__ import annotations

import numpy as np
import pytest

from segadeform.body import load_body
from segadeform.errors import InputError
from segadeform.io import read_pc2
from segadeform.motion import make_motion
from segadeform.runtime import ModelPackage
from segadeform.runtime.pipeline import Run
from segadeform.settings import Effects
from tests.conftest import SAMPLES

SKIRT = SAMPLES / "garments" / "skirt.obj"


@pytest.fixture(scope="module")
def body():
    return load_body(SAMPLES / "bodies" / "default_body.npz")


def _walk_run(package, body, **kw) -> Run:
    """A run of the sample skirt on a short procedural walk (no cache, placement not checked)."""
    return Run(
        garment=SKIRT,
        motion=make_motion("walk", seconds=0.2),
        package=ModelPackage(package),
        body=body,
        cache=False,
        force=True,
        **kw,
    )


@pytest.mark.parametrize(
    "effects",
    [Effects(collisions=False), Effects(), Effects(cloth=True)],
    ids=["network", "collisions", "cloth"],
)
def test_stream_and_animate_are_the_frames_execute_writes(tmp_path, random_package, body, effects):
    motion = make_motion("dance", seconds=0.5, seed=3)

    def run(output=None, frames=(3, None)):
        return Run(
            garment=SKIRT,
            motion=motion,
            package=ModelPackage(random_package),
            body=body,
            effects=effects,
            output=output,
            batch=4,
            cache=False,
            force=True,
            frames=frames,
        )

    summary = run(tmp_path / "out.pc2").execute()
    written = read_pc2(tmp_path / "out.pc2").frames
    chunks = list(run().stream())
    assert [lo for lo, _, _ in chunks] == list(range(3, motion.n_frames, 4))
    streamed = np.concatenate([f for _, f, _ in chunks])
    assert streamed.dtype == np.float32 and streamed.shape == written.shape == (summary.frames, written.shape[1], 3)
    assert np.array_equal(streamed, written)
    # the body comes with the frames when the run posed it (collisions, the cloth stage)
    posed = effects.collisions or effects.cloth
    assert all((b is not None) == posed for _, _, b in chunks)
    if posed:
        assert chunks[0][2].shape == (4, len(body.v_template), 3)
    assert np.array_equal(run().animate(), written)
    # a second stream starts the clip afresh: the same frames
    assert np.array_equal(np.concatenate([f for _, f, _ in run().stream()]), written)


def test_a_run_with_no_output_is_streamed_not_executed(random_package, body):
    r = _walk_run(random_package, body)
    with pytest.raises(InputError, match=r"no output to write.*Run\.stream\(\)"):
        r.execute()
    assert r.animate().shape[0] == r.stop - r.start


def test_the_readme_library_snippets_run_as_written(monkeypatch):
    """The README's Library section ran into NameError on its second line (a library user's trial): its two first
    blocks are run here as pasted, from the repository's root (the Blender one needs the simulator's environment)."""
    import re

    from tests.conftest import SAMPLES

    root = SAMPLES.parent
    text = (root / "README.md").read_text(encoding="utf-8")
    section = text[text.index("## Library\n") :]
    blocks = re.findall(r"```python\n(.*?)```", section, re.S)
    assert len(blocks) == 3 and "simulate(" in blocks[2]
    monkeypatch.chdir(root)
    scope: dict = {}
    exec(compile(blocks[0], "README.md: Library 1", "exec"), scope)
    assert scope["frames"].shape == (30, 1536, 3) and scope["frames"].dtype == np.float32
    exec(compile(blocks[1], "README.md: Library 2", "exec"), scope)
    low, mid, high = scope["low"], scope["mid"], scope["high"]
    assert np.abs(low + mid + high - scope["mesh"].vertices).max() < 1e-9


def test_run_and_a_scene_take_the_format_of_their_output(tmp_path, random_package, body):
    """A review: ``Run(output="out.obj")`` wrote a point cache named .obj, and `run SCENE -o x.usda` on a scene
    writing .pc2 was refused once Scene checked its format against its output."""
    from click.testing import CliRunner

    from segadeform.cli.main import cli

    def run(output, fmt=None):
        return _walk_run(random_package, body, output=output, output_format=fmt)

    assert run(tmp_path / "a.usda").output_format == "usd" and run(tmp_path / "b.pc2").output_format == "pc2"
    with pytest.raises(InputError, match="cannot tell the output format"):
        run(tmp_path / "out.obj")
    with pytest.raises(InputError, match="the extension says pc2, the format asked for is usd"):
        run(tmp_path / "c.pc2", "usd")
    scene = tmp_path / "s.toml"
    scene.write_text(
        f'[garment]\nmesh = "{SKIRT}"\n[motion]\nkind = "walk"\nseconds = 0.2\n'
        f'[output]\npath = "{tmp_path / "scene.pc2"}"\n[model]\npackage = "{random_package}"\n'
    )
    r = CliRunner().invoke(cli, ["run", str(scene), "-o", str(tmp_path / "other.usda"), "--force", "--no-cache"])
    assert r.exit_code == 0 and (tmp_path / "other.usda").is_file() and not (tmp_path / "scene.pc2").exists(), r.output
