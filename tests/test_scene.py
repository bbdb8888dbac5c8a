import pytest

from segadeform.errors import FileFormatError
from segadeform.settings import Effects, load_scene, parse_effects
from tests.conftest import SAMPLES


def write(tmp_path, text):
    p = tmp_path / "s.toml"
    p.write_text(text)
    return p


BASE = '[garment]\nmesh = "g.obj"\n[motion]\nkind = "walk"\n[output]\npath = "o.pc2"\n'


def test_sample_scenes_parse():
    s = load_scene(SAMPLES / "scenes" / "skirt_walk.toml")
    assert s.garment == (SAMPLES / "garments" / "skirt.obj").resolve()
    assert s.effects == Effects() and s.output_format == "pc2"
    d = load_scene(SAMPLES / "scenes" / "skirt_dance_dqs.toml")
    assert d.effects.skinning == "dqs" and not d.effects.wrinkles and d.up == "y" and d.output_format == "obj-seq"


def test_minimal_scene_defaults(tmp_path):
    s = load_scene(write(tmp_path, BASE))
    assert s.motion.kind == "walk" and s.body is None and s.model is None and s.effects == Effects()
    assert s.output == tmp_path / "o.pc2"


@pytest.mark.parametrize(
    "extra, words",
    [
        ("[effects]\nglitter = true\n", "unknown key effects.glitter"),
        ("[lights]\non = 1\n", "unknown table [lights]"),
        ('[effects]\nwrinkles = "yes"\n', "effects.wrinkles has the wrong type"),
        ('[effects]\nskinning = "blend"\n', "skinning must be"),
        ("[effects]\ncollision_margin = -1\n", "collision_margin"),
        # a margin with collisions and the cloth stage off did nothing (a scene author's trial)
        ("[effects]\ncollision_margin = 0.02\n", "sets collision_margin but neither collisions nor the cloth stage"),
        ("[output2]\n", "unknown table"),
        ('[body]\nbetas = [1, "a"]\n', "betas"),
    ],
)
def test_invalid_scenes(tmp_path, extra, words):
    p = write(tmp_path, BASE + extra)
    with pytest.raises(FileFormatError, match=words.replace("[", r"\[").replace("]", r"\]")) as ei:
        load_scene(p)
    assert str(p) in str(ei.value)


def test_knobs_of_an_effect_the_command_line_turns_on_are_the_scenes(tmp_path):
    """A scene may keep the knobs of an effect it leaves off when the command line turns it on: `simulate
    --effects=+wind` with wind_strength in [simulate], `run --effects=+cloth` with cloth_ knobs in [effects] (both
    refused before: the knob rule read the scene's own effects).  Without the change they are refused as before;
    the scene keeps its own effects, and the change keeps its knobs."""
    from segadeform.settings.simulation import parse_sim_effects

    p = write(tmp_path, BASE + '[simulate]\neffects = ["gravity", "body_collision"]\nwind_strength = 50\n')
    with pytest.raises(FileFormatError, match=r"sets wind_strength but the effect wind is off.*--effects=\+wind"):
        load_scene(p)
    with pytest.raises(FileFormatError, match="sets wind_strength"):
        load_scene(p, sim_effects="-body_collision")
    sc = load_scene(p, sim_effects="+wind")
    assert sc.simulate.effects == ("gravity", "body_collision") and sc.simulate.wind_strength == 50
    assert "wind" in parse_sim_effects("+wind", sc.simulate.effects)
    q = write(tmp_path, BASE + "[effects]\ndynamics = true\ncloth_iterations = 6\n")
    with pytest.raises(FileFormatError, match=r"cloth stage is off.*--effects=\+cloth"):
        load_scene(q)
    sc = load_scene(q, effects="+cloth")
    assert not sc.effects.cloth and parse_effects("+cloth", sc.effects).cloth_settings.iterations == 6


