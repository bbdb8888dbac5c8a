"""Each command lives in the module its group names (cli/), and moving one changes nothing it prints."""

from __future__ import annotations

from click.testing import CliRunner

from segadeform.cli.main import cli

from ..conftest import SAMPLES


def test_commands_live_in_their_own_modules():
    where = {name: cmd.callback.__module__ for name, cmd in cli.commands.items() if cmd.callback is not None}
    assert where["info"] == "segadeform.cli.info_cmd" and where["run"] == "segadeform.cli.run"
    assert where["inspect"] == "segadeform.cli.inspect_cmd" and where["simulate"] == "segadeform.cli.simulate"
    import segadeform.cli.run as run_mod
    import segadeform.cli.simulate as sim_mod

    assert "info" not in run_mod.__doc__ and "garment make" not in sim_mod.__doc__


def test_info_prints_the_package():
    r = CliRunner().invoke(cli, ["info", str(SAMPLES / "models" / "default")])
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    assert lines[0].startswith(f"{SAMPLES / 'models' / 'default'}: segadeform-model-package schema ")
    assert lines[1].startswith("  units m, up +y, 24 joints") and lines[2].startswith("  config: {")
    assert any(ln.startswith("  ops (") for ln in lines)
