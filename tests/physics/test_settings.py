"""A scene's [simulate] table -> solver settings: only the named effects are on."""

from __future__ import annotations

import numpy as np
import pytest

from segadeform.errors import FileFormatError, InputError
from segadeform.physics import DEFAULT_EFFECTS, EFFECTS, MATERIALS, SimSettings, blender_settings, parse_simulate_table
from segadeform.settings import load_scene


def _scene(tmp_path, simulate: str) -> object:
    p = tmp_path / "s.toml"
    p.write_text('[garment]\nmesh = "g.obj"\n[motion]\nkind = "walk"\n[output]\npath = "o.pc2"\n' + simulate)
    return load_scene(p)


def test_scene_without_simulate_table_has_none(tmp_path):
    assert _scene(tmp_path, "").simulate is None


def test_named_effects_only(tmp_path):
    sc = _scene(tmp_path, '[simulate]\neffects = ["gravity", "pinning"]\nmaterial = "silk"\n')
    s = sc.simulate
    assert s.effects == ("gravity", "pinning") and s.material == "silk"
    b = blender_settings(s)
    assert b["effects"] == {e: e in ("gravity", "pinning") for e in EFFECTS}
    assert b["cloth"]["bending_stiffness"] == 0.0 and b["cloth"]["air_damping"] == 0.0
    assert b["cloth"]["pin_stiffness"] == s.pin_stiffness
    assert b["wind"] is None and "self_distance_min" not in b["collision"]


def test_every_effect_maps_to_its_switch():
    for e in EFFECTS:
        on = blender_settings(SimSettings(effects=(e,)))
        off = blender_settings(SimSettings(effects=()))
        assert on["effects"][e] and not off["effects"][e]
        assert sum(on["effects"].values()) == 1
    m = MATERIALS["denim"]
    b = blender_settings(SimSettings(effects=("bending", "air_damping", "wind"), material="denim"))
    assert b["cloth"]["bending_stiffness"] == m.bending and b["cloth"]["air_damping"] == m.air_damping
    assert b["cloth"]["tension_stiffness"] == m.tension and b["wind"]["strength"] > 0


def test_effects_are_canonical_and_defaults():
    assert SimSettings(effects=("wind", "gravity")).effects == ("gravity", "wind")
    assert SimSettings().effects == DEFAULT_EFFECTS


@pytest.mark.parametrize(
    "table, msg",
    [
        ('[simulate]\nmaterial = "silk"\n', "must name its effects"),
        ('[simulate]\neffects = ["gravity", "magic"]\n', "unknown simulation effect"),
        ('[simulate]\neffects = ["gravity", "gravity"]\n', "named twice"),
        ('[simulate]\neffects = []\nmaterial = "paper"\n', "unknown material"),
        ("[simulate]\neffects = []\nquality = 0\n", "quality"),
        ("[simulate]\neffects = []\nquality = 2.5\n", "wrong type"),
        ("[simulate]\neffects = []\nbogus = 1\n", "unknown key simulate.bogus"),
        ("[simulate]\neffects = []\nwind = [0, 0, 0]\n", "non-zero"),
        # a knob of an effect that is off did nothing, silently (the cloth stage's were refused: a scene's trial)
        ('[simulate]\neffects = ["gravity"]\nwind_strength = 50\n', "sets wind_strength but the effect wind is off"),
        ('[simulate]\neffects = ["gravity"]\npin_stiffness = 2\n', "sets pin_stiffness but the effect pinning is off"),
        ('[simulate]\neffects = ["gravity"]\nmax_step_motion = 0.05\n', "effect body_collision is off"),
    ],
)
def test_bad_simulate_tables_name_the_file(tmp_path, table, msg):
    with pytest.raises(FileFormatError) as e:
        _scene(tmp_path, table)
    assert msg in str(e.value) and "s.toml" in str(e.value)
    if msg in ("unknown material", "quality", "non-zero") or "is off" in msg:  # its key's line (a user's trial)
        assert e.value.line == 9, (table, e.value.line)


def test_parse_none_is_default():
    assert parse_simulate_table(None) == SimSettings()
    with pytest.raises(InputError):
        SimSettings(pin="sleeve")


def test_impulse_clamp_reaches_the_cloth_collision_settings(tmp_path):
    s = _scene(tmp_path, '[simulate]\neffects = ["body_collision"]\nimpulse_clamp = 0.02\n').simulate
    assert s.impulse_clamp == 0.02 and blender_settings(s)["collision"]["impulse_clamp"] == 0.02
    assert blender_settings(SimSettings())["collision"]["impulse_clamp"] == 0.0  # Blender's own default: off
    with pytest.raises(FileFormatError, match="impulse_clamp"):
        _scene(tmp_path, "[simulate]\neffects = []\nimpulse_clamp = 2.0\n")


def test_max_step_motion_is_read_and_leaves_older_digests_alone(tmp_path):
    s = _scene(tmp_path, '[simulate]\neffects = ["body_collision"]\nmax_step_motion = 0.01\n').simulate
    assert s.max_step_motion == 0.01 and s.to_dict()["max_step_motion"] == 0.01
    assert "max_step_motion" not in SimSettings().to_dict()  # off: the settings of datasets made before it
    with pytest.raises(FileFormatError, match="max_step_motion"):
        _scene(tmp_path, "[simulate]\neffects = []\nmax_step_motion = -0.01\n")


def test_untangle_body_is_read_and_leaves_older_digests_alone(tmp_path):
    s = _scene(tmp_path, '[simulate]\neffects = ["body_collision"]\nuntangle_body = true\n').simulate
    assert s.untangle_body is True and s.to_dict()["untangle_body"] is True
    assert "untangle_body" not in SimSettings().to_dict()  # off: the settings of datasets made before it
    with pytest.raises(FileFormatError, match="untangle_body"):
        _scene(tmp_path, "[simulate]\neffects = []\nuntangle_body = 1\n")
    with pytest.raises(InputError, match="untangle_body"):
        SimSettings(untangle_body="yes")


def test_clip_quality_follows_the_fastest_frame():
    from segadeform.physics.blender import clip_quality

    b = np.zeros((4, 3, 3))
    b[2:, 1, 0] = 0.05  # 5 cm between frames 1 and 2
    assert clip_quality(b, 10, 0.01) == 10 and clip_quality(b, 2, 0.01) == 5
    b[3:, 2, 2] = 0.5  # 50 cm between frames 2 and 3
    assert clip_quality(b, 10, 0.01) == 50
    b[3:, 0, 1] = 5.0  # 5 m: more than the cap allows
    assert clip_quality(b, 10, 0.01) == 80 and clip_quality(b[:1], 10, 0.01) == 10
    with pytest.raises(InputError, match="max_step_motion"):
        clip_quality(b, 10, 0.0)
    with pytest.raises(InputError, match="body frames"):
        clip_quality(b[0], 10, 0.01)


def test_the_collider_is_single_sided_either_way_and_normals_only_when_asked():
    """Blender's "single sided" (``use_culling``) is named in both modes (its default, with which every dataset
    was made); ``collision_normals`` adds "override normals" and nothing else."""
    plain = blender_settings(SimSettings(effects=("body_collision",)))["body_collision"]
    normals = blender_settings(SimSettings(effects=("body_collision",), collision_normals=True))["body_collision"]
    assert plain["use_culling"] is True and normals["use_culling"] is True
    assert "use_normal" not in plain and normals["use_normal"] is True
    assert {k: v for k, v in normals.items() if k != "use_normal"} == plain