def test_knobs_of_an_effect_the_command_line_turns_off_are_kept_and_ignored(tmp_path):
    """The other direction (a user's trial: `run scene.toml --effects=-cloth` on a scene with cloth = true and
    cloth_iterations was refused with the hint to set cloth = true, which the file set): the knobs are kept and do
    nothing, as `--quality fast` ignores them; the same for [simulate] and `simulate --effects=-wind`."""
    from segadeform.settings.simulation import parse_sim_effects

    q = write(tmp_path, BASE + "[effects]\ncloth = true\ncloth_iterations = 6\ncollision_margin = 0.006\n")
    sc = load_scene(q, effects="-cloth")
    assert sc.effects.cloth and not parse_effects("-cloth", sc.effects).cloth
    assert sc.effects.cloth_settings.iterations == 6
    sc = load_scene(q, effects="none")  # collision_margin too: both stages off
    assert not parse_effects("none", sc.effects).collisions
    p = write(tmp_path, BASE + '[simulate]\neffects = ["gravity", "wind"]\nwind_strength = 50\n')
    sc = load_scene(p, sim_effects="-wind")
    assert sc.simulate.wind_strength == 50 and "wind" not in parse_sim_effects("-wind", sc.simulate.effects)


@pytest.mark.parametrize(
    "text, words",
    [
        ('[motion]\nkind = "walk"\n[output]\npath = "o.pc2"\n', "missing garment.mesh"),
        ('[garment]\nmesh = "g.obj"\n[output]\npath = "o.pc2"\n', "missing [motion]"),
        (
            '[garment]\nmesh = "g.obj"\n[motion]\nkind = "walk"\nfile = "m.npz"\n[output]\npath = "o.pc2"\n',
            "exactly one",
        ),
        ('[garment]\nmesh = "g.obj"\n[motion]\nfile = "m.npz"\nseed = 3\n[output]\npath = "o.pc2"\n', "procedural"),
        ('[garment]\nmesh = "g.obj"\n[motion]\nkind = "walk"\nframes = "x"\n[output]\npath = "o.pc2"\n', "A:B"),
        ('[garment]\nmesh = "g.obj"\n[motion]\nkind = "walk"\n[output]\npath = "o.fbx"\n', "output.format"),
        ("garment = = 1", "invalid TOML"),
    ],
)
def test_structural_errors(tmp_path, text, words):
    with pytest.raises(FileFormatError, match=words.replace("[", r"\[").replace("]", r"\]")):
        load_scene(write(tmp_path, text))


def test_effects_flags():
    e = parse_effects("dqs,-wrinkles,-collisions")
    assert e == Effects(skinning="dqs", wrinkles=False, collisions=False)
    with pytest.raises(FileFormatError, match="unknown effect"):
        parse_effects("sparkles")


def test_effects_not_named_are_off(tmp_path):
    base = '[garment]\nmesh = "g.obj"\n[motion]\nkind = "walk"\n[output]\npath = "o.pc2"\n'
    s = load_scene(write(tmp_path, base + '[effects]\nskinning = "lbs"\ncollisions = true\n'))
    assert s.effects == Effects(skinning="lbs", dynamics=False, wrinkles=False, collisions=True)
    assert s.effects.off() == ["dynamics", "wrinkles"] and s.effects.label() == "lbs+collisions"
    s = load_scene(write(tmp_path, base + "[effects]\n"))
    assert s.effects == Effects(dynamics=False, wrinkles=False, collisions=False)
    from segadeform.settings import DEFAULT_EFFECTS

    assert load_scene(write(tmp_path, base)).effects == DEFAULT_EFFECTS == Effects()


def test_cli_effects_complete_list_or_changes():
    assert parse_effects("dqs,collisions") == Effects(skinning="dqs", dynamics=False, wrinkles=False, collisions=True)
    assert parse_effects("dynamics") == Effects(dynamics=True, wrinkles=False, collisions=False)
    base = Effects(skinning="dqs", dynamics=True, wrinkles=False, collisions=True, collision_margin=0.01)
    assert parse_effects("-collisions,+wrinkles", base) == Effects(
        skinning="dqs", wrinkles=True, collisions=False, collision_margin=0.01
    )
    assert parse_effects("lbs,collisions", base).collision_margin == 0.01
    with pytest.raises(FileFormatError, match="mix a complete list"):
        parse_effects("collisions,-wrinkles")
    # two skinnings, or one effect twice, are refused, as the Node and C++ runtimes refuse them (a user's trial:
    # "lbs,dqs" ran dqs and "+wrinkles,-wrinkles" ran without wrinkles, silently)
    with pytest.raises(FileFormatError, match="name one skinning"):
        parse_effects("lbs,dqs")
    for twice in ("+wrinkles,-wrinkles", "cloth,cloth", "dqs,-collisions,-collisions", "dqs,dqs", "lbs,-cloth,lbs"):
        with pytest.raises(FileFormatError, match="effects name .* twice"):
            parse_effects(twice, base)
    assert parse_effects("none", base) == Effects(
        dynamics=False, wrinkles=False, collisions=False, collision_margin=0.01
    )  # as `simulate --effects none`


