"""`segadeform simulate SCENE` writes what `run` writes (the same SceneOutput): garment, body, the body's
rest mesh; every file announced (needs the simulator environment; CI has it)."""

from __future__ import annotations

from click.testing import CliRunner

from segadeform.cli.main import cli
from segadeform.io import read_mesh, read_pc2


def test_simulate_scene_writes_like_run(sim_python, tmp_path, coarse_skirt):
    from segadeform.io import Mesh, write_obj

    write_obj(tmp_path / "skirt.obj", Mesh(vertices=coarse_skirt.vertices, faces=coarse_skirt.faces))
    scene = tmp_path / "s.toml"
    scene.write_text(
        '[garment]\nmesh = "skirt.obj"\n[motion]\nkind = "walk"\nseconds = 0.2\n'
        '[output]\npath = "out/g.pc2"\nbody = "out/b.pc2"\n'
        '[simulate]\neffects = ["gravity", "body_collision"]\nquality = 3\n'
        "drape_seconds = 0.1\nblend_seconds = 0.0\n"
    )
    r = CliRunner().invoke(cli, ["simulate", str(scene)])
    assert r.exit_code == 0, r.output
    for name in ("g.pc2", "b.pc2", "b.obj"):
        assert f"wrote {tmp_path / 'out' / name}" in r.output
    g = read_pc2(tmp_path / "out" / "g.pc2").frames
    b = read_pc2(tmp_path / "out" / "b.pc2").frames
    assert g.shape == (6, len(coarse_skirt.vertices), 3) and b.shape[0] == 6
    assert read_mesh(tmp_path / "out" / "b.obj").n_vertices == b.shape[1]