def test_scene_only_parses_and_uses_the_io_axes(tmp_path, monkeypatch):
    """Building the motion is the motion layer's (segadeform.motion.build_motion); the output axes are the io
    layer's list (an axis added there is accepted by scenes without touching scene.py)."""
    import segadeform.settings.scene as scene_mod
    from segadeform.motion import MotionSpec, build_motion

    assert not hasattr(scene_mod, "build_motion") and scene_mod.MotionSpec is MotionSpec
    s = load_scene(write(tmp_path, BASE.replace('path = "o.pc2"', 'path = "o.pc2"\nup = "z"')))
    assert s.up == "z" and build_motion(s.motion).n_frames > 1
    with pytest.raises(FileFormatError, match=r"unknown output.up axis \(expected y \| z, got x\)"):
        load_scene(write(tmp_path, BASE.replace('path = "o.pc2"', 'path = "o.pc2"\nup = "x"')))
    monkeypatch.setattr(scene_mod, "UP_AXES", ("y", "z", "x"))
    assert load_scene(write(tmp_path, BASE.replace('path = "o.pc2"', 'path = "o.pc2"\nup = "x"'))).up == "x"


@pytest.mark.parametrize(
    "motion, line, words",
    [
        ('kind = "moonwalk"', 4, "unknown motion kind"),
        (f'file = "{SAMPLES / "motions" / "cmu" / "02_01_walk.bvh"}"\nunits = "furlong"', 5, "unknown units"),
    ],
)
def test_a_bad_motion_value_names_the_scene_and_line(tmp_path, motion, line, words):
    """A user's trial: `unknown motion kind` and `unknown units` from a scene named neither file nor line."""
    from click.testing import CliRunner

    from segadeform.cli.main import cli

    p = tmp_path / "s.toml"
    p.write_text(
        f'[garment]\nmesh = "{SAMPLES / "garments" / "skirt.obj"}"\n[motion]\n{motion}\n'
        f'[output]\npath = "{tmp_path / "o.pc2"}"\n'
    )
    r = CliRunner().invoke(cli, ["run", str(p), "--no-cache"])
    assert r.exit_code == 1 and f"{p}:{line}: [motion]: {words}" in r.output, r.output
    assert not (tmp_path / "o.pc2").exists()


def test_a_scene_made_in_python_takes_its_format_from_the_output_and_checks_its_parts(tmp_path):
    """A library user's trial: ``Scene(output=Path("x.obj"))`` kept the default format pc2 and wrote a point cache
    named .obj; ``effects="+cloth"`` was said as "effects must name skinning"; ``MotionSpec()`` as "unknown motion
    kind" with nothing got."""
    from pathlib import Path

    from segadeform.errors import InputError
    from segadeform.settings import Scene, parse_effects
    from segadeform.settings.scene import MotionSpec

    walk = MotionSpec(kind="walk")
    assert Scene(garment=Path("g.obj"), motion=walk, output=Path("o.usda")).output_format == "usd"
    assert Scene(garment=Path("g.obj"), motion=walk, output=Path("o.pc2")).output_format == "pc2"
    assert Scene(garment=Path("g.obj"), motion=walk, output=Path("frames")).output_format == "obj-seq"
    with pytest.raises(InputError, match="cannot tell the output format from the file extension"):
        Scene(garment=Path("g.obj"), motion=walk, output=Path("x.obj"))
    with pytest.raises(InputError, match="the extension says usd, the format asked for is pc2"):
        Scene(garment=Path("g.obj"), motion=walk, output=Path("o.usda"), output_format="pc2")
    with pytest.raises(InputError, match=r"effects must be an Effects.*parse_effects"):
        Scene(garment=Path("g.obj"), motion=walk, output=Path("o.pc2"), effects="+cloth")
    assert Scene(
        garment=Path("g.obj"), motion=walk, output=Path("o.pc2"), effects=parse_effects("+cloth")
    ).effects.cloth
    with pytest.raises(InputError, match=r"a motion is a file or a procedural kind.*got neither"):
        MotionSpec()
    with pytest.raises(InputError, match="got both"):
        MotionSpec(file=tmp_path / "m.bvh", kind="walk")
